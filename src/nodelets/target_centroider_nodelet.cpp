// target_centroider: image_raw + camera_info -> targets (TargetObservationArray),
// debug_image (lazy), diagnostics. Thin: parameters once, convert, call
// targets::TargetCentroider, publish. See doc/nodes/target_centroider.md.
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/image_encodings.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/targets/options_reader.h"
#include "slope_monitor/core/targets/target_centroider.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/target_conversions.h"

namespace slope_monitor {

class TargetCentroiderNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    targets::NodeOptions node;
    targets::Options o;
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          o = targets::ReadOptions(p);  // the same reader as the centroid_targets tool's
          node = targets::ReadNodeOptions(p);
          p.CheckNoUnknownKeys();
          o.Check();
        })) {
      // Bad parameters: nothing is measured, but the node stays up and says
      // why, throttled in the log and in diagnostics.
      config_error_ = *error;
      NODELET_ERROR("target_centroider: %s; not advertising", config_error_.c_str());
      updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
      updater_->setHardwareID(pnh.getNamespace());
      updater_->add("target_centroider", this, &TargetCentroiderNodelet::Diagnose);
      diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
        NODELET_ERROR_THROTTLE(30.0, "target_centroider: not running: %s", config_error_.c_str());
        updater_->update();
      });
      return;
    }
    camera_name_ = node.camera_name;
    site_frame_ = node.site_frame;
    use_tf_pose_ = node.use_tf_pose;
    pixel_size_ = node.pixel_size;
    queue_size_ = node.queue_size;
    io::TargetList list;
    if (!node.target_list.empty()) {
      try {
        list = io::TargetList::Load(
            node.target_list);  // names the file and the key (e.g. a duplicate ID)
      } catch (const Error& e) {
        // A bad target list: keep measuring, but with no list every target is
        // published as UNKNOWN (never as a control point); said on every image
        // (throttled) and in diagnostics.
        target_list_error_ = Message("target list '", node.target_list, "' not used: ", e.what(),
                                     "; every target is published as unknown");
        NODELET_ERROR("target_centroider: %s", target_list_error_.c_str());
      }
    }
    try {
      centroider_ = std::make_unique<targets::TargetCentroider>(o, list);
    } catch (const Error& e) {
      NODELET_ERROR("target_centroider: %s; not advertising", e.what());
      return;
    }
    if (camera_name_.empty()) {
      camera_name_ = ros::names::parentNamespace(nh.getNamespace());
      if (camera_name_.empty() || camera_name_ == "/") camera_name_ = nh.getNamespace();
      if (!camera_name_.empty() && camera_name_[0] == '/') camera_name_ = camera_name_.substr(1);
    }
    if (use_tf_pose_) {
      // Poses from /tf and /tf_static on this nodelet's queue, in order with the
      // images. A camera's static pose is the first one received (the
      // installation's): the bundle adjuster republishes each fixed camera's
      // adjusted pose on /tf_static after every epoch, and whether that came
      // before or after the next epoch's image depends on the replay rate and
      // the CPU; the centroids (perspective correction) must not.
      tf_buffer_ = std::make_unique<tf2_ros::Buffer>();
      tf_subs_.push_back(nh.subscribe<tf2_msgs::TFMessage>(
          "/tf", 100, [this](const tf2_msgs::TFMessageConstPtr& m) { OnTf(*m, false); }));
      tf_subs_.push_back(nh.subscribe<tf2_msgs::TFMessage>(
          "/tf_static", 100, [this](const tf2_msgs::TFMessageConstPtr& m) { OnTf(*m, true); }));
    }
    it_ = std::make_unique<image_transport::ImageTransport>(nh);
    targets_pub_ = nh.advertise<TargetObservationArray>("targets", 10);
    debug_pub_ = it_->advertise("debug_image", 1);
    sub_ = it_->subscribeCamera("image_raw", queue_size_, &TargetCentroiderNodelet::OnImage, this);
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID(camera_name_);
    updater_->add("target_centroider", this, &TargetCentroiderNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
    start_ = ros::WallTime::now();
  }

  void OnTf(const tf2_msgs::TFMessage& tf, bool is_static) {
    for (const geometry_msgs::TransformStamped& t : tf.transforms) {
      if (is_static && !static_frames_.insert(t.child_frame_id).second)
        continue;  // the first pose stays
      try {
        tf_buffer_->setTransform(t, is_static ? "tf_static" : "tf", is_static);
      } catch (const std::exception& e) {
        NODELET_WARN_THROTTLE(10.0, "target_centroider: transform to '%s' ignored: %s",
                              t.child_frame_id.c_str(), e.what());
      }
    }
  }

  void OnImage(const sensor_msgs::ImageConstPtr& image,
               const sensor_msgs::CameraInfoConstPtr& info) {
    if (!target_list_error_.empty()) {
      NODELET_ERROR_THROTTLE(30.0, "target_centroider: %s", target_list_error_.c_str());
    }
    try {
      std::optional<Eigen::Isometry3d> site_from_optical;
      if (use_tf_pose_ && info->K[0] > 0) {
        try {
          site_from_optical = tf2::transformToEigen(tf_buffer_->lookupTransform(
              site_frame_, image->header.frame_id, image->header.stamp));
        } catch (const tf2::TransformException&) {
          // no pose: circles stay unidentified, no perspective correction
        }
      }
      const ros_adapters::CentroidedImage c =
          ros_adapters::CentroidImage(*centroider_, *image, *info, site_from_optical, camera_name_,
                                      pixel_size_, sub_.getTopic());
      const targets::Result& r = c.result;
      const TargetObservationArray& out = c.targets;
      targets_pub_.publish(out);
      if (debug_pub_.getNumSubscribers() > 0)
        debug_pub_.publish(ros_adapters::ToDebugImage(c, image->header));
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++frames_;
      last_detections_ = r.observations.size();
      for (const auto& [reason, n] : r.summary.rejects_by_reason) rejects_[reason] += n;
    } catch (
        const std::exception& e) {  // slope_monitor::Error, cv_bridge::Exception, cv::Exception
      NODELET_ERROR_THROTTLE(5.0, "target_centroider: dropped image (topic %s, stamp %.3f): %s",
                             sub_.getTopic().c_str(), image->header.stamp.toSec(), e.what());
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++errors_;
      last_error_ = e.what();
    }
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    if (!config_error_.empty()) {
      stat.summaryf(diagnostic_msgs::DiagnosticStatus::ERROR, "not running: %s",
                    config_error_.c_str());
      return;
    }
    const double elapsed = (ros::WallTime::now() - start_).toSec();
    stat.add("frames", frames_);
    stat.add("frame rate [Hz]", elapsed > 0 ? frames_ / elapsed : 0.0);
    stat.add("detections (last frame)", last_detections_);
    stat.add("dropped images", errors_);
    for (const auto& [reason, n] : rejects_) stat.add("rejected: " + reason, n);
    if (!target_list_error_.empty()) {
      stat.summaryf(diagnostic_msgs::DiagnosticStatus::ERROR, "%s", target_list_error_.c_str());
    } else if (errors_ > 0) {
      stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%d images dropped; last: %s", errors_,
                    last_error_.c_str());
    } else if (frames_ == 0) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no images yet");
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "measuring");
    }
  }

  std::unique_ptr<targets::TargetCentroider> centroider_;
  std::string camera_name_, site_frame_;
  std::string config_error_;       // bad parameters: the node only reports this
  std::string target_list_error_;  // bad target list: measuring without it
  bool use_tf_pose_ = true;
  double pixel_size_ = 1.0;
  int queue_size_ =
      100;  // images buffered while the detector is busy (a replayed survey comes in bursts)
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::vector<ros::Subscriber> tf_subs_;
  std::set<std::string> static_frames_;  // child frames whose static pose is set
  std::unique_ptr<image_transport::ImageTransport> it_;
  image_transport::CameraSubscriber sub_;
  image_transport::Publisher debug_pub_;
  ros::Publisher targets_pub_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  ros::WallTime start_;
  std::mutex stats_mutex_;
  int frames_ = 0, errors_ = 0, last_detections_ = 0;
  std::map<std::string, int> rejects_;
  std::string last_error_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::TargetCentroiderNodelet, nodelet::Nodelet)
