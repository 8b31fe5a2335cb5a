// The fixed_targetless cameras of a site in the graph:
// one runner per camera turns its photos (sensor_msgs::Image + CameraInfo)
// into the outputs of dense::TargetlessCamera, the core chain track_camera
// runs. Used by the targetless_camera nodelet and by process_bag, so both
// give the same numbers.
//
// Per camera (io::SiteCamera of kind fixed_targetless): the reference pose
// from `pose_file` (resect_camera's PREFIX.pose.yaml), the DEM from `dem`,
// the stable area from `stable_polygons` (pixels of the reference photo) or
// else the site's areas.stable / areas.outline (ground polygons met by the
// reference rays). The reference photo is the camera's first photo, or the
// one whose file name (reference_images: ["<camera>=<path>"]) is given.
// Outputs per later photo:
//  * PointDisplacementArray (source FEATURE, point_id "<camera>/p<probe>",
//    source_name "targetless_camera/<camera>"): the usable probes of the
//    monitored area (flagged and stable check probes are not published);
//  * the re-oriented pose site -> <camera>_optical (tf);
//  * a DiagnosticStatus "targetless_camera: <camera>": rotation, the three
//    angles' changes and sigmas, RMS px, the field's counts and flags; WARN
//    naming the camera and the angle above max_rotation_deg;
//  * with report_dir, the field drawn over the photo (dense/field_picture.h):
//    <report_dir>/<camera>_field_eNN.png, NN the photo's epoch (1, 2, ...).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <geometry_msgs/TransformStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/core/dense/targetless_camera.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/parameters.h"

namespace slope_monitor {
namespace ros_adapters {

// config/defaults/targetless_camera.yaml.
struct TargetlessParameters {
  std::string site_file;                          // required
  io::SiteFile site;                              // read from site_file
  std::vector<std::string> reference_images;      // "<camera>=<photo file>" as written
  std::map<std::string, std::string> references;  // camera -> reference photo file
  std::string frame_id = "site";
  std::string report_dir;  // where <camera>_field_eNN.png go; "" = not written
  dense::TargetlessCameraOptions options;
};
// Throws ConfigError naming the key (no site file, no fixed_targetless camera, ...).
TargetlessParameters ReadTargetlessParameters(ParamReader& p);

struct TargetlessOutputs {
  std::optional<slope_monitor::PointDisplacementArray> displacements;
  std::optional<geometry_msgs::TransformStamped> site_from_optical;
  diagnostic_msgs::DiagnosticStatus status;
  std::vector<std::string> warnings;  // each names the camera (WARN)
  std::string picture;                // the field picture written, or ""
  std::string info;                   // one line for the log (INFO)
};

class TargetlessCameraRunner {
 public:
  // Reads the camera's pose file, DEM and stable polygons now (errors name
  // the site file key and the file).
  TargetlessCameraRunner(const TargetlessParameters& params, const io::SiteCamera& camera);

  // A photo and its camera_info. The first one (or the configured
  // reference) becomes the reference: its outputs carry only the pose and
  // the status. Throws slope_monitor::Error (bad image, DEM not covering the
  // view) or cv_bridge::Exception.
  TargetlessOutputs OnImage(const sensor_msgs::Image& image, const sensor_msgs::CameraInfo& info);

  const std::string& camera() const { return camera_.name; }

 private:
  TargetlessOutputs Reference(const sensor_msgs::Image& image, const sensor_msgs::CameraInfo& info);

  const TargetlessParameters& params_;
  io::SiteCamera camera_;
  camera::ExteriorOrientation reference_pose_;
  io::GeoRaster dem_;
  std::vector<std::vector<Eigen::Vector2d>> stable_polygons_;  // pixels; empty: site areas
  std::unique_ptr<dense::TargetlessCamera> tracker_;
  ros::Time reference_stamp_;
  unsigned int epoch_ = 0;
};

// Every fixed_targetless camera of the site, each photo paired with its
// camera_info by stamp (in either order), as the nodelet and process_bag
// receive them.
class TargetlessCameras {
 public:
  explicit TargetlessCameras(const TargetlessParameters& params);
  TargetlessCameras(const TargetlessCameras&) = delete;
  TargetlessCameras& operator=(const TargetlessCameras&) = delete;

  std::vector<std::string> cameras() const;
  bool Handles(const std::string& camera) const { return runners_.count(camera) > 0; }
  // The outputs of the photo this message completes, if it completes one.
  // Errors as TargetlessCameraRunner::OnImage; the pair is dropped then.
  std::optional<TargetlessOutputs> AddImage(const std::string& camera,
                                            const sensor_msgs::Image::ConstPtr& image);
  std::optional<TargetlessOutputs> AddCameraInfo(const std::string& camera,
                                                 const sensor_msgs::CameraInfo::ConstPtr& info);

 private:
  struct Pending {
    std::map<ros::Time, sensor_msgs::Image::ConstPtr> images;
    std::map<ros::Time, sensor_msgs::CameraInfo::ConstPtr> infos;
  };
  std::optional<TargetlessOutputs> Pair(const std::string& camera, const ros::Time& stamp);

  TargetlessParameters params_;  // the runners keep a reference: never moved
  std::map<std::string, std::unique_ptr<TargetlessCameraRunner>> runners_;
  std::map<std::string, Pending> pending_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
