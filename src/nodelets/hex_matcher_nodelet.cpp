// hex_matcher: targetless matching of image pairs on hexagonal pyramids,
// refined by modified least-squares correlation (core/matching/hex_matcher.h).
//
// Thin wrapper: parameters -> HexMatcherOptions / MatchPrior; images ->
// cv::Mat (single channel kept; colour converted to mono8); the core does
// the rest. Two modes (parameter `mode`):
//   pair:  image_a + image_b of the same epoch (two cameras) -> tie points;
//          a pair is the latest a and b whose stamps differ by <= max_pair_dt.
//   track: image (one camera); the first image received is the reference
//          epoch, every later image is matched against it with the
//          displacement prior (global shift from stable ground estimated).
// Output: tie_points (slope_monitor/TiePointArray, header of image b,
// per-match 2x2 covariance), diagnostics (matches, rejects by reason, time).
#include <memory>
#include <mutex>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>

#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class HexMatcherNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          ReadParameters(pnh);
          matcher_ = std::make_unique<matching::HexMatcher>(options_);
        })) {
      NODELET_ERROR("hex_matcher: %s; not advertising", error->c_str());
      return;
    }
    pub_ = nh.advertise<slope_monitor::TiePointArray>("tie_points", 5);
    if (mode_ == "pair") {
      sub_a_ = nh.subscribe("image_a", 2, &HexMatcherNodelet::OnImageA, this);
      sub_b_ = nh.subscribe("image_b", 2, &HexMatcherNodelet::OnImageB, this);
    } else {
      sub_a_ = nh.subscribe("image", 2, &HexMatcherNodelet::OnTrackImage, this);
    }
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    updater_->setHardwareID("hex_matcher");
    updater_->add("matching", this, &HexMatcherNodelet::Diagnose);
    diag_timer_ = nh.createTimer(ros::Duration(1.0), [this](const ros::TimerEvent&) { updater_->update(); });
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    mode_ = p.String("mode", "pair", {"pair", "track"});
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
    p.CheckNoUnknownKeys();
    options_.Check();
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
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::HexMatcherNodelet, nodelet::Nodelet)
