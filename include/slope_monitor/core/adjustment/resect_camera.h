// Resection of one camera from surveyed points picked in its photo, starting
// from a nominal camera (focal length and sensor size, or EXIF) and no guess of
// the attitude.
//
//   1. Start: with a known position, the attitude is the rotation that best
//      maps the site directions (X - X0) onto the pixels' bearings (Wahba's
//      problem, SVD); without one, the three-point resection with the other
//      points choosing among its candidates (geometry::Resect, doc/design.md).
//   2. Adjustment (Ceres, adjustment::CollinearityError): exterior free (the
//      position held, or tied to its prior, when given), the interior
//      parameters named in `free_interior` free, the others held; points held,
//      or tied to their survey when point_sigma > 0.
//   3. Covariance of the free parameters (a priori: pixel_sigma), the
//      correlations above `correlation_warning`, and per point the residual
//      and Baarda's data-snooping test on the standardized residual
//      w = v / (sigma sqrt(q_vv)) (|w| > snooping_critical fails).
// Coordinates are shifted internally to the points' centroid; the results are
// in the input frame.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/io/surveyed_points.h"

namespace slope_monitor {
namespace adjustment {

struct ResectCameraOptions {
  std::vector<std::string> free_interior = {"c"};  // names of camera::InteriorNames()
  double pixel_sigma = 1.0;   // [px] std of a picked pixel (each coordinate), > 0
  double point_sigma = 0.0;   // [m] std of a surveyed coordinate; 0 holds the points
  bool has_position = false;  // a known projection centre:
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // [m] in the points' frame
  double position_sigma = 0.0;                         // [m] its std; 0 holds it
  double snooping_critical = 3.29;   // Baarda's critical value of |w| (alpha 0.001, two-sided)
  double correlation_warning = 0.9;  // |rho| above this is reported
  double start_inlier_fraction =
      0.05;  // start: a point agrees within this fraction of the image diagonal
  void Check() const;
};

struct ResectedPoint {
  std::string id;
  Eigen::Vector2d observed = Eigen::Vector2d::Zero();  // [px]
  Eigen::Vector2d residual = Eigen::Vector2d::Zero();  // [px] projected minus observed
  double w = 0.0;                // largest |standardized residual| of the two coordinates
  bool snooping_failed = false;  // |w| > snooping_critical
};

struct EstimatedParameter {
  std::string name;    // "X0", "Y0", "Z0", "theta", "phi", "kappa", or an interior name
  double value = 0.0;  // [m], [rad], or the interior unit (camera_model.h)
  double sigma = 0.0;
};

struct ResectCameraSummary {
  bool success = false;
  std::string message;
  camera::CameraModel model;             // adjusted interior
  camera::ExteriorOrientation exterior;  // in the input frame
  Eigen::Matrix<double, 6, 6> exterior_covariance =
      Eigen::Matrix<double, 6, 6>::Zero();        // [m^2, rad^2]
  std::vector<EstimatedParameter> parameters;     // the free ones, in block order
  Eigen::MatrixXd correlation;                    // of `parameters`
  std::vector<std::string> correlation_warnings;  // "c-k1 0.953"
  std::vector<ResectedPoint> points;
  double rms_px = 0.0;  // sqrt(sum(du^2 + dv^2) / N)
  double sigma0 = 0.0;  // a posteriori std of unit weight (0 without redundancy)
  int redundancy = 0;
  int num_snooping_failed = 0;
  std::string start;  // how the start was found
};

// Throws InvalidArgument for fewer than 4 points, a name in free_interior that
// is not an interior parameter, or points behind the camera after the
// adjustment (naming them); success = false with the reason when no start is
// found or the adjustment fails.
ResectCameraSummary ResectCamera(const std::vector<io::PickedPoint>& points,
                                 const camera::CameraModel& nominal,
                                 const ResectCameraOptions& options);

// The rotation that maps site directions onto camera bearings (both unit,
// photogrammetric camera frame), least squares (Wahba's problem by SVD).
Eigen::Matrix3d RotationFromDirections(const std::vector<Eigen::Vector3d>& site_directions,
                                       const std::vector<Eigen::Vector3d>& bearings);

}  // namespace adjustment
}  // namespace slope_monitor
