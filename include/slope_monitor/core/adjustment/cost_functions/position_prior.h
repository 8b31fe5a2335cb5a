// GNSS prior on a camera's projection centre (UAV photos).
//
// Model: residual = S (X0 - X_gnss), S^T S = C_gnss^-1 (C_gnss the 3x3 position
// covariance [m^2] in site). Sign: estimate minus measurement. [-] (whitened)
// The lever arm antenna -> projection centre is assumed already applied.
//
// Parameter blocks:
//   0  exterior[6]  X0 Y0 Z0 [m], theta phi kappa [rad]; only X0 Y0 Z0 enter.
#pragma once

#include <ceres/sized_cost_function.h>
#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace adjustment {

class PositionPriorError : public ceres::SizedCostFunction<3, camera::kNumExterior> {
 public:
  PositionPriorError(const Eigen::Vector3d& measured, const Eigen::Matrix3d& sqrt_information)
      : measured_(measured), sqrt_information_(sqrt_information) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector3d> x0(parameters[0]);
    Eigen::Map<Eigen::Vector3d> r(residuals);
    r = sqrt_information_ * (x0 - measured_);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 3, camera::kNumExterior, Eigen::RowMajor>> j(jacobians[0]);
      j.setZero();
      j.leftCols<3>() = sqrt_information_;
    }
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& measured,
                                     const Eigen::Matrix3d& sqrt_information) {
    return new PositionPriorError(measured, sqrt_information);
  }

 private:
  Eigen::Vector3d measured_;
  Eigen::Matrix3d sqrt_information_;
};

}  // namespace adjustment
}  // namespace slope_monitor
