// Space resection: the exterior orientation of one image from control points.
//
// Closed form from three points (Grunert's solution, as reviewed by Haralick
// et al. 1994): the distances from the projection centre to the three points
// follow from a quartic, so there are up to four candidate poses (doc/design.md:
// "two candidate solutions, a fourth point picks one"; in general up to four).
// A fourth point picks the candidate. Inside RANSAC every sample's candidates
// are scored on all points; the best is refined by least squares
// (collinearity, interior fixed) on its inliers, with a covariance.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace geometry {

// Unit ray of a pixel in the photogrammetric camera frame (x right, y up,
// looking along -z), undistorted.
Eigen::Vector3d BearingOfPixel(const camera::CameraModel& model, const Eigen::Vector2d& pixel);

// All candidate poses from three bearings (photogrammetric camera frame, unit)
// and their three site points; empty when the configuration is degenerate.
std::vector<camera::ExteriorOrientation> ResectThreePoints(const Eigen::Vector3d bearings[3],
                                                           const Eigen::Vector3d points_in_site[3]);

struct ResectionOptions {
  double inlier_threshold_px = 4.0;  // [px] reprojection error of a RANSAC inlier, > 0
  int max_iterations = 300;          // RANSAC samples, > 0
  unsigned int seed = 1;             // deterministic sampling
  bool refine = true;                // least-squares refinement on the inliers
  double pixel_sigma = 1.0;          // [px] observation std (covariance of the result)
  void Check() const;
};

struct ResectionResult {
  bool success = false;
  std::string message;
  camera::ExteriorOrientation exterior;
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  // [m^2, rad^2]
  std::vector<bool> inliers;
  int num_inliers = 0;
  double rms_px = 0.0;                 // [px] over the inliers
  int num_candidates_best_sample = 0;  // candidates of the three-point solution that won
};

// Needs >= 4 control points (three to solve, one or more to choose), not all
// collinear; otherwise success = false with the reason. Non-finite inputs are
// an InvalidArgument.
ResectionResult Resect(const camera::CameraModel& model, const std::vector<Eigen::Vector2d>& pixels,
                       const std::vector<Eigen::Vector3d>& points_in_site,
                       const ResectionOptions& options);

}  // namespace geometry
}  // namespace slope_monitor
