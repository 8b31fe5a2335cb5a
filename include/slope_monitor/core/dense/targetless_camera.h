// A fixed camera without targets, photo by photo: the
// one chain the track_camera tool, the targetless_camera nodelet and
// process_bag run for a camera of kind `fixed_targetless`.
//
//   TargetlessCamera cam("north_cam", model, reference_pose, &dem, areas, options);
//   cam.SetReference(first_photo, t0);
//   TargetlessEpoch e = cam.Process(photo, t);   // e.reorientation, e.field, e.warnings
//
// Per photo: the hex matcher on the stable area (global shift on, only
// interest points inside the stable area matched, the rest "moving"), its
// normal-quality matches -> adjustment::ReorientCamera (the attitude change
// from the reference photo, position held) -> with a DEM,
// dense::ComputeDisplacementField (probe grid over the monitored area,
// projected onto the DEM). A rotation above max_rotation_deg, or one of the
// three angles' change above it, is a warning naming the camera and the angle.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/adjustment/reorient_camera.h"
#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/dense/displacement_field.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/matching/hex_matcher.h"

namespace slope_monitor {
namespace dense {

using ImagePredicate = std::function<bool(const Eigen::Vector2d&)>;

struct TargetlessCameraOptions {
  // The hex matcher of the stable tie points: its defaults, except 40000
  // interest points detected on the whole photo (only the stable ones are
  // matched) and LSC on images low-passed by 1 px (JPEG noise, changing
  // light on rock). See TrackingMatcherOptions().
  matching::HexMatcherOptions matcher = TrackingMatcherOptions();
  // [px] search radius of the stable tie points, > 0: first around no shift (it must
  // cover the mast's turn: 24 px = 0.27 deg at c = 5000 px), then around their median shift.
  double match_radius = 24.0;
  double max_rotation_deg = 0.5;  // [deg] WARN above (total angle or one angle's change), > 0
  adjustment::ReorientOptions reorient;
  DisplacementFieldOptions field;
  void Check() const;  // throws InvalidArgument naming the field
  static matching::HexMatcherOptions TrackingMatcherOptions();
};

// Where the stable ground and the monitored area are in the reference photo.
struct ImageAreas {
  // Optional: without it the whole photo is taken as stable for the
  // re-orientation and the field has no stable check probes.
  ImagePredicate stable;
  ImagePredicate monitored;  // optional; default: not stable (everywhere without `stable`)
};

// The areas from polygons of the site file ([m] site x, y): a pixel is
// stable when its reference ray meets the DEM inside a stable polygon;
// monitored when it meets it inside the outline (every pixel on the DEM
// when the outline is empty) and is not stable. Without stable polygons,
// stable = on the DEM and outside the outline (the image minus the monitored
// area). Throws InvalidArgument when neither is given. The predicates keep a
// pointer to `dem`: it must outlive them.
ImageAreas AreasFromSitePolygons(const camera::CameraModel& model,
                                 const camera::ExteriorOrientation& reference,
                                 const io::GeoRaster& dem,
                                 const std::vector<Eigen::Vector2d>& outline,
                                 const std::vector<std::vector<Eigen::Vector2d>>& stable,
                                 double max_range);

struct TargetlessEpoch {
  matching::HexMatchSummary matches;  // of the stable tie points
  int ties = 0;                       // normal-quality stable ties given to the re-orientation
  adjustment::ReorientSummary reorientation;
  bool has_field = false;  // a DEM was given and the re-orientation succeeded
  DisplacementField field;
  double dt = 0.0;                    // [s] photo time - reference time
  std::vector<std::string> warnings;  // each names the camera (and the angle)
};

class TargetlessCamera {
 public:
  // `dem` may be null (re-orientation only); it must outlive the object.
  TargetlessCamera(std::string name, const camera::CameraModel& model,
                   const camera::ExteriorOrientation& reference, const io::GeoRaster* dem,
                   ImageAreas areas, const TargetlessCameraOptions& options);

  // The reference photo (8-bit single channel, the camera's size) and its
  // time [s]. Throws InvalidArgument naming the camera when the size differs.
  void SetReference(const cv::Mat& image, double time);
  bool has_reference() const { return !reference_image_.empty(); }
  double reference_time() const { return reference_time_; }
  const std::string& name() const { return name_; }
  const camera::CameraModel& model() const { return model_; }
  const camera::ExteriorOrientation& reference_pose() const { return reference_; }

  // One later photo. `dem_name` names the DEM in messages. Throws
  // InvalidArgument for an image of the wrong size or a DEM that does not
  // cover the view.
  TargetlessEpoch Process(const cv::Mat& image, double time,
                          const std::string& dem_name = "DEM") const;

 private:
  std::string name_;
  camera::CameraModel model_;
  camera::ExteriorOrientation reference_;
  const io::GeoRaster* dem_;
  ImageAreas areas_;
  TargetlessCameraOptions options_;
  matching::HexMatcher matcher_;
  cv::Mat reference_image_;
  double reference_time_ = 0.0;
};

}  // namespace dense
}  // namespace slope_monitor
