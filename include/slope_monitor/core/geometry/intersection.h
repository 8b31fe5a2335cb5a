// Forward intersection: a point in site from its rays in two or more oriented
// images, by linear least squares (closest point to all rays) refined by
// Gauss-Newton on the collinearity equations, with its covariance
// (J^T W J)^-1 from the pixel covariances (orientations taken as exact).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace geometry {

struct RayObservation {
  const camera::CameraModel* model = nullptr;
  camera::ExteriorOrientation exterior;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();                  // [px]
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity() * 0.01;  // [px^2]
};

struct IntersectionOptions {
  double min_angle_deg = 1.0;  // [deg] largest angle between any two rays must exceed this
  int max_iterations = 10;     // Gauss-Newton iterations
  void Check() const;
};

struct IntersectionResult {
  bool success = false;
  std::string message;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    // [m] site
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // [m^2]
  double rms_px = 0.0;                                   // [px]
  double max_angle_deg = 0.0;                            // [deg] widest ray pair
};

IntersectionResult Intersect(const std::vector<RayObservation>& rays,
                             const IntersectionOptions& options = {});

}  // namespace geometry
}  // namespace slope_monitor
