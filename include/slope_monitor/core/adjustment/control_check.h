// Control point check: which control point disagrees with the others
// (data snooping, Baarda 1968, after a robust similarity fit).
//
// Every control point i has two independent positions: its survey s_i (the
// target list, covariance S_i) and a measurement m_i in another frame (the
// photogrammetric block of a free or GNSS-tied adjustment, covariance M_i).
// Model: s_i = T(m_i) + e_i, T a similarity (or rigid) transform,
//   T(m) = scale * rotation * m + translation.
//
//  1. Start: RANSAC Helmert fit (geometry::FitSimilarityRobust, inlier
//     threshold loss_scale times the median point sigma); least squares when
//     RANSAC finds no consensus.
//  2. Robust fit in Ceres over all points: whitened residuals
//     r_i = L_i (T(m_i) - s_i), L_i^T L_i = (S_i + scale^2 R M_i R^T)^-1,
//     Cauchy loss of scale loss_scale. Parameter blocks: rotation update
//     (angle-axis, rad, applied on the start rotation), translation (m),
//     log(scale) (held when estimate_scale is false).
//  3. Standardized residuals at the robust solution: with the loss weights W
//     (rho' per point), H = J (J^T W J)^-1 J^T W and r = (I - H) l, the
//     residual covariance is C = (I - H)(I - H)^T (whitened observations have
//     unit covariance). Per point T_i = r_i^T C_ii^-1 r_i (chi2 with 3 degrees
//     of freedom for a good point), w_i = sqrt(T_i). A blunder's weight is
//     near 0, so its w_i is its disagreement with the fit of the others; its
//     neighbours keep small residuals.
//  4. The point with the largest w_i above critical_value is the blunder; it
//     is set aside and 2-4 repeat while at least 4 points are left.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace adjustment {

struct ControlCheckOptions {
  bool estimate_scale = true;  // similarity (true) or rigid transform
  double loss_scale = 3.0;     // [sigma] Cauchy loss scale on whitened residuals, > 0
  double critical_value =
      4.03;                 // [-] w above which a point is a blunder: sqrt(chi2(3) at 99.9 %), > 0
  int max_iterations = 50;  // Ceres iterations per robust fit, > 0
  void Check() const;       // throws ConfigError naming the field
};

struct ControlPointPair {
  std::string id;
  Eigen::Vector3d surveyed = Eigen::Vector3d::Zero();                 // [m] target list (site)
  Eigen::Matrix3d surveyed_covariance = Eigen::Matrix3d::Identity();  // [m^2]
  Eigen::Vector3d measured = Eigen::Vector3d::Zero();                 // [m] the other frame
  Eigen::Matrix3d measured_covariance = Eigen::Matrix3d::Identity();  // [m^2]
};

struct ControlPointTest {
  std::string id;
  Eigen::Vector3d residual = Eigen::Vector3d::Zero();  // [m] surveyed - T(measured), final T
  double w = 0.0;  // [-] standardized residual of the last fit that tested the point
  bool blunder = false;
};

struct ControlCheckSummary {
  bool success = false;  // false: too few points, collinear, or the fit failed (message says why)
  std::string message;
  geometry::Similarity3 surveyed_from_measured;  // final fit, blunders left out
  std::vector<ControlPointTest> points;          // input order
  std::vector<std::string> blunders;             // in the order found (largest w first)
  // "control point X disagrees with the others by 52.3 mm (w = 14.2 > 4.03)", one per blunder.
  std::vector<std::string> notes;
};

// Needs >= 4 points (3 for the transform plus redundancy). Throws
// InvalidArgument naming the point for a non-finite position or a covariance
// that is not symmetric positive definite; ConfigError from options.Check().
ControlCheckSummary CheckControlPoints(const std::vector<ControlPointPair>& points,
                                       const ControlCheckOptions& options = {});

}  // namespace adjustment
}  // namespace slope_monitor
