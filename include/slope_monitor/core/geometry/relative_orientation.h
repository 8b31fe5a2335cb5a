// Relative orientation of two images from tie points: the five-point
// essential-matrix solution (OpenCV's cv::findEssentialMat, Nister) inside
// RANSAC, the pose recovered with the cheirality check (cv::recoverPose),
// then the scale and the site datum from control points seen in both images
// (forward intersection in the model frame + Helmert transform to site).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace geometry {

struct RelativeOrientationOptions {
  double inlier_threshold_px = 1.0;  // [px] Sampson distance threshold of RANSAC, > 0
  double confidence = 0.999;         // (0, 1)
  int max_iterations = 2000;
  unsigned int seed = 1;
  void Check() const;
};

struct RelativeOrientationResult {
  bool success = false;
  std::string message;
  // Photogrammetric camera frame of b from that of a: u_b = rotation * u_a + translation,
  // |translation| = 1 (the scale is unknown from tie points alone).
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  std::vector<bool> inliers;
  int num_inliers = 0;
};

RelativeOrientationResult RelativeOrientation(const camera::CameraModel& model_a,
                                              const std::vector<Eigen::Vector2d>& pixels_a,
                                              const camera::CameraModel& model_b,
                                              const std::vector<Eigen::Vector2d>& pixels_b,
                                              const RelativeOrientationOptions& options);

struct PairInSite {
  bool success = false;
  std::string message;
  camera::ExteriorOrientation exterior_a;
  camera::ExteriorOrientation exterior_b;
  Similarity3 site_from_model;
  double control_rms = 0.0;  // [m] Helmert residual over the control points
};

// Scale and datum from >= 3 control points seen in both images.
PairInSite OrientPairInSite(const RelativeOrientationResult& relative,
                            const camera::CameraModel& model_a, const camera::CameraModel& model_b,
                            const std::vector<Eigen::Vector2d>& control_pixels_a,
                            const std::vector<Eigen::Vector2d>& control_pixels_b,
                            const std::vector<Eigen::Vector3d>& control_in_site,
                            const HelmertOptions& helmert);

}  // namespace geometry
}  // namespace slope_monitor
