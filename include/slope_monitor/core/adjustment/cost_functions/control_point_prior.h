// Prior on a control point from its survey.
//
// Model: residual = S (X - X_surveyed), S^T S = C_survey^-1 (C_survey the 3x3
// survey covariance [m^2], e.g. diag(sh^2, sh^2, sv^2) from the target list's
// horizontal and vertical sigma). Sign: estimate minus survey. [-] (whitened)
//
// Parameter blocks:
//   0  point[3]  X Y Z [m] object point in site
#pragma once

#include <ceres/sized_cost_function.h>
#include <Eigen/Core>

namespace slope_monitor {
namespace adjustment {

// Linear, so the Jacobian is analytic (it is the constant S).
class ControlPointPrior : public ceres::SizedCostFunction<3, 3> {
 public:
  ControlPointPrior(const Eigen::Vector3d& surveyed, const Eigen::Matrix3d& sqrt_information)
      : surveyed_(surveyed), sqrt_information_(sqrt_information) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Eigen::Vector3d> x(parameters[0]);
    Eigen::Map<Eigen::Vector3d> r(residuals);
    r = sqrt_information_ * (x - surveyed_);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> j(jacobians[0]);
      j = sqrt_information_;
    }
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& surveyed,
                                     const Eigen::Matrix3d& sqrt_information) {
    return new ControlPointPrior(surveyed, sqrt_information);
  }

 private:
  Eigen::Vector3d surveyed_;
  Eigen::Matrix3d sqrt_information_;
};

}  // namespace adjustment
}  // namespace slope_monitor
