#include <cmath>

#include <Eigen/LU>
#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/snavely_reprojection_error.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

template <int N>
Eigen::Matrix<double, N, N> SqrtInformation(const Eigen::Matrix<double, N, N>& covariance) {
  if (!covariance.allFinite() || !covariance.isApprox(covariance.transpose(), 1e-9)) {
    throw InvalidArgument(Message("covariance is not finite and symmetric: ", covariance.format(Eigen::IOFormat(4))));
  }
  const Eigen::Matrix<double, N, N> information = covariance.inverse();
  Eigen::LLT<Eigen::Matrix<double, N, N>> llt(information);
  if (llt.info() != Eigen::Success || !information.allFinite()) {
    throw InvalidArgument(Message("covariance is not positive definite: ", covariance.format(Eigen::IOFormat(4))));
  }
  // information = L L^T, so S = L^T gives S^T S = information.
  return llt.matrixL().transpose();
}

template Eigen::Matrix<double, 2, 2> SqrtInformation<2>(const Eigen::Matrix<double, 2, 2>&);
template Eigen::Matrix<double, 3, 3> SqrtInformation<3>(const Eigen::Matrix<double, 3, 3>&);

namespace {
Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d s;
  s << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return s;
}
}  // namespace

bool SnavelyReprojectionErrorAnalytic::Evaluate(double const* const* parameters, double* residuals,
                                                double** jacobians) const {
  const double* cam = parameters[0];
  const Eigen::Map<const Eigen::Vector3d> w(cam);
  const Eigen::Map<const Eigen::Vector3d> x(parameters[1]);
  const double theta2 = w.squaredNorm();
  Eigen::Matrix3d r;
  Eigen::Matrix3d jl;  // left Jacobian of SO(3) at w
  const Eigen::Matrix3d wx = Skew(w);
  if (theta2 > 1e-16) {
    const double theta = std::sqrt(theta2);
    const double s = std::sin(theta), c = std::cos(theta);
    r = Eigen::Matrix3d::Identity() + (s / theta) * wx + ((1.0 - c) / theta2) * wx * wx;
    jl = Eigen::Matrix3d::Identity() + ((1.0 - c) / theta2) * wx + ((theta - s) / (theta2 * theta)) * wx * wx;
  } else {
    r = Eigen::Matrix3d::Identity() + wx;
    jl = Eigen::Matrix3d::Identity() + 0.5 * wx;
  }
  const Eigen::Vector3d rx = r * x;
  const Eigen::Vector3d p = rx + Eigen::Vector3d(cam[3], cam[4], cam[5]);
  if (p.z() == 0.0) return false;
  const double inv_z = 1.0 / p.z();
  const double xp = -p.x() * inv_z;
  const double yp = -p.y() * inv_z;
  const double f = cam[6], k1 = cam[7], k2 = cam[8];
  const double r2 = xp * xp + yp * yp;
  const double d = 1.0 + r2 * (k1 + k2 * r2);
  residuals[0] = f * d * xp - observed_x_;
  residuals[1] = f * d * yp - observed_y_;
  if (jacobians == nullptr) return true;

  // d(pred)/d(xp, yp) = f (d I + 2 d'(r2) p p^T), d' = k1 + 2 k2 r2.
  const double dd = k1 + 2.0 * k2 * r2;
  Eigen::Matrix2d dpred_dp;
  dpred_dp << f * (d + 2.0 * dd * xp * xp), f * 2.0 * dd * xp * yp, f * 2.0 * dd * xp * yp,
      f * (d + 2.0 * dd * yp * yp);
  // d(xp, yp)/dP.
  Eigen::Matrix<double, 2, 3> dp_dP;
  dp_dP << -inv_z, 0.0, p.x() * inv_z * inv_z, 0.0, -inv_z, p.y() * inv_z * inv_z;
  const Eigen::Matrix<double, 2, 3> dpred_dP = dpred_dp * dp_dP;

  if (jacobians[0] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 9, Eigen::RowMajor>> j(jacobians[0]);
    j.block<2, 3>(0, 0) = -dpred_dP * Skew(rx) * jl;
    j.block<2, 3>(0, 3) = dpred_dP;
    j(0, 6) = d * xp;
    j(1, 6) = d * yp;
    j(0, 7) = f * r2 * xp;
    j(1, 7) = f * r2 * yp;
    j(0, 8) = f * r2 * r2 * xp;
    j(1, 8) = f * r2 * r2 * yp;
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> jp(jacobians[1]);
    jp = dpred_dP * r;
  }
  return true;
}

}  // namespace adjustment
}  // namespace slope_monitor
