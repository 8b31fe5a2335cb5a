// target_centroider: image_raw + camera_info -> targets (TargetObservationArray),
// debug_image (lazy), diagnostics. Thin: parameters once, convert, call
// ros_adapters::TargetCentroiderStep (shared with process_bag), publish. With `site_file`, one
// channel per camera of kind fixed or uav the site lists (any number), on /<camera>/camera/... and
// /<camera>/targets; with graph_cameras and no site file that lists cameras, the same for
// io::DefaultCameras(). See doc/nodes/target_centroider.md.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <tf2_msgs/TFMessage.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/target_centroider_step.h"

namespace slope_monitor {

class TargetCentroiderNodelet : public nodelet::Nodelet {
 private:
  // One camera's input, outputs and counts. Without a site file the nodelet
  // has one, on topics relative to its namespace (image_raw, camera_info,
  // targets, debug_image); with one, a channel per camera of kind fixed or
  // uav that the site lists, on /<camera>/camera/image_raw (+ camera_info),
  // /<camera>/targets and /<camera>/debug_image.
  struct Channel {
    std::unique_ptr<ros_adapters::TargetCentroiderStep> step;  // its own libapriltag detector
    image_transport::CameraSubscriber sub;
    image_transport::Publisher debug_pub;
    ros::Publisher targets_pub;
  };

  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    ros_adapters::TargetCentroiderParameters params;
    const targets::NodeOptions& node = params.node;
    std::optional<io::SiteFile> site;
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          params = ros_adapters::ReadTargetCentroiderParameters(p);
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
    const bool no_targets = site && io::SiteWithoutTargets(*site, node.target_list);
    if (no_targets)
      NODELET_INFO(
          "target_centroider: site '%s' lists no targets and target list '%s' is not there: "
          "no target stage (an empty target list per photo)",
          site->name.c_str(), node.target_list.c_str());
    std::optional<io::TargetList> list;
    if (!no_targets) list = LoadTargets(node, site);
    if (node.use_tf_pose && !no_targets) {
      // Poses from /tf and /tf_static on this nodelet's queue, in order with
      // the images; a camera's static pose is the first one received
      // (ros_adapters::CameraPoses).
      poses_ = std::make_unique<ros_adapters::CameraPoses>(tf2::BufferCore::DEFAULT_CACHE_TIME);
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
          AddChannel(cam.name, ros_adapters::CameraPixelSize(node, &cam),
                     "/" + cam.name + "/camera/", "/" + cam.name + "/", params, list);
        updater_->setHardwareID("target_centroider");
      } else {
        std::string name = node.camera_name;
        if (name.empty()) {
          name = ros::names::parentNamespace(nh.getNamespace());
          if (name.empty() || name == "/") name = nh.getNamespace();
          if (!name.empty() && name[0] == '/') name = name.substr(1);
        }
        AddChannel(name, node.pixel_size, "", "", params, list);
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
    try {
      // YAML or a surveyors' CSV; names the file and the key
      return ros_adapters::CentroiderTargets(node, site ? &*site : nullptr);
    } catch (const Error& e) {
      target_list_error_ = Message("target list '", node.target_list, "' not used: ", e.what(),
                                   "; every target is published as unknown");
      NODELET_ERROR("target_centroider: %s", target_list_error_.c_str());
      return io::TargetList();
    }
  }

  // Throws Error (the centroider's options or families).
  void AddChannel(const std::string& name, double pixel_size, const std::string& input_prefix,
                  const std::string& output_prefix,
                  const ros_adapters::TargetCentroiderParameters& params,
                  const std::optional<io::TargetList>& list) {
    auto c = std::make_unique<Channel>();
    ros::NodeHandle& nh = getNodeHandle();
    c->step = std::make_unique<ros_adapters::TargetCentroiderStep>(
        name, pixel_size, params, list, nh.resolveName(input_prefix + "image_raw"));
    c->targets_pub = nh.advertise<TargetObservationArray>(output_prefix + "targets", 10);
    c->debug_pub = it_->advertise(output_prefix + "debug_image", 1);
    Channel* raw = c.get();
    c->sub = it_->subscribeCamera(
        input_prefix + "image_raw", params.node.queue_size,
        [this, raw](const sensor_msgs::ImageConstPtr& image,
                    const sensor_msgs::CameraInfoConstPtr& info) { OnImage(raw, image, info); });
    updater_->add(channels_.empty() && output_prefix.empty() ? "target_centroider"
                                                             : "target_centroider: " + name,
                  [this, raw](diagnostic_updater::DiagnosticStatusWrapper& stat) {
                    raw->step->Diagnose(stat, (ros::WallTime::now() - start_).toSec(),
                                        target_list_error_);
                  });
    channels_.push_back(std::move(c));
  }

  void OnTf(const tf2_msgs::TFMessage& tf, bool is_static) {
    std::vector<std::string> problems;
    poses_->Add(tf, is_static, &problems);
    for (const std::string& p : problems)
      NODELET_WARN_THROTTLE(10.0, "target_centroider: %s", p.c_str());
  }

  void OnImage(Channel* ch, const sensor_msgs::ImageConstPtr& image,
               const sensor_msgs::CameraInfoConstPtr& info) {
    if (!target_list_error_.empty()) {
      NODELET_ERROR_THROTTLE(30.0, "target_centroider: %s", target_list_error_.c_str());
    }
    ros_adapters::TargetCentroiderStep& step = *ch->step;
    try {
      const ros_adapters::CentroidedImage c = step.Centroid(
          *image, *info,
          poses_ ? step.Pose(poses_->buffer(), *image, *info) : std::optional<Eigen::Isometry3d>());
      ch->targets_pub.publish(c.targets);
      if (step.has_targets() && ch->debug_pub.getNumSubscribers() > 0)
        ch->debug_pub.publish(ros_adapters::ToDebugImage(c, image->header));
      step.Count(c);
    } catch (
        const std::exception& e) {  // slope_monitor::Error, cv_bridge::Exception, cv::Exception
      NODELET_ERROR_THROTTLE(5.0, "target_centroider: %s",
                             step.Dropped(image->header, e.what()).c_str());
    }
  }

  std::vector<std::unique_ptr<Channel>> channels_;
  std::string config_error_;                          // bad parameters: the node only reports this
  std::string target_list_error_;                     // bad target list: measuring without it
  std::unique_ptr<ros_adapters::CameraPoses> poses_;  // null: no tf poses used
  std::vector<ros::Subscriber> tf_subs_;
  std::unique_ptr<image_transport::ImageTransport> it_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  ros::WallTime start_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::TargetCentroiderNodelet, nodelet::Nodelet)
