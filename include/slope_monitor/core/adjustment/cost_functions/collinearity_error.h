// Collinearity reprojection error of one target / tie point observation.
//
// Model (doc/design.md, camera_model.h):
//   u = M(theta, phi, kappa) (X - X0)                     photogrammetric camera frame
//   x = x0 + dx - c u_x / u_z,  y = y0 + dy - c u_y / u_z  [mm] (distortion dx, dy as in Distort())
//   (col, row) = MmToPixel(sensor, x, y)                   [px], OpenCV convention
//   residual = L^T ((col, row)_predicted - (col, row)_observed)   [-] (whitened)
// where L L^T = inverse of the observation covariance [px^2] (sqrt_information =
// L^T), so a residual of 1 is one standard deviation. Sign: predicted minus
// observed.
//
// Parameter blocks:
//   0  exterior[6]  X0 Y0 Z0 [m] projection centre in site; theta phi kappa [rad]
//   1  interior[10] c [mm], x0 y0 [mm] (principal point from the image centre, x right,
//                   y up), k1 [mm^-2], k2 [mm^-4], k3 [mm^-6], p1 p2 [mm^-1], b1 b2 [-]
//   2  point[3]     X Y Z [m] object point in site
// Any block may be held constant (or partly, SubsetManifold) by the caller.
// Two implementations of the same residual: CollinearityError (templated,
// automatic differentiation: the reference) and CollinearityErrorAnalytic
// (hand-derived Jacobians, what the adjuster uses; at 150 photos automatic
// differentiation was 64 % of the solve). Tests compare the two.
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/cost_function.h>
#include <ceres/sized_cost_function.h>
#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace adjustment {

class CollinearityError {
 public:
  CollinearityError(const camera::Sensor& sensor, const Eigen::Vector2d& observed_px,
                    const Eigen::Matrix2d& sqrt_information)
      : sensor_(sensor), observed_(observed_px), sqrt_information_(sqrt_information) {}

  template <typename T>
  bool operator()(const T* exterior, const T* interior, const T* point, T* residuals) const {
    T xy_mm[2] = {T(0), T(0)};
    const Eigen::Matrix<T, 3, 1> u = camera::PointInCamera(exterior, point);
    if (u(2) == T(0)) return false;
    camera::ProjectToImageMm(exterior, interior, point, xy_mm);
    T col, row;
    camera::MmToPixel(sensor_, xy_mm[0], xy_mm[1], &col, &row);
    const T e0 = col - T(observed_.x());
    const T e1 = row - T(observed_.y());
    residuals[0] = T(sqrt_information_(0, 0)) * e0 + T(sqrt_information_(0, 1)) * e1;
    residuals[1] = T(sqrt_information_(1, 0)) * e0 + T(sqrt_information_(1, 1)) * e1;
    return true;
  }

  // sqrt_information: upper-triangular L^T with L L^T = covariance^-1 (see
  // SqrtInformation()).
  static ceres::CostFunction* Create(const camera::Sensor& sensor,
                                     const Eigen::Vector2d& observed_px,
                                     const Eigen::Matrix2d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<CollinearityError, 2, camera::kNumExterior,
                                           camera::kNumInterior, 3>(
        new CollinearityError(sensor, observed_px, sqrt_information));
  }

 private:
  camera::Sensor sensor_;
  Eigen::Vector2d observed_;
  Eigen::Matrix2d sqrt_information_;
};

// The same residual as CollinearityError with analytic Jacobians:
//   d u / d X = M,  d u / d X0 = -M,  d u / d(theta, phi, kappa) from
//   M = MKappa MPhi MTheta (rotation.h) differentiated factor by factor (no
//   division by cos(phi): exact at phi = +-90 deg),
//   then x_u = -c u_x / u_z, the distortion polynomial and the pixel scale.
class CollinearityErrorAnalytic
    : public ceres::SizedCostFunction<2, camera::kNumExterior, camera::kNumInterior, 3> {
 public:
  CollinearityErrorAnalytic(const camera::Sensor& sensor, const Eigen::Vector2d& observed_px,
                            const Eigen::Matrix2d& sqrt_information)
      : sensor_(sensor), observed_(observed_px), sqrt_information_(sqrt_information) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

 private:
  camera::Sensor sensor_;
  Eigen::Vector2d observed_;
  Eigen::Matrix2d sqrt_information_;
};

// Square root of the information matrix of a covariance: S with
// S^T S = covariance^-1 (Cholesky of the inverse). Throws InvalidArgument when
// the covariance is not symmetric positive definite.
template <int N>
Eigen::Matrix<double, N, N> SqrtInformation(const Eigen::Matrix<double, N, N>& covariance);

}  // namespace adjustment
}  // namespace slope_monitor
