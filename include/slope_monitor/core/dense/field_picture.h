// The displacement field of a fixed camera drawn over its photo: the picture the targetless_camera
// node and process_bag write into the report folder (<camera>_field_eNN.png) and track_camera into
// its --out folder, all through this one function.
//
// Each probe that LSC matched is an arrow on the new photo: from where its
// reference ground point x_ref appears in the new photo (projected with the
// re-oriented pose, i.e. with the mast's turn removed) along its image
// displacement xb - that position, multiplied by a common exaggeration so
// that the longest arrow of the usable monitored probes is
// longest_arrow_px long (times the photo's width in thousands of pixels). Colours (BGR):
//   green   usable probe of the monitored area (published)
//   cyan    usable check probe on stable ground (should be ~0)
//   orange  flagged "grazing"
//   magenta flagged "line_of_sight"
//   yellow  any other flag with a match ("inconsistent", "no_surface")
//   red dot no match ("off_image", "lsc_<status>")
// A legend at the top left holds the scale bar: a bar of the exaggeration
// times a round number of pixels of image motion, labelled in pixels and in
// metres: that motion across the line of sight at the median range of the
// usable probes (range x pixel size / principal distance; along a slope seen
// obliquely a pixel covers more ground).
#pragma once

#include <string>

#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/dense/displacement_field.h"

namespace slope_monitor {
namespace dense {

struct FieldPictureOptions {
  // [px] drawn length of the longest usable arrow, > 0, per 1000 px of the
  // photo's width (x1 below 2000 px, x2 below 3000, ...; lines and text alike).
  double longest_arrow_px = 80.0;
  void Check() const;  // throws InvalidArgument naming the field
};

struct FieldPictureSummary {
  double exaggeration = 1.0;   // drawn px per px of image motion
  double bar_motion_px = 0.0;  // [px] image motion the scale bar stands for
  double bar_metres = 0.0;     // [m] that motion on the ground (0: not known)
  double metres_per_px = 0.0;  // [m/px] across the view at the median range (0: no probe)
  int arrows = 0;              // probes drawn as arrows (matched)
  int dots = 0;                // probes without a match (red dots)
};

// Where probe p's reference ground point appears in the photo taken with
// `current` (the tail of its arrow), or false.
bool ArrowTail(const camera::CameraModel& model, const camera::ExteriorOrientation& current,
               const FieldPoint& p, Eigen::Vector2d* tail);

// The photo (8-bit, 1 or 3 channels, the camera's size) as BGR with the
// field's arrows, legend and scale bar; the same size as the photo. Throws
// InvalidArgument for a photo of another size or type.
cv::Mat DrawDisplacementField(const cv::Mat& photo, const DisplacementField& field,
                              const camera::CameraModel& model,
                              const camera::ExteriorOrientation& current,
                              const FieldPictureOptions& options,
                              FieldPictureSummary* summary = nullptr);

// DrawDisplacementField written as a PNG; throws IoError naming the path.
FieldPictureSummary WriteDisplacementFieldPng(const std::string& path, const cv::Mat& photo,
                                              const DisplacementField& field,
                                              const camera::CameraModel& model,
                                              const camera::ExteriorOrientation& current,
                                              const FieldPictureOptions& options);

// "<camera>_field_eNN.png" (epoch two digits at least, as surface_eNN.tif).
std::string FieldPictureFileName(const std::string& camera, int epoch);

}  // namespace dense
}  // namespace slope_monitor
