// 3-D similarity (Helmert) transform between point sets, least squares
// (Umeyama 1991) and robust (RANSAC over three-point samples, then a least
// squares fit on the inliers).
//
//   x_in_target = scale * rotation * x_in_source + translation
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace geometry {

struct Similarity3 {
  double scale = 1.0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Eigen::Vector3d operator*(const Eigen::Vector3d& x) const {
    return scale * (rotation * x) + translation;
  }
  Similarity3 Inverse() const;
  // Covariance of a transformed point from the covariance in the source frame.
  Eigen::Matrix3d TransformCovariance(const Eigen::Matrix3d& c) const {
    return scale * scale * rotation * c * rotation.transpose();
  }
};

struct HelmertOptions {
  bool estimate_scale = true;      // false: rigid (scale 1)
  double inlier_threshold = 0.05;  // [m] residual distance for a RANSAC inlier, > 0
  int max_iterations = 500;        // RANSAC samples, > 0
  unsigned int seed = 1;           // RANSAC random seed (deterministic)
  void Check() const;              // throws ConfigError naming the field
};

struct HelmertResult {
  bool success = false;
  std::string message;
  Similarity3 target_from_source;
  std::vector<bool> inliers;  // per point pair
  int num_inliers = 0;
  std::vector<double> residuals;  // [m] |T(source) - target| per pair
  double rms = 0.0;               // [m] over the inliers
};

// Least-squares similarity (weights >= 0; empty: all 1). Needs >= 3 non-collinear
// pairs; throws InvalidArgument otherwise (naming the count or "collinear").
Similarity3 FitSimilarity(const std::vector<Eigen::Vector3d>& source,
                          const std::vector<Eigen::Vector3d>& target, bool estimate_scale,
                          const std::vector<double>& weights = {});

// Robust fit. Fails (success = false, message says why) on fewer than 3
// pairs, collinear points, or fewer than 3 inliers.
HelmertResult FitSimilarityRobust(const std::vector<Eigen::Vector3d>& source,
                                  const std::vector<Eigen::Vector3d>& target,
                                  const HelmertOptions& options);

// A camera's exterior orientation carried along by `t` (a block moved into
// the site, or onto its control points): its centre moved by t, its attitude
// turned by t's rotation (the scale changes no direction).
camera::ExteriorOrientation TransformExterior(const Similarity3& t,
                                              const camera::ExteriorOrientation& e);

// True when the points lie (within relative tolerance) on one line.
bool AreCollinear(const std::vector<Eigen::Vector3d>& points, double relative_tolerance = 1e-3);

}  // namespace geometry
}  // namespace slope_monitor
