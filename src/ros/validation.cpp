#include "slope_monitor/ros/validation.h"

#include <cmath>

#include <Eigen/Eigenvalues>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

bool Finite(const Eigen::Vector3d& v) { return v.allFinite(); }

Eigen::Vector3d ToEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }
Eigen::Vector3d ToEigen(const geometry_msgs::Vector3& v) { return {v.x, v.y, v.z}; }

// An identifier as it may appear in a log line: cut, control characters escaped.
std::string Shown(const std::string& id) {
  std::string out;
  for (unsigned char c : id.substr(0, 40))
    out += (c < 0x20 || c > 0x7e) ? '?' : static_cast<char>(c);
  return id.size() > 40 ? out + "..." : out;
}

}  // namespace

void ValidationOptions::Check() const {
  if (site_extent && site_extent->isEmpty()) throw ConfigError("validation site_extent is empty");
  if (!(extent_margin >= 0.0))
    throw ConfigError(Message("validation extent_margin = ", extent_margin, " m must be >= 0"));
  if (!(max_coordinate > 0.0))
    throw ConfigError(Message("validation max_coordinate = ", max_coordinate, " m must be > 0"));
  if (!(max_displacement > 0.0))
    throw ConfigError(
        Message("validation max_displacement = ", max_displacement, " m must be > 0"));
  if (!(min_sigma > 0.0 && max_sigma > min_sigma))
    throw ConfigError(Message("validation sigma range [", min_sigma, ", ", max_sigma,
                              "] m must be 0 < min < max"));
  if (!(future_tolerance >= 0.0))
    throw ConfigError(
        Message("validation future_tolerance = ", future_tolerance, " s must be >= 0"));
  if (!std::isfinite(min_stamp)) throw ConfigError("validation min_stamp must be finite");
}

MessageValidator::MessageValidator(const ValidationOptions& options) : options_(options) {
  options_.Check();
}

uint64_t MessageValidator::total_rejected() const {
  uint64_t n = 0;
  for (const auto& [reason, count] : rejected_) n += count;
  return n;
}

void MessageValidator::Reject(const std::string& reason, const std::string& detail) {
  ++rejected_[reason];
  problems_.push_back(Message(reason, ": ", detail));
}

std::string MessageValidator::PositionProblem(const Eigen::Vector3d& x) const {
  if (options_.site_extent) {
    const Eigen::Vector3d m = Eigen::Vector3d::Constant(options_.extent_margin);
    if (!Eigen::AlignedBox3d(options_.site_extent->min() - m, options_.site_extent->max() + m)
             .contains(x))
      return Message("position (", x.x(), ", ", x.y(), ", ", x.z(),
                     ") m lies outside the site extent + ", options_.extent_margin, " m");
  } else if (x.cwiseAbs().maxCoeff() > options_.max_coordinate) {
    return Message("position (", x.x(), ", ", x.y(), ", ", x.z(), ") m exceeds ",
                   options_.max_coordinate, " m");
  }
  return "";
}

std::string MessageValidator::StampProblem(double stamp, double now) const {
  if (!std::isfinite(stamp)) return "stamp is not finite";
  if (now > 0.0 && stamp > now + options_.future_tolerance)
    return Message("stamp ", stamp, " s lies ", stamp - now, " s in the future");
  if (stamp < options_.min_stamp)
    return Message("stamp ", stamp, " s is before the site's start ", options_.min_stamp);
  return "";
}

std::string MessageValidator::EpochProblem(const std::string& source, uint32_t epoch) {
  const auto it = last_epoch_.find(source);
  if (it != last_epoch_.end()) {
    if (epoch < it->second)
      return Message("epoch ", epoch, " is before the source's last epoch ", it->second);
    if (epoch - it->second > options_.max_epoch_step)
      return Message("epoch ", epoch, " jumps more than ", options_.max_epoch_step,
                     " past the last epoch ", it->second);
  } else if (epoch > options_.max_first_epoch) {
    return Message("first epoch ", epoch, " exceeds ", options_.max_first_epoch);
  }
  last_epoch_[source] = epoch;
  return "";
}

std::string MessageValidator::CovarianceProblem(const Eigen::Matrix3d& c) const {
  if (!c.allFinite()) return "covariance is not finite";
  const double scale = c.cwiseAbs().maxCoeff();
  if ((c - c.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale)
    return "covariance is not symmetric";
  const Eigen::Vector3d ev =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(c, Eigen::EigenvaluesOnly).eigenvalues();
  if (!(ev.minCoeff() > 0.0))
    return Message("covariance is not positive definite (eigenvalue ", ev.minCoeff(), ")");
  const double lo = std::sqrt(ev.minCoeff()), hi = std::sqrt(ev.maxCoeff());
  if (lo < options_.min_sigma || hi > options_.max_sigma)
    return Message("sigma ", lo, " .. ", hi, " m outside [", options_.min_sigma, ", ",
                   options_.max_sigma, "] m");
  return "";
}

slope_monitor::PointDisplacementArray MessageValidator::Filter(
    const slope_monitor::PointDisplacementArray& msg, const std::string& topic, double now) {
  problems_.clear();
  slope_monitor::PointDisplacementArray out;
  out.header = msg.header;
  out.epoch = msg.epoch;
  const std::string where = Message("topic '", topic, "'");
  std::string problem = StampProblem(msg.header.stamp.toSec(), now);
  if (!problem.empty()) {
    Reject("bad stamp", Message(where, ": header ", problem));
    return out;
  }
  const std::string source = msg.displacements.empty() ? "" : msg.displacements.front().source_name;
  problem = EpochProblem(topic + " " + source, msg.epoch);
  if (!problem.empty()) {
    Reject("epoch not monotonic", Message(where, ": ", problem));
    return out;
  }
  for (const slope_monitor::PointDisplacement& d : msg.displacements) {
    const std::string item = Message(where, ": point '", Shown(d.point_id), "'");
    Eigen::Matrix3d c;
    for (int k = 0; k < 9; ++k) c(k / 3, k % 3) = d.covariance[k];
    const Eigen::Vector3d x = ToEigen(d.reference_position), dx = ToEigen(d.displacement);
    if ((problem = io::IdProblem(d.point_id)).size()) {
      Reject("bad identifier", Message(item, ": point_id ", problem));
    } else if (!d.source_name.empty() && (problem = io::IdProblem(d.source_name)).size()) {
      Reject("bad identifier", Message(item, ": source_name ", problem));
    } else if (!Finite(x) || !Finite(dx) || !std::isfinite(d.significance)) {
      Reject("non-finite value", item);
    } else if ((problem = PositionProblem(x)).size()) {
      Reject("out of range", Message(item, ": ", problem));
    } else if (dx.norm() > options_.max_displacement) {
      Reject("out of range", Message(item, ": displacement ", dx.norm(), " m exceeds ",
                                     options_.max_displacement, " m"));
    } else if ((problem = CovarianceProblem(c)).size()) {
      Reject("bad covariance", Message(item, ": ", problem));
    } else if ((problem = StampProblem(d.stamp.toSec(), now)).size() ||
               (problem = StampProblem(d.reference_stamp.toSec(), now)).size()) {
      Reject("bad stamp", Message(item, ": ", problem));
    } else {
      out.displacements.push_back(d);
    }
  }
  return out;
}

bool MessageValidator::Accept(const slope_monitor::RadioSampleBlock& msg,
                              const std::string& expected_receiver, double now) {
  problems_.clear();
  const std::string item = Message("receiver '", expected_receiver, "' block ", msg.sequence);
  std::string problem;
  if (msg.receiver_id != expected_receiver) {
    Reject("receiver id does not match topic",
           Message(item, ": labelled '", Shown(msg.receiver_id), "', arrived on the topic of '",
                   expected_receiver, "'"));
  } else if (!std::isfinite(msg.sample_rate) || !(msg.sample_rate > 0.0) ||
             !std::isfinite(msg.center_frequency) || !std::isfinite(msg.full_scale) ||
             !(msg.full_scale > 0.0)) {
    Reject("non-finite value",
           Message(item, ": sample_rate, center_frequency or full_scale not finite and > 0"));
  } else if (!msg.q.empty() && msg.q.size() != msg.i.size()) {
    Reject("out of range",
           Message(item, ": ", msg.i.size(), " i but ", msg.q.size(), " q samples"));
  } else if ((problem = StampProblem(msg.header.stamp.toSec(), now)).size()) {
    Reject("bad stamp", Message(item, ": ", problem));
  } else {
    for (float v : msg.i)
      if (!std::isfinite(v)) problem = "an i sample is not finite";
    for (float v : msg.q)
      if (!std::isfinite(v)) problem = "a q sample is not finite";
    if (!problem.empty()) Reject("non-finite value", Message(item, ": ", problem));
  }
  return problems_.empty();
}

}  // namespace ros_adapters
}  // namespace slope_monitor
