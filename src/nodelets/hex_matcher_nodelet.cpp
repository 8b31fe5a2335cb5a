// hex_matcher: targetless matching of image pairs on hexagonal pyramids,
// refined by modified least-squares correlation (core/matching/hex_matcher.h).
//
// Thin wrapper: parameters -> HexMatcherOptions / MatchPrior; images ->
// cv::Mat (single channel kept; colour converted to mono8); the core does
// the rest. Three modes (parameter `mode`):
//   pair:  image_a + image_b of the same epoch (two cameras) -> tie points;
//          a pair is the latest a and b whose stamps differ by <= max_pair_dt.
//   track: image (one camera); the first image received is the reference
//          epoch, every later image is matched against it with the
//          displacement prior (global shift from stable ground estimated).
//   sequence: image (one moving camera, e.g. the UAV) + optional
//          position_prior; each new image b is matched with earlier images a
//          of its epoch (core/matching/sequence.h: nearest priors within
//          max_pair_distance, else the previous sequence_depth images), the
//          prior shift from EstimateGlobalShift (core/matching/global_shift.h),
//          track IDs shared by all pairs of the same image a, pairs_b set.
//          Callbacks only queue; one worker thread matches the images in
//          arrival order (deterministic: no result depends on thread timing,
//          only on the prior being in when the image's turn comes, see
//          prior_wait).
// Output: tie_points (slope_monitor/TiePointArray, header of image b,
// per-match 2x2 covariance), diagnostics (matches, rejects by reason, time).
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <thread>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>

#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_polygons.h"
#include "slope_monitor/core/matching/global_shift.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/matching/sequence.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class HexMatcherNodelet : public nodelet::Nodelet {
 public:
  ~HexMatcherNodelet() override {
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      stop_ = true;
    }
    queue_cv_.notify_all();
    if (worker_.joinable()) worker_.join();
  }

 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          ReadParameters(pnh);
          matcher_ = std::make_unique<matching::HexMatcher>(options_);
        })) {
      NODELET_ERROR("hex_matcher: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(nh, pnh, "hex_matcher",
                                                                               "parameters rejected: " + *error);
      return;
    }
    pub_ = nh.advertise<slope_monitor::TiePointArray>("tie_points", 5);
    if (mode_ == "pair") {
      sub_a_ = nh.subscribe("image_a", 2, &HexMatcherNodelet::OnImageA, this);
      sub_b_ = nh.subscribe("image_b", 2, &HexMatcherNodelet::OnImageB, this);
    } else if (mode_ == "track") {
      sub_a_ = nh.subscribe("image", 2, &HexMatcherNodelet::OnTrackImage, this);
    } else {
      // Large queues: a fast bag replay must lose no image (the callbacks
      // only queue; the worker matches).
      sub_a_ = nh.subscribe("image", image_queue_, &HexMatcherNodelet::OnSequenceImage, this);
      sub_b_ = nh.subscribe("position_prior", image_queue_, &HexMatcherNodelet::OnPositionPrior, this);
      worker_ = std::thread([this] { SequenceWorker(); });
    }
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    updater_->setHardwareID("hex_matcher");
    updater_->add("matching", this, &HexMatcherNodelet::Diagnose);
    diag_timer_ = nh.createTimer(ros::Duration(1.0), [this](const ros::TimerEvent&) { updater_->update(); });
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    mode_ = p.String("mode", "pair", {"pair", "track", "sequence"});
    max_pair_dt_ = p.Double("max_pair_dt", 0.5, 0.0, 3600.0, "s");
    camera_a_ = p.String("camera_a", "cam_a");
    camera_b_ = p.String("camera_b", "cam_b");
    options_.pyramid_levels = p.Int("pyramid_levels", 3, 1, 6);
    options_.sampling = p.String("hex_sampling", "nearest", {"nearest", "interpolated"}) == "nearest"
                            ? matching::HexSampling::kNearest
                            : matching::HexSampling::kInterpolated;
    options_.profile_length = p.Int("profile_length", 4, 1, 16, "cells");
    options_.min_score = p.Double("min_score", 0.6, -1.0, 1.0);
    options_.max_ratio = p.Double("max_ratio", 0.85, 0.01, 1.0);
    options_.mutual_tolerance = p.Double("mutual_tolerance", 2.0, 0.1, 100.0, "px");
    options_.lsc_search_radius = p.Int("lsc_search_radius", 3, 0, 20, "px");
    options_.lsc_prefilter_sigma = p.Double("lsc_prefilter_sigma", 0.0, 0.0, 5.0, "px");
    options_.interest.log_sigma = p.Double("log_sigma", 2.0, 0.5, 10.0, "px");
    options_.interest.max_points = p.Int("max_points", 2000, 1, 100000);
    options_.interest.min_distance = p.Int("min_distance", 5, 1, 100, "px");
    options_.interest.min_gradient = p.Double("min_gradient", 4.0, 0.0, 1e6, "grey/px");
    options_.lsc.model = matching::LscModelFromName(p.String("lsc_model", "affine", {"affine", "shift"}));
    options_.lsc.interpolation =
        matching::InterpolationFromName(p.String("lsc_interpolation", "bicubic", {"bilinear", "bicubic"}));
    options_.lsc.gradient =
        matching::LscGradientFromName(p.String("lsc_gradient", "template", {"template", "resampled"}));
    options_.lsc.affine_min_f = p.Double("lsc_affine_min_f", 2.45, 0.0, 1e6);
    options_.lsc.half_window = p.Int("lsc_half_window", 5, 1, 50, "px");
    options_.lsc.estimate_gain = p.Bool("lsc_estimate_gain", false);
    options_.lsc.min_correlation = p.Double("lsc_min_correlation", 0.7, -1.0, 1.0);
    options_.lsc.max_sigma = p.Double("lsc_max_sigma", 0.5, 1e-6, 100.0, "px");
    options_.lsc.min_eigen_ratio = p.Double("lsc_min_eigen_ratio", 0.1, 0.0, 0.999);
    options_.lsc.max_shift_affine_correlation = p.Double("lsc_max_shift_affine_correlation", 1.0, 1e-6, 1.0);
    options_.lsc.fallback_affine_precision = p.Bool("lsc_fallback_affine_precision", false);
    options_.quality.enabled = p.Bool("quality_control", true);
    options_.quality.min_correlation = p.Double("quality_min_correlation", 0.8, -1.0, 1.0);
    options_.quality.max_residual_ratio = p.Double("quality_max_residual_ratio", 2.0, 1.0001, 1e6);
    options_.quality.two_way = p.Bool("quality_two_way", true);
    options_.quality.max_two_way = p.Double("quality_max_two_way", 0.5, 1e-6, 100.0, "px");
    options_.quality.neighbour_radius = p.Double("quality_neighbour_radius", 40.0, 1.0, 10000.0, "px");
    options_.quality.max_neighbour_deviation = p.Double("quality_max_neighbour_deviation", 1.5, 1e-6, 1000.0, "px");
    options_.quality.reject = p.Bool("quality_reject", false);
    prior_.radius = p.Double("search_radius", 24.0, 1.0, 1000.0, "px");
    prior_.moving_radius = p.Double("moving_radius", 48.0, 1.0, 1000.0, "px");
    const std::vector<double> shift = p.DoubleList("prior_shift", {0.0, 0.0});
    if (shift.size() != 2) throw ConfigError(p.FullKey("prior_shift") + " must have 2 values [px]");
    prior_.shift = Eigen::Vector2d(shift[0], shift[1]);
    prior_.estimate_global_shift = p.Bool("estimate_global_shift", mode_ == "track");
    // Operator's outline of known obstacles in image a: rectangles
    // [x0, y0, x1, y1, ...] [px]; matches there are flagged low quality.
    const std::vector<double> boxes = p.DoubleList("exclude_boxes", {});
    if (boxes.size() % 4 != 0) {
      throw ConfigError(p.FullKey("exclude_boxes") + " must hold 4 values per box (x0, y0, x1, y1) [px], got " +
                        std::to_string(boxes.size()));
    }
    for (size_t i = 0; i < boxes.size(); i += 4) {
      if (!(boxes[i] < boxes[i + 2] && boxes[i + 1] < boxes[i + 3])) {
        throw ConfigError(p.FullKey("exclude_boxes") + ": box " + std::to_string(i / 4) +
                          " needs x0 < x1 and y0 < y1");
      }
    }
    if (!boxes.empty()) {
      prior_.excluded = [boxes](const Eigen::Vector2d& x) {
        for (size_t i = 0; i < boxes.size(); i += 4) {
          if (x.x() >= boxes[i] && x.y() >= boxes[i + 1] && x.x() <= boxes[i + 2] && x.y() <= boxes[i + 3]) return true;
        }
        return false;
      };
    }
    // Track mode: the operator's stable area of the reference image
    // (polygons in pixels, io/image_polygons.h); the rest may move
    // (moving_radius) and only stable points give the global shift.
    const std::string stable_file = p.String("stable_polygons", "");
    if (!stable_file.empty()) {
      const auto stable = io::ReadImagePolygons(stable_file, p.FullKey("stable_polygons"));
      prior_.moving = [stable](const Eigen::Vector2d& x) { return !io::InsideAny(stable, x); };
      if (p.Bool("match_only_stable", false))
        prior_.within = [stable](const Eigen::Vector2d& x) { return io::InsideAny(stable, x); };
    } else if (p.Bool("match_only_stable", false)) {
      throw ConfigError(p.FullKey("match_only_stable") + " needs stable_polygons");
    }
    // Sequence mode (one moving camera).
    camera_ = p.String("camera", "uav");
    sequence_max_gap_ = p.Double("sequence_max_gap", 120.0, 0.0, 1e6, "s");
    pairing_.max_pair_distance = p.Double("max_pair_distance", 30.0, 0.01, 1e5, "m");
    pairing_.max_pairs_per_image = p.Int("max_pairs_per_image", 4, 1, 100);
    pairing_.sequence_depth = p.Int("sequence_depth", 2, 1, 100);
    position_prior_max_dt_ = p.Double("position_prior_max_dt", 0.1, 0.0, 60.0, "s");
    site_frame_ = p.String("site_frame", "site");
    prior_wait_ = p.Double("prior_wait", 2.0, 0.0, 600.0, "s");
    image_queue_ = p.Int("image_queue", 200, 1, 100000);
    sequence_border_ = p.Double("sequence_border", 12.0, 0.0, 1000.0, "px");
    shift_options_.max_size = p.Int("shift_max_size", 320, 32, 4096, "px");
    shift_options_.min_response = p.Double("shift_min_response", 0.01, 0.0, 1.0);
    shift_options_.min_overlap_correlation = p.Double("shift_min_overlap_correlation", 0.55, -1.0, 1.0);
    shift_options_.min_overlap = p.Int("shift_min_overlap", 48, 8, 100000, "px");
    shift_options_.min_overlap_fraction = p.Double("shift_min_overlap_fraction", 0.1, 0.0, 0.99);
    shift_options_.candidates = p.Int("shift_candidates", 32, 1, 100);
    shift_options_.taper = p.Double("shift_taper", 0.1, 0.01, 0.5);
    shift_options_.refine = p.Bool("shift_refine", true);
    shift_options_.refine_factor = p.Int("shift_refine_factor", 2, 1, 16);
    // Interest points per image a in sequence mode (0: max_points). Half the
    // default: measured 0.90 s instead of 1.23 s per 1280 x 960 pair with the
    // same precision (bench_hex_matcher_sequence).
    const int sequence_max_points = p.Int("sequence_max_points", 1000, 0, 100000);
    if (mode_ == "sequence" && sequence_max_points > 0) options_.interest.max_points = sequence_max_points;
    p.CheckNoUnknownKeys();
    options_.Check();
    pairing_.Check();
    shift_options_.Check();
  }

  static cv::Mat ToMat(const sensor_msgs::ImageConstPtr& msg) {
    if (sensor_msgs::image_encodings::numChannels(msg->encoding) == 1) {
      return cv_bridge::toCvShare(msg)->image;
    }
    return cv_bridge::toCvShare(msg, sensor_msgs::image_encodings::MONO8)->image;
  }

  void OnImageA(const sensor_msgs::ImageConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_a_ = msg;
    TryPair();
  }
  void OnImageB(const sensor_msgs::ImageConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    last_b_ = msg;
    TryPair();
  }
  void TryPair() {
    if (!last_a_ || !last_b_) return;
    if (std::fabs((last_a_->header.stamp - last_b_->header.stamp).toSec()) > max_pair_dt_) return;
    Process(last_a_, last_b_, prior_, camera_a_, camera_b_);
    last_a_.reset();
    last_b_.reset();
  }

  void OnTrackImage(const sensor_msgs::ImageConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!reference_) {
      reference_ = msg;
      NODELET_INFO("hex_matcher: reference image at %.3f", msg->header.stamp.toSec());
      return;
    }
    Process(reference_, msg, prior_, camera_a_, camera_a_);
  }

  void Process(const sensor_msgs::ImageConstPtr& a, const sensor_msgs::ImageConstPtr& b,
               const matching::MatchPrior& prior, const std::string& cam_a, const std::string& cam_b) {
    matching::HexMatchResult r;
    try {
      r = matcher_->Match(ToMat(a), ToMat(b), prior);
    } catch (const std::exception& e) {
      ++errors_;
      last_error_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "hex_matcher: dropping pair %s / %s: %s", a->header.frame_id.c_str(),
                             b->header.frame_id.c_str(), e.what());
      return;
    }
    slope_monitor::TiePointArray out;
    out.header = b->header;
    out.header_a = a->header;
    out.camera_a = cam_a;
    out.camera_b = cam_b;
    for (const matching::HexMatch& m : r.matches) {
      slope_monitor::TiePoint t;
      t.xa = m.xa.x();
      t.ya = m.xa.y();
      t.xb = m.xb.x();
      t.yb = m.xb.y();
      t.covariance = {m.covariance(0, 0), m.covariance(0, 1), m.covariance(1, 0), m.covariance(1, 1)};
      t.correlation = m.correlation;
      t.quality = m.quality;
      t.method = slope_monitor::TiePoint::METHOD_LSC;
      out.points.push_back(t);
    }
    pub_.publish(out);
    last_summary_ = r.summary;
    ++pairs_;
  }

  // ---- sequence mode ----
  struct Pending {
    sensor_msgs::ImageConstPtr msg;
    ros::WallTime received;
  };
  struct Earlier {
    sensor_msgs::ImageConstPtr msg;
    cv::Mat image;
    matching::SequenceImage info;
  };

  void OnSequenceImage(const sensor_msgs::ImageConstPtr& msg) {
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      pending_.push_back({msg, ros::WallTime::now()});
    }
    queue_cv_.notify_all();
  }

  void OnPositionPrior(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    if (!msg->header.frame_id.empty() && msg->header.frame_id != site_frame_) {
      NODELET_ERROR_THROTTLE(5.0, "hex_matcher: position_prior in frame '%s', expected '%s' (site_frame); ignored",
                             msg->header.frame_id.c_str(), site_frame_.c_str());
      std::lock_guard<std::mutex> lock(mutex_);
      ++bad_priors_;
      return;
    }
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      priors_.push_back(msg);
      latest_prior_ = std::max(latest_prior_, msg->header.stamp.toSec());
    }
    queue_cv_.notify_all();
  }

  // The front image may be matched: its prior is in, the priors have moved
  // past it, or it waited prior_wait (wall time) for one. Caller holds
  // queue_mutex_.
  bool FrontReady() const {
    if (pending_.empty()) return false;
    const double t = pending_.front().msg->header.stamp.toSec();
    if (latest_prior_ > t + position_prior_max_dt_) return true;
    for (const auto& p : priors_) {
      if (std::fabs(p->header.stamp.toSec() - t) <= position_prior_max_dt_) return true;
    }
    return (ros::WallTime::now() - pending_.front().received).toSec() >= prior_wait_;
  }

  void SequenceWorker() {
    while (true) {
      Pending next;
      geometry_msgs::PoseWithCovarianceStampedConstPtr prior;
      {
        std::unique_lock<std::mutex> lock(queue_mutex_);
        while (!stop_ && !FrontReady()) queue_cv_.wait_for(lock, std::chrono::milliseconds(50));
        if (stop_) return;
        next = pending_.front();
        pending_.pop_front();
        const double t = next.msg->header.stamp.toSec();
        double best = position_prior_max_dt_;
        for (const auto& p : priors_) {
          const double dt = std::fabs(p->header.stamp.toSec() - t);
          if (dt <= best) {
            best = dt;
            prior = p;
          }
        }
        // Priors older than this image (images arrive in time order) are done.
        while (!priors_.empty() && priors_.front()->header.stamp.toSec() < t - position_prior_max_dt_) {
          priors_.pop_front();
        }
      }
      try {
        ProcessSequenceImage(next.msg, prior);
      } catch (const std::exception& e) {
        // Not expected (pairs catch their own errors); keep the worker alive.
        NODELET_ERROR_THROTTLE(5.0, "hex_matcher: sequence image at %.3f: %s", next.msg->header.stamp.toSec(),
                               e.what());
      }
    }
  }

  slope_monitor::TiePointArray SequenceMessage(const sensor_msgs::ImageConstPtr& b, const Earlier* a,
                                               uint32_t pairs_b) const {
    slope_monitor::TiePointArray out;
    out.header = b->header;
    if (a != nullptr) {
      out.header_a = a->msg->header;
      out.camera_a = camera_;
      out.epoch_a = epoch_;
    }
    out.camera_b = camera_;
    out.epoch_b = epoch_;
    out.pairs_b = pairs_b;
    return out;
  }

  void ProcessSequenceImage(const sensor_msgs::ImageConstPtr& b,
                            const geometry_msgs::PoseWithCovarianceStampedConstPtr& prior) {
    const double t = b->header.stamp.toSec();
    Earlier current;
    current.msg = b;
    current.info.serial = ++serial_;
    current.info.stamp = t;
    if (prior) {
      current.info.has_position = true;
      current.info.position = Eigen::Vector2d(prior->pose.pose.position.x, prior->pose.pose.position.y);
    }
    // A new epoch (flight) after a gap, or when the stamps run backwards (a bag replayed again).
    if (history_.empty() || t - last_stamp_ > sequence_max_gap_ || t < last_stamp_) {
      if (!history_.empty()) NODELET_INFO("hex_matcher: new sequence epoch at %.3f", t);
      history_.clear();
      ++epoch_;
    }
    last_stamp_ = t;
    std::string convert_error;
    try {
      current.image = ToMat(b);
    } catch (const std::exception& e) {
      convert_error = std::string("image at ") + std::to_string(t) + ": " + e.what();
    }
    std::vector<matching::SequenceImage> infos;
    for (const Earlier& e : history_) infos.push_back(e.info);
    const std::vector<size_t> plan = matching::PlanSequencePairs(infos, current.info, pairing_);
    const uint32_t n = static_cast<uint32_t>(std::max<size_t>(1, plan.size()));
    if (plan.empty()) {
      pub_.publish(SequenceMessage(b, nullptr, 1));
      std::lock_guard<std::mutex> lock(mutex_);
      ++sequence_images_;
      ++unpaired_;
    }
    for (const size_t& k : plan) {
      const Earlier& a = history_[k];
      slope_monitor::TiePointArray out = SequenceMessage(b, &a, n);
      std::string failure, reason;
      matching::HexMatchResult r;
      matching::GlobalShiftResult gs;
      try {
        if (!convert_error.empty()) throw InvalidArgument(convert_error);
        gs = matching::EstimateGlobalShift(a.image, current.image, shift_options_);
        if (!gs.usable) {
          reason = "shift_unusable";
          failure = "global shift not usable: " + gs.reason;
        } else {
          matching::MatchPrior pr = prior_;
          pr.shift = gs.shift;
          const cv::Size size = current.image.size();
          const double border = sequence_border_;
          const Eigen::Vector2d shift = gs.shift;
          // Only the points of a that the shift puts inside b.
          pr.within = [size, border, shift](const Eigen::Vector2d& x) {
            const Eigen::Vector2d y = x + shift;
            return y.x() >= border && y.y() >= border && y.x() <= size.width - 1 - border &&
                   y.y() <= size.height - 1 - border;
          };
          r = matcher_->Match(a.image, current.image, pr);
          for (const matching::HexMatch& m : r.matches) {
            slope_monitor::TiePoint tp;
            tp.id = matching::SequenceTrackId(a.info.serial, m.xa, a.image.cols);
            tp.xa = m.xa.x();
            tp.ya = m.xa.y();
            tp.xb = m.xb.x();
            tp.yb = m.xb.y();
            tp.covariance = {m.covariance(0, 0), m.covariance(0, 1), m.covariance(1, 0), m.covariance(1, 1)};
            tp.correlation = m.correlation;
            tp.quality = m.quality;
            tp.method = slope_monitor::TiePoint::METHOD_LSC;
            out.points.push_back(tp);
          }
        }
      } catch (const std::exception& e) {
        reason = "error";
        failure = e.what();
        out.points.clear();
      }
      if (!failure.empty()) {
        NODELET_ERROR_THROTTLE(5.0, "hex_matcher: sequence pair %.3f / %.3f failed (empty tie points): %s",
                               a.info.stamp, t, failure.c_str());
      }
      pub_.publish(out);
      if (failure.empty()) {
        int low = 0;
        for (const auto& m : r.matches) low += m.IsLowQuality() ? 1 : 0;
        NODELET_INFO("hex_matcher: sequence pair %.3f / %.3f (%zu of %u): shift (%.1f, %.1f) px (NCC %.2f), %zu tie "
                     "points (%d low quality) of %d candidates in %.2f s",
                     a.info.stamp, t, static_cast<size_t>(&k - plan.data()) + 1, n, gs.shift.x(), gs.shift.y(),
                     gs.overlap_correlation, r.matches.size(), low, r.summary.candidates, r.summary.seconds);
      }
      std::lock_guard<std::mutex> lock(mutex_);
      ++pairs_;
      if (!failure.empty()) {
        ++failed_pairs_[reason];
        // An unusable shift (photos that hardly overlap) is normal in a
        // flight; only errors (bad images) make the status WARN.
        if (reason == "error") {
          ++errors_;
          last_error_ = failure;
        }
      } else {
        last_summary_ = r.summary;
        last_shift_ = gs;
      }
    }
    if (!plan.empty()) {
      std::lock_guard<std::mutex> lock(mutex_);
      ++sequence_images_;
    }
    // Keep b as a partner of later images unless it cannot be matched (its
    // conversion failed, or its size or encoding differs from the epoch's).
    const bool keep = convert_error.empty() &&
                      (history_.empty() || (history_.front().image.size() == current.image.size() &&
                                            history_.front().image.type() == current.image.type()));
    if (keep) {
      history_.push_back(current);
      if (history_.size() > kMaxHistory) history_.erase(history_.begin());
    }
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (errors_ > 0 && !last_error_.empty()) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "last pair dropped: " + last_error_);
    } else if (pairs_ == 0) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "waiting for images");
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "matching");
    }
    stat.add("mode", mode_);
    stat.add("pairs", pairs_);
    stat.add("dropped", errors_);
    stat.add("candidates", last_summary_.candidates);
    stat.add("matches", last_summary_.matched);
    stat.add("low quality", last_summary_.low_quality);
    for (const auto& kv : last_summary_.flags) stat.add("flag " + kv.first, kv.second);
    stat.add("time [s]", last_summary_.seconds);
    for (const auto& kv : last_summary_.rejects) stat.add("reject " + kv.first, kv.second);
    if (mode_ == "sequence") {
      stat.add("images", sequence_images_);
      stat.add("images without partner", unpaired_);
      stat.add("bad position priors", bad_priors_);
      for (const auto& kv : failed_pairs_) stat.add("failed pairs " + kv.first, kv.second);
      stat.add("last shift x [px]", last_shift_.shift.x());
      stat.add("last shift y [px]", last_shift_.shift.y());
      stat.add("last shift response", last_shift_.response);
      stat.add("last shift overlap correlation", last_shift_.overlap_correlation);
    }
  }

  std::string mode_;
  double max_pair_dt_ = 0.5;
  std::string camera_a_, camera_b_;
  matching::HexMatcherOptions options_;
  matching::MatchPrior prior_;
  std::unique_ptr<matching::HexMatcher> matcher_;
  ros::Publisher pub_;
  ros::Subscriber sub_a_, sub_b_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::Timer diag_timer_;
  std::mutex mutex_;
  sensor_msgs::ImageConstPtr last_a_, last_b_, reference_;
  matching::HexMatchSummary last_summary_;
  int pairs_ = 0, errors_ = 0;
  std::string last_error_;
  // Sequence mode.
  static constexpr size_t kMaxHistory = 300;  // images kept per epoch (~1.2 MB each at 1280 x 960)
  std::string camera_, site_frame_;
  double sequence_max_gap_ = 120.0, position_prior_max_dt_ = 0.1, prior_wait_ = 2.0, sequence_border_ = 12.0;
  int image_queue_ = 200;
  matching::SequencePairOptions pairing_;
  matching::GlobalShiftOptions shift_options_;
  std::mutex queue_mutex_;  // pending_, priors_, latest_prior_, stop_
  std::condition_variable queue_cv_;
  std::deque<Pending> pending_;
  std::deque<geometry_msgs::PoseWithCovarianceStampedConstPtr> priors_;
  double latest_prior_ = -1e300;
  bool stop_ = false;
  std::thread worker_;
  // Worker only.
  std::vector<Earlier> history_;
  uint32_t serial_ = 0, epoch_ = 0;
  double last_stamp_ = 0.0;
  // Diagnostics (mutex_).
  int sequence_images_ = 0, unpaired_ = 0, bad_priors_ = 0;
  std::map<std::string, int> failed_pairs_;
  matching::GlobalShiftResult last_shift_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics> setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::HexMatcherNodelet, nodelet::Nodelet)
