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
//          position_prior -> matching::SequenceMatcher; with site_file, the
//          site's camera of kind uav on its own topics
//          (ros/hex_matcher_parameters.h)
//          (core/matching/sequence_matcher.h: pairs, prior association by
//          messages, epochs, pair method, track IDs, pairs_b; process_bag
//          --uav-tie-points runs the same). Callbacks only queue; one worker
//          thread (ros/worker_queue.h) feeds the images and priors to it in
//          arrival order and polls it with the wall clock (prior_wait, live
//          sensors only; not in a replay, ros/setup.h LiveTimeouts).
// Output: tie_points (slope_monitor/TiePointArray, header of image b,
// per-match 2x2 covariance), diagnostics (matches, rejects by reason, time).
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/matching/sequence_matcher.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"
#include "slope_monitor/ros/sequence_conversions.h"
#include "slope_monitor/ros/sequence_step.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/worker_queue.h"

namespace slope_monitor {

class HexMatcherNodelet : public nodelet::Nodelet {
 public:
  // The worker stops (after the input it is matching) before the rest goes.
  ~HexMatcherNodelet() override { queue_.reset(); }

 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          ReadParameters(pnh);
          matcher_ = std::make_unique<matching::HexMatcher>(params_.hex);
          if (mode_ == "sequence")
            sequence_ = std::make_unique<ros_adapters::SequenceMatcherStep>(params_);
        })) {
      NODELET_ERROR("hex_matcher: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "hex_matcher", "parameters rejected: " + *error);
      return;
    }
    if (!params_.idle
             .empty()) {  // a site with targets, started by the graph (only_without_targets)
      NODELET_INFO("hex_matcher: idle: %s", params_.idle.c_str());
      return;
    }
    // tie_topic: "tie_points", or the site's UAV camera's /<camera>/tie_points.
    pub_ = nh.advertise<slope_monitor::TiePointArray>(params_.tie_topic, 5);
    if (mode_ == "pair") {
      sub_a_ = nh.subscribe("image_a", 2, &HexMatcherNodelet::OnImageA, this);
      sub_b_ = nh.subscribe("image_b", 2, &HexMatcherNodelet::OnImageB, this);
    } else if (mode_ == "track") {
      sub_a_ = nh.subscribe("image", 2, &HexMatcherNodelet::OnTrackImage, this);
    } else {
      // Large queues: a fast bag replay must lose no image (the callbacks
      // only queue; the worker matches).
      queue_ = std::make_unique<ros_adapters::WorkerQueue<Input>>(
          [this](const std::optional<Input>& in) { SequenceStep(in); },
          std::chrono::milliseconds(50));
      sub_a_ = nh.subscribe(params_.image_topic, params_.image_queue,
                            &HexMatcherNodelet::OnSequenceImage, this);
      sub_b_ = nh.subscribe(params_.prior_topic, params_.image_queue,
                            &HexMatcherNodelet::OnPositionPrior, this);
      end_sub_ = ros_adapters::SubscribeEndOfInput(nh, ros_adapters::kEndOfMatching,
                                                   [this] { OnEndOfInput(); });
    }
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh, getName());
    updater_->setHardwareID("hex_matcher");
    updater_->add("matching", this, &HexMatcherNodelet::Diagnose);
    diag_timer_ =
        nh.createTimer(ros::Duration(1.0), [this](const ros::TimerEvent&) { updater_->update(); });
  }

  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    params_ = ros_adapters::ReadHexMatcherParameters(p);
    mode_ = params_.mode;
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
    if (std::fabs((last_a_->header.stamp - last_b_->header.stamp).toSec()) > params_.max_pair_dt)
      return;
    Process(last_a_, last_b_, params_.prior, params_.camera_a, params_.camera_b);
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
    Process(reference_, msg, params_.prior, params_.camera_a, params_.camera_a);
  }

  void Process(const sensor_msgs::ImageConstPtr& a, const sensor_msgs::ImageConstPtr& b,
               const matching::MatchPrior& prior, const std::string& cam_a,
               const std::string& cam_b) {
    matching::HexMatchResult r;
    try {
      r = matcher_->Match(ros_adapters::ImageForMatching(a), ros_adapters::ImageForMatching(b),
                          prior);
    } catch (const std::exception& e) {
      ++errors_;
      last_error_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "hex_matcher: dropping pair %s / %s: %s",
                             a->header.frame_id.c_str(), b->header.frame_id.c_str(), e.what());
      return;
    }
    pub_.publish(ros_adapters::ToMsg(r, a->header, b->header, cam_a, cam_b));
    last_summary_ = r.summary;
    ++pairs_;
  }

  // ---- sequence mode: inputs queued in arrival order, fed to the core by the worker ----
  struct Input {
    sensor_msgs::ImageConstPtr image;  // or
    geometry_msgs::PoseWithCovarianceStampedConstPtr prior;
    bool end_of_input = false;  // or the end of a replay (ros/setup.h)
  };

  void OnEndOfInput() { queue_->Push({nullptr, nullptr, true}); }

  void OnSequenceImage(const sensor_msgs::ImageConstPtr& msg) { queue_->Push({msg, nullptr}); }

  void OnPositionPrior(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    if (const auto why = sequence_->CheckPrior(*msg)) {
      NODELET_ERROR_THROTTLE(5.0, "hex_matcher: %s", why->c_str());
      std::lock_guard<std::mutex> lock(mutex_);
      ++bad_priors_;
      return;
    }
    queue_->Push({nullptr, msg});
  }

  // The worker's next input (none: nothing came for 50 ms).
  void SequenceStep(const std::optional<Input>& next) {
    const double now = ros::WallTime::now().toSec();
    ros_adapters::SequenceOutput out;
    if (next && next->image) {
      // Replay: no prior_wait, so an image waits for a prior only when the
      // bag has a prior topic (its player advertises every topic at start),
      // as process_bag decides it.
      if (!ros_adapters::LiveTimeouts())
        sequence_->matcher().SetPriorsExpected(sub_b_.getNumPublishers() > 0);
      out = sequence_->AddImage(next->image, now);
    } else if (next && next->prior) {
      out = sequence_->AddPrior(*next->prior);
    } else if (next && next->end_of_input) {
      NODELET_INFO("hex_matcher: end of the replay: matching the photos still waiting");
      out = sequence_->Finish();
    } else if (ros_adapters::LiveTimeouts()) {
      out = sequence_->Poll(now);
    }
    Publish(out);
  }

  void Publish(const ros_adapters::SequenceOutput& out) {
    for (const ros_adapters::LogLine& line : out.log) {
      if (line.level == ros_adapters::LogLine::kError)
        NODELET_ERROR_THROTTLE(5.0, "hex_matcher: %s", line.text.c_str());
      else  // the matcher's lines and each pair's progress
        NODELET_INFO("hex_matcher: %s", line.text.c_str());
    }
    for (const slope_monitor::TiePointArray& msg : out.tie_points) pub_.publish(msg);
    std::lock_guard<std::mutex> lock(mutex_);
    summary_ = sequence_->matcher().summary();
    pairs_ = summary_.pairs;
    errors_ = summary_.errors;
    last_error_ = summary_.last_error;
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
      stat.add("pair method", matching::SequencePairMethodName(params_.sequence.method));
      stat.add("images", summary_.images);
      stat.add("images without partner", summary_.unpaired);
      stat.add("sequence pairs", summary_.pairs);
      stat.add("tie points", summary_.tie_points);
      stat.add("bad images", summary_.errors);
      stat.add("bad position priors", bad_priors_);
      stat.add("position priors given up (prior_wait)", summary_.prior_timeouts);
      for (const auto& kv : summary_.failed_pairs) stat.add("failed pairs " + kv.first, kv.second);
      stat.add("epoch", summary_.epoch);
      stat.add("photos in memory", summary_.images_in_memory);
      stat.add("memory [MB]", summary_.memory_bytes / (1024.0 * 1024.0));
      stat.add("photos released", summary_.released);
    }
  }

  std::string mode_;
  ros_adapters::HexMatcherParameters params_;
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
  std::unique_ptr<ros_adapters::SequenceMatcherStep> sequence_;  // worker only (and CheckPrior)
  std::unique_ptr<ros_adapters::WorkerQueue<Input>> queue_;      // the inputs, to the worker
  ros::Subscriber end_sub_;  // replay only: the end of the input
  // Diagnostics (mutex_).
  int bad_priors_ = 0;
  matching::SequenceMatcherSummary summary_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::HexMatcherNodelet, nodelet::Nodelet)
