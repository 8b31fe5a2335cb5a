#include "slope_monitor/ros/target_centroider_step.h"

#include <cstdio>
#include <exception>
#include <utility>

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

#include "slope_monitor/core/io/target_file.h"

namespace slope_monitor {
namespace ros_adapters {

TargetCentroiderParameters ReadTargetCentroiderParameters(ParamReader& p) {
  TargetCentroiderParameters t;
  t.options = targets::ReadOptions(p);  // the same reader as the centroid_targets tool's
  t.node = targets::ReadNodeOptions(p);
  p.CheckNoUnknownKeys();
  t.options.Check();
  return t;
}

io::TargetList CentroiderTargets(const targets::NodeOptions& node, const io::SiteFile* site) {
  if (site && site->targets) return *site->targets;
  if (node.target_list.empty()) return io::TargetList();
  return io::LoadTargetFileInSite(node.target_list, site ? &site->crs : nullptr);
}

double CameraPixelSize(const targets::NodeOptions& node, const io::SiteCamera* camera) {
  return camera && camera->pixel_size > 0.0 ? camera->pixel_size : node.pixel_size;
}

CameraPoses::CameraPoses(double cache_seconds) : buffer_(ros::Duration(cache_seconds)) {}

void CameraPoses::Add(const tf2_msgs::TFMessage& tf, bool is_static,
                      std::vector<std::string>* problems) {
  for (const geometry_msgs::TransformStamped& t : tf.transforms) {
    if (is_static) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (!static_frames_.insert(t.child_frame_id).second) continue;  // the first pose stays
    }
    try {
      buffer_.setTransform(t, is_static ? "tf_static" : "tf", is_static);
    } catch (const std::exception& e) {
      problems->push_back("transform to '" + t.child_frame_id + "' ignored: " + e.what());
    }
  }
}

TargetCentroiderStep::TargetCentroiderStep(const std::string& camera, double pixel_size,
                                           const TargetCentroiderParameters& parameters,
                                           const std::optional<io::TargetList>& targets,
                                           const std::string& topic)
    : camera_(camera), topic_(topic), pixel_size_(pixel_size), node_(parameters.node) {
  // Points picked by hand (a gcp list) reach the adjuster from the capture.
  if (targets && !targets->OnlyPicked())
    centroider_ = std::make_unique<targets::TargetCentroider>(parameters.options, *targets);
}

std::optional<Eigen::Isometry3d> TargetCentroiderStep::Pose(
    const tf2::BufferCore& tf, const sensor_msgs::Image& image,
    const sensor_msgs::CameraInfo& info) const {
  if (!node_.use_tf_pose || !centroider_ || !(info.K[0] > 0)) return std::nullopt;
  try {
    return tf2::transformToEigen(
        tf.lookupTransform(node_.site_frame, image.header.frame_id, image.header.stamp));
  } catch (const tf2::TransformException&) {
    return std::nullopt;  // no pose: circles stay unidentified, no perspective correction
  }
}

CentroidedImage TargetCentroiderStep::Centroid(
    const sensor_msgs::Image& image, const sensor_msgs::CameraInfo& info,
    const std::optional<Eigen::Isometry3d>& site_from_optical) const {
  if (centroider_)
    return CentroidImage(*centroider_, image, info, site_from_optical, camera_, pixel_size_,
                         topic_);
  // No targets to look for: the photo's empty target list (the adjuster
  // counts an epoch's photos by them).
  CentroidedImage none;
  none.targets.header = image.header;
  none.targets.camera_name = camera_;
  none.targets.image_width = image.width;
  none.targets.image_height = image.height;
  return none;
}

void TargetCentroiderStep::Count(const CentroidedImage& c) {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.frames;
  if (!centroider_) return;
  counts_.last_detections = static_cast<int>(c.result.observations.size());
  for (const auto& [reason, n] : c.result.summary.rejects_by_reason) counts_.rejects[reason] += n;
}

std::string TargetCentroiderStep::Dropped(const std_msgs::Header& image_header,
                                          const std::string& what) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    ++counts_.errors;
    counts_.last_error = what;
  }
  char stamp[32];
  std::snprintf(stamp, sizeof stamp, "%.3f", image_header.stamp.toSec());
  return "dropped image (topic " + topic_ + ", stamp " + stamp + "): " + what;
}

CentroiderCounts TargetCentroiderStep::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

void TargetCentroiderStep::Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat,
                                    double elapsed, const std::string& list_error) const {
  const CentroiderCounts n = counts();
  stat.add("camera", camera_);
  stat.add("frames", n.frames);
  stat.add("frame rate [Hz]", elapsed > 0 ? n.frames / elapsed : 0.0);
  stat.add("detections (last frame)", n.last_detections);
  stat.add("dropped images", n.errors);
  for (const auto& [reason, count] : n.rejects) stat.add("rejected: " + reason, count);
  if (!list_error.empty()) {
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::ERROR, "%s", list_error.c_str());
  } else if (n.errors > 0) {
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%d images dropped; last: %s", n.errors,
                  n.last_error.c_str());
  } else if (n.frames == 0) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "no images yet");
  } else {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "measuring");
  }
}

}  // namespace ros_adapters
}  // namespace slope_monitor
