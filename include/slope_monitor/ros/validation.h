// One validation layer at the message boundary: every subscriber that takes
// measurements passes each message through a MessageValidator before the
// core sees it. An element that fails is dropped, counted by reason and
// named (for a throttled log line); the rest of its array is kept.
//
// Checks (ValidationOptions, SI units):
//   * every number finite;
//   * identifiers (point id, receiver id, source name) 1..64 printable
//     ASCII characters (io::IdProblem);
//   * positions within the site extent plus a margin (without an extent:
//     |x|, |y|, |z| <= max_coordinate), displacements <= max_displacement;
//   * covariance symmetric, positive definite, every sigma (square root of
//     an eigenvalue) within [min_sigma, max_sigma] metres;
//   * stamps not later than wall-clock now + future_tolerance (skipped when
//     now is 0) and not before min_stamp;
//   * epoch numbers per source (topic) never decrease and never jump by more
//     than max_epoch_step;
//   * a radio sample block's receiver_id equals the receiver of its topic.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RadioSampleBlock.h"

namespace slope_monitor {
namespace ros_adapters {

struct ValidationOptions {
  std::optional<Eigen::AlignedBox3d> site_extent;  // [m] site frame; none: max_coordinate applies
  double extent_margin = 500.0;                    // [m] around site_extent
  double max_coordinate = 1e5;                     // [m] |coordinate| without a site extent
  double max_displacement = 1e3;                   // [m]
  double min_sigma = 1e-6;                         // [m]
  double max_sigma = 1e3;                          // [m]
  double future_tolerance = 300.0;                 // [s] stamps may lead the clock by this much
  double min_stamp = 0.0;                          // [s] site start; earlier stamps are refused
  uint32_t max_epoch_step = 100000;  // [epochs] largest forward jump of a source's epoch
  uint32_t max_first_epoch =
      1000000000;  // [-] first epoch of a source, as camera_capture first_epoch
  void Check() const;
};

class MessageValidator {
 public:
  explicit MessageValidator(const ValidationOptions& options = ValidationOptions());

  // The valid part of `msg` (same header and epoch); an empty array when the
  // whole message is refused (bad epoch, stamp). `now` [s]: wall-clock time
  // (a replay's simulated clock lags the bag's stamps at high rates; "the
  // future" is real time).
  slope_monitor::PointDisplacementArray Filter(const slope_monitor::PointDisplacementArray& msg,
                                               const std::string& topic, double now);
  // True when the block may be used; `expected_receiver` is the receiver the
  // topic belongs to.
  bool Accept(const slope_monitor::RadioSampleBlock& msg, const std::string& expected_receiver,
              double now);

  // Rejections so far by reason ("non-finite value", "bad identifier", ...).
  const std::map<std::string, uint64_t>& rejected() const { return rejected_; }
  uint64_t total_rejected() const;
  // Problems found by the last call, one line each, naming the topic and item.
  const std::vector<std::string>& last_problems() const { return problems_; }

  // Empty when the 3x3 covariance [m^2] is usable, else the reason.
  std::string CovarianceProblem(const Eigen::Matrix3d& covariance) const;

 private:
  void Reject(const std::string& reason, const std::string& detail);
  std::string PositionProblem(const Eigen::Vector3d& x) const;
  std::string StampProblem(double stamp, double now) const;
  std::string EpochProblem(const std::string& source, uint32_t epoch);

  ValidationOptions options_;
  std::map<std::string, uint32_t> last_epoch_;  // per source
  std::map<std::string, uint64_t> rejected_;
  std::vector<std::string> problems_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
