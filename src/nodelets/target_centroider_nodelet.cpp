// target_centroider: image_raw + camera_info -> targets (TargetObservationArray),
// debug_image (lazy), diagnostics. Thin: parameters once, convert, call
// targets::TargetCentroider, publish. With `site_file`, one channel per camera
// of kind fixed or uav the site lists (any number), on /<camera>/camera/...
// and /<camera>/targets; with graph_cameras and no site file that lists
// cameras, the same for io::DefaultCameras(). See doc/nodes/target_centroider.md.
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
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_file.h"
#include "slope_monitor/core/targets/options_reader.h"
#include "slope_monitor/core/targets/target_centroider.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/target_conversions.h"

namespace slope_monitor {

class TargetCentroiderNodelet : public nodelet::Nodelet {
 private:
  // One camera's input, outputs and counts. Without a site file the nodelet
  // has one, on topics relative to its namespace (image_raw, camera_info,
  // targets, debug_image); with one, a channel per camera of kind fixed or
  // uav that the site lists, on /<camera>/camera/image_raw (+ camera_info),
  // /<camera>/targets and /<camera>/debug_image.
  struct Channel {
    std::string name;
    double pixel_size = 1.0;
    std::unique_ptr<targets::TargetCentroider> centroider;  // its own libapriltag detector
    image_transport::CameraSubscriber sub;
    image_transport::Publisher debug_pub;
    ros::Publisher targets_pub;
    int frames = 0, errors = 0, last_detections = 0;  // guarded by stats_mutex_
    std::map<std::string, int> rejects;
    std::string last_error;
  };

  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    targets::NodeOptions node;
    targets::Options o;
    std::optional<io::SiteFile> site;
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          o = targets::ReadOptions(p);  // the same reader as the centroid_targets tool's
          node = targets::ReadNodeOptions(p);
          p.CheckNoUnknownKeys();
          o.Check();
          if (!node.site_file.empty()) site = io::LoadSiteFile(node.site_file);
        })) {
      // Bad parameters: nothing is measured, but the node stays up and says
      // why, throttled in the log and in diagnostics.
      config_error_ = *error;
      NODELET_ERROR("target_centroider: %s; not advertising", config_error_.c_str());
      updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
      updater_->setHardwareID(pnh.getNamespace());
      updater_->add("target_centroider", [this](diagnostic_updater::DiagnosticStatusWrapper& stat) {
        stat.summaryf(diagnostic_msgs::DiagnosticStatus::ERROR, "not running: %s",
                      config_error_.c_str());
      });
      diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) {
        NODELET_ERROR_THROTTLE(30.0, "target_centroider: not running: %s", config_error_.c_str());
        updater_->update();
      });
      return;
    }
    // A site without targets (a UAV flight tied by its tie points): no target
    // stage, as in process_bag; each photo gets its empty target list (the
    // adjuster counts the epoch's photos by them). A real flight's photos
    // would only give false circles.
    no_targets_ = site && io::SiteWithoutTargets(*site, node.target_list);
    if (no_targets_)
      NODELET_INFO(
          "target_centroider: site '%s' lists no targets and target list '%s' is not there: "
          "no target stage (an empty target list per photo)",
          site->name.c_str(), node.target_list.c_str());
    site_frame_ = node.site_frame;
    use_tf_pose_ = node.use_tf_pose && !no_targets_;
    const io::TargetList list = no_targets_ ? io::TargetList() : LoadTargets(node, site);
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
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    try {
      if ((site && !site->cameras.empty()) || node.graph_cameras) {
        // The site's cameras with targets, else the graph's default ones, in
        // one queue (images and poses in arrival order, as above); the camera
        // kind is the site's field.
        std::vector<io::SiteCamera> cameras;
        if (site && !site->cameras.empty())
          for (const io::SiteCamera* cam : site->CamerasWithTargets()) cameras.push_back(*cam);
        else
          for (const io::SiteCamera& cam : io::DefaultCameras())
            if (cam.kind != io::CameraKind::kFixedTargetless) cameras.push_back(cam);
        for (const io::SiteCamera& cam : cameras)
          AddChannel(cam.name, cam.pixel_size > 0.0 ? cam.pixel_size : node.pixel_size,
                     "/" + cam.name + "/camera/", "/" + cam.name + "/", o, list, node.queue_size);
        updater_->setHardwareID("target_centroider");
      } else {
        std::string name = node.camera_name;
        if (name.empty()) {
          name = ros::names::parentNamespace(nh.getNamespace());
          if (name.empty() || name == "/") name = nh.getNamespace();
          if (!name.empty() && name[0] == '/') name = name.substr(1);
        }
        AddChannel(name, node.pixel_size, "", "", o, list, node.queue_size);
        updater_->setHardwareID(name);
      }
    } catch (const Error& e) {
      NODELET_ERROR("target_centroider: %s; not advertising", e.what());
      channels_.clear();
      return;
    }
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
    start_ = ros::WallTime::now();
    if (channels_.size() > 1 || site) {
      const std::string from = site && !site->cameras.empty()
                                   ? "the site file '" + node.site_file + "'"
                                   : "the graph's defaults (no site file lists cameras)";
      NODELET_INFO("target_centroider: %zu camera(s) of %s", channels_.size(), from.c_str());
    }
  }

  // The site file's targets when it lists them, else target_list. A bad list:
  // keep measuring, but with no list every target is published as UNKNOWN
  // (never as a control point); said on every image (throttled) and in
  // diagnostics.
  io::TargetList LoadTargets(const targets::NodeOptions& node,
                             const std::optional<io::SiteFile>& site) {
    if (site && site->targets) return *site->targets;
    if (node.target_list.empty()) return io::TargetList();
    try {
      // YAML or a surveyors' CSV; names the file and the key
      return io::LoadTargetFileInSite(node.target_list, site ? &site->crs : nullptr);
    } catch (const Error& e) {
      target_list_error_ = Message("target list '", node.target_list, "' not used: ", e.what(),
                                   "; every target is published as unknown");
      NODELET_ERROR("target_centroider: %s", target_list_error_.c_str());
      return io::TargetList();
    }
  }

  // Throws Error (the centroider's options or families).
  void AddChannel(const std::string& name, double pixel_size, const std::string& input_prefix,
                  const std::string& output_prefix, const targets::Options& o,
                  const io::TargetList& list, int queue_size) {
    auto c = std::make_unique<Channel>();
    c->name = name;
    c->pixel_size = pixel_size;
    c->centroider = std::make_unique<targets::TargetCentroider>(o, list);
    ros::NodeHandle& nh = getNodeHandle();
    c->targets_pub = nh.advertise<TargetObservationArray>(output_prefix + "targets", 10);
    c->debug_pub = it_->advertise(output_prefix + "debug_image", 1);
    Channel* raw = c.get();
    c->sub = it_->subscribeCamera(
        input_prefix + "image_raw", queue_size,
        [this, raw](const sensor_msgs::ImageConstPtr& image,
                    const sensor_msgs::CameraInfoConstPtr& info) { OnImage(raw, image, info); });
    updater_->add(
        channels_.empty() && output_prefix.empty() ? "target_centroider"
                                                   : "target_centroider: " + name,
        [this, raw](diagnostic_updater::DiagnosticStatusWrapper& stat) { Diagnose(*raw, stat); });
    channels_.push_back(std::move(c));
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

  void OnImage(Channel* ch, const sensor_msgs::ImageConstPtr& image,
               const sensor_msgs::CameraInfoConstPtr& info) {
    if (!target_list_error_.empty()) {
      NODELET_ERROR_THROTTLE(30.0, "target_centroider: %s", target_list_error_.c_str());
    }
    if (no_targets_) {
      TargetObservationArray none;
      none.header = image->header;
      none.camera_name = ch->name;
      none.image_width = image->width;
      none.image_height = image->height;
      ch->targets_pub.publish(none);
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++ch->frames;
      return;
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
          ros_adapters::CentroidImage(*ch->centroider, *image, *info, site_from_optical, ch->name,
                                      ch->pixel_size, ch->sub.getTopic());
      const targets::Result& r = c.result;
      ch->targets_pub.publish(c.targets);
      if (ch->debug_pub.getNumSubscribers() > 0)
        ch->debug_pub.publish(ros_adapters::ToDebugImage(c, image->header));
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++ch->frames;
      ch->last_detections = r.observations.size();
      for (const auto& [reason, n] : r.summary.rejects_by_reason) ch->rejects[reason] += n;
    } catch (
        const std::exception& e) {  // slope_monitor::Error, cv_bridge::Exception, cv::Exception
      NODELET_ERROR_THROTTLE(5.0, "target_centroider: dropped image (topic %s, stamp %.3f): %s",
                             ch->sub.getTopic().c_str(), image->header.stamp.toSec(), e.what());
      std::lock_guard<std::mutex> lock(stats_mutex_);
      ++ch->errors;
      ch->last_error = e.what();
    }
  }

  void Diagnose(const Channel& ch, diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(stats_mutex_);
    const double elapsed = (ros::WallTime::now() - start_).toSec();
    stat.add("camera", ch.name);
    stat.add("frames", ch.frames);
    stat.add("frame rate [Hz]", elapsed > 0 ? ch.frames / elapsed : 0.0);
    stat.add("detections (last frame)", ch.last_detections);
    stat.add("dropped images", ch.errors);
    for (const auto& [reason, n] : ch.rejects) stat.add("rejected: " + reason, n);
    if (!target_list_error_.empty()) {
      stat.summaryf(diagnostic_msgs::DiagnosticStatus::ERROR, "%s", target_list_error_.c_str());
    } else if (ch.errors > 0) {
      stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%d images dropped; last: %s",
                    ch.errors, ch.last_error.c_str());
    } else if (ch.frames == 0) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no images yet");
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "measuring");
    }
  }

  std::vector<std::unique_ptr<Channel>> channels_;
  std::string site_frame_;
  std::string config_error_;       // bad parameters: the node only reports this
  std::string target_list_error_;  // bad target list: measuring without it
  bool no_targets_ = false;        // io::SiteWithoutTargets: empty target lists only
  bool use_tf_pose_ = true;
  std::unique_ptr<tf2_ros::Buffer> tf_buffer_;
  std::vector<ros::Subscriber> tf_subs_;
  std::set<std::string> static_frames_;  // child frames whose static pose is set
  std::unique_ptr<image_transport::ImageTransport> it_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  ros::WallTime start_;
  std::mutex stats_mutex_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::TargetCentroiderNodelet, nodelet::Nodelet)
