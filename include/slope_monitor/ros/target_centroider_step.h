// The target centroider node's work, from ROS messages: the
// node's parameters and targets, the camera poses from /tf and /tf_static,
// and per camera one photo (Image + CameraInfo of one stamp) into the
// TargetObservationArray to publish (ros/target_conversions.h), with the
// counts its diagnostics report. The target_centroider nodelet (in its
// callbacks) and process_bag (in bag-time order, the centroiding itself on
// another thread) use these same pieces, so both give the same targets.
//
//   TargetCentroiderParameters p = ReadTargetCentroiderParameters(reader);
//   TargetCentroiderStep step("fixed_cam_1", CameraPixelSize(p.node, site_camera), p,
//                             CentroiderTargets(p.node, site));
//   const CentroidedImage c = step.Centroid(image, info, step.Pose(poses, image, info));
//   publish(c.targets); step.Count(c);
#pragma once

#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2/buffer_core.h>
#include <tf2_msgs/TFMessage.h>
#include <Eigen/Geometry>

#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/core/targets/options_reader.h"
#include "slope_monitor/core/targets/target_centroider.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/target_conversions.h"

namespace slope_monitor {
namespace ros_adapters {

// config/defaults/target_centroider.yaml: the centroider's options and the
// node's own keys.
struct TargetCentroiderParameters {
  targets::Options options;
  targets::NodeOptions node;
};
// Reads both, refuses unknown keys and checks the options (ConfigError or
// InvalidArgument naming the key).
TargetCentroiderParameters ReadTargetCentroiderParameters(ParamReader& p);

// The targets to look for: the site file's when it lists them, else the
// node's target_list (YAML or a surveyors' CSV, placed by the site's CRS);
// an empty list when there is neither. Throws Error naming the file.
io::TargetList CentroiderTargets(const targets::NodeOptions& node, const io::SiteFile* site);

// A camera's pixel size [mm/px]: the site file's for the camera when it
// gives one, else the node's pixel_size.
double CameraPixelSize(const targets::NodeOptions& node, const io::SiteCamera* camera);

// The poses the centroider looks up: /tf and /tf_static as they come. A
// frame's static pose is the first one received (the installation's): the
// bundle adjuster republishes each fixed camera's adjusted pose on
// /tf_static after every epoch, and whether that comes before or after the
// next epoch's photo depends on the replay rate and the CPU; the centroids
// (circle IDs, perspective correction) must not. Thread-safe.
class CameraPoses {
 public:
  // `cache_seconds`: how long /tf is kept (a bag read offline: its length).
  explicit CameraPoses(double cache_seconds);
  // A transform tf2 refuses is skipped: one line each in `*problems`.
  void Add(const tf2_msgs::TFMessage& tf, bool is_static, std::vector<std::string>* problems);
  const tf2::BufferCore& buffer() const { return buffer_; }

 private:
  tf2::BufferCore buffer_;
  std::mutex mutex_;
  std::set<std::string> static_frames_;  // child frames whose static pose is set
};

// The counts of one camera's photos, for its diagnostics.
struct CentroiderCounts {
  int frames = 0, errors = 0, last_detections = 0;
  std::map<std::string, int> rejects;  // by reason, over all photos
  std::string last_error;
};

// One camera's centroider. Centroid() and Pose() are const and may run on
// another thread than the counting (Count, Dropped, Diagnose, which lock).
class TargetCentroiderStep {
 public:
  // `targets`: none for a run without a target stage (a site without
  // targets, io::SiteWithoutTargets): each photo gets its empty target list.
  // `topic`: the image topic, named in error messages. Throws Error (the
  // centroider's options or families).
  TargetCentroiderStep(const std::string& camera, double pixel_size,
                       const TargetCentroiderParameters& parameters,
                       const std::optional<io::TargetList>& targets, const std::string& topic);

  const std::string& camera() const { return camera_; }
  const std::string& topic() const { return topic_; }
  bool has_targets() const { return centroider_ != nullptr; }

  // The camera's pose in site_frame at the photo's stamp (its header's
  // frame); none without use_tf_pose or targets, for an uncalibrated
  // camera_info (K[0] == 0) or when `tf` has no such transform (then the
  // circles stay unidentified, with no perspective correction).
  std::optional<Eigen::Isometry3d> Pose(const tf2::BufferCore& tf, const sensor_msgs::Image& image,
                                        const sensor_msgs::CameraInfo& info) const;

  // The photo's targets (without targets: the empty list with the photo's
  // header, camera and size). Throws slope_monitor::Error (bad input),
  // cv_bridge::Exception or cv::Exception.
  CentroidedImage Centroid(const sensor_msgs::Image& image, const sensor_msgs::CameraInfo& info,
                           const std::optional<Eigen::Isometry3d>& site_from_optical) const;

  // A photo centroided (published).
  void Count(const CentroidedImage& c);
  // A photo dropped (Centroid threw `what`): counted; the line to log,
  // "dropped image (topic T, stamp S): what".
  std::string Dropped(const std_msgs::Header& image_header, const std::string& what);
  CentroiderCounts counts() const;

  // The camera's diagnostics: counts, frame rate over `elapsed` [s], rejects
  // by reason; ERROR with `list_error` (a target list not used), WARN for
  // dropped photos or none yet, else OK.
  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat, double elapsed,
                const std::string& list_error) const;

 private:
  std::string camera_, topic_;
  double pixel_size_;
  targets::NodeOptions node_;
  std::unique_ptr<targets::TargetCentroider> centroider_;  // null: no target stage
  mutable std::mutex mutex_;                               // guards counts_
  CentroiderCounts counts_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
