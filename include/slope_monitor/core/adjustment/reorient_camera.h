// Re-orientation of a fixed camera on stable ground: the
// change of attitude between the reference photo (whose orientation is known:
// resected or target-adjusted) and a new photo, from tie points on stable
// ground (xa in the reference photo, xb in the new one).
//
// The mast sways and settles but the projection centre stays: the position is
// held and only theta, phi, kappa of the new photo are estimated. Each tie
// point's reference ray (xa through the reference pose) is put at a far
// distance (the depth does not matter with the position held) and projected
// into the new photo with the package's collinearity cost. Start: Wahba's
// problem on the rays (SVD); then a robust adjustment (Huber, scale
// huber_px), the points beyond outlier_factor x the robust sigma (1.4826 x
// MAD of the residual norms) removed, and adjusted again without a loss.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace adjustment {

struct StableTiePoint {
  Eigen::Vector2d xa = Eigen::Vector2d::Zero();  // [px] reference photo
  Eigen::Vector2d xb = Eigen::Vector2d::Zero();  // [px] new photo
};

struct ReorientOptions {
  double pixel_sigma = 0.5;     // [px] std of a tie point coordinate (a priori), > 0
  double huber_px = 1.0;        // [px] Huber scale of the robust pass, > 0
  double outlier_factor = 3.0;  // removal beyond this x robust sigma, > 0
  int min_points = 6;           // fewer inliers: no solution, >= 3
  void Check() const;
};

struct ReorientSummary {
  bool success = false;
  std::string message;
  camera::ExteriorOrientation exterior;             // the new photo's pose (reference position)
  Eigen::Vector3d delta = Eigen::Vector3d::Zero();  // [rad] dtheta dphi dkappa (new - reference)
  double rotation_angle = 0.0;                      // [rad] angle of M_new M_ref^T
  Eigen::Matrix3d covariance =
      Eigen::Matrix3d::Zero();  // [rad^2] theta phi kappa, scaled by max(1, sigma0^2)
  Eigen::Vector3d sigma = Eigen::Vector3d::Zero();  // [rad] sqrt of its diagonal
  double rms_px = 0.0;                              // sqrt(sum(du^2 + dv^2) / N) over the inliers
  double sigma0 = 0.0;                              // a posteriori std of unit weight
  int num_points = 0;                               // inliers used
  int num_outliers = 0;
  std::vector<bool> inliers;
};

// Throws InvalidArgument for non-finite tie points or an invalid model.
ReorientSummary ReorientCamera(const camera::CameraModel& model,
                               const camera::ExteriorOrientation& reference,
                               const std::vector<StableTiePoint>& ties,
                               const ReorientOptions& options);

}  // namespace adjustment
}  // namespace slope_monitor
