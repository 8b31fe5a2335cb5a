#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/snavely_reprojection_error.h"
#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

template <int N>
Eigen::Matrix<double, N, N> SqrtInformation(const Eigen::Matrix<double, N, N>& covariance) {
  if (!covariance.allFinite() || !covariance.isApprox(covariance.transpose(), 1e-9)) {
    throw InvalidArgument(
        Message("covariance is not finite and symmetric: ", covariance.format(Eigen::IOFormat(4))));
  }
  const Eigen::Matrix<double, N, N> information = covariance.inverse();
  Eigen::LLT<Eigen::Matrix<double, N, N>> llt(information);
  if (llt.info() != Eigen::Success || !information.allFinite()) {
    throw InvalidArgument(
        Message("covariance is not positive definite: ", covariance.format(Eigen::IOFormat(4))));
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
    jl = Eigen::Matrix3d::Identity() + ((1.0 - c) / theta2) * wx +
         ((theta - s) / (theta2 * theta)) * wx * wx;
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

namespace {
// d M(angle) / d angle for the three elementary rotations of rotation.h.
Eigen::Matrix3d DMTheta(double t) {
  Eigen::Matrix3d m;
  m << -std::sin(t), 0, -std::cos(t), 0, 0, 0, std::cos(t), 0, -std::sin(t);
  return m;
}
Eigen::Matrix3d DMPhi(double p) {
  Eigen::Matrix3d m;
  m << 0, 0, 0, 0, -std::sin(p), -std::cos(p), 0, std::cos(p), -std::sin(p);
  return m;
}
Eigen::Matrix3d DMKappa(double k) {
  Eigen::Matrix3d m;
  m << -std::sin(k), std::cos(k), 0, -std::cos(k), -std::sin(k), 0, 0, 0, 0;
  return m;
}
}  // namespace

bool CollinearityErrorAnalytic::Evaluate(double const* const* parameters, double* residuals,
                                         double** jacobians) const {
  const double* ext = parameters[0];
  const double* in = parameters[1];
  const Eigen::Vector3d d(parameters[2][0] - ext[0], parameters[2][1] - ext[1],
                          parameters[2][2] - ext[2]);
  const Eigen::Matrix3d mt = camera::MTheta(ext[3]), mp = camera::MPhi(ext[4]),
                        mk = camera::MKappa(ext[5]);
  const Eigen::Matrix3d m = mk * mp * mt;
  const Eigen::Vector3d u = m * d;
  if (u.z() == 0.0) return false;
  const double c = in[camera::kC];
  const double iz = 1.0 / u.z();
  const double nx = -u.x() * iz, ny = -u.y() * iz;  // normalised: x_u = c nx
  const double xu = c * nx, yu = c * ny;
  const double k1 = in[camera::kK1], k2 = in[camera::kK2], k3 = in[camera::kK3];
  const double p1 = in[camera::kP1], p2 = in[camera::kP2], b1 = in[camera::kB1],
               b2 = in[camera::kB2];
  const double r2 = xu * xu + yu * yu;
  const double radial = r2 * (k1 + r2 * (k2 + r2 * k3));
  const double xl = xu * (1.0 + radial) + p1 * (r2 + 2.0 * xu * xu) + 2.0 * p2 * xu * yu;
  const double yl = yu * (1.0 + radial) + p2 * (r2 + 2.0 * yu * yu) + 2.0 * p1 * xu * yu;
  const double x_mm = in[camera::kX0] + (1.0 + b1) * xl + b2 * yl;
  const double y_mm = in[camera::kY0] + yl;
  const Eigen::Vector2d e(0.5 * (sensor_.width - 1) + x_mm / sensor_.pixel_size - observed_.x(),
                          0.5 * (sensor_.height - 1) - y_mm / sensor_.pixel_size - observed_.y());
  const Eigen::Vector2d whitened = sqrt_information_ * e;
  residuals[0] = whitened(0);
  residuals[1] = whitened(1);
  if (jacobians == nullptr) return true;

  // residual = S P (x_mm, y_mm): P the pixel scale (row axis down), S the whitening.
  const Eigen::Matrix2d sp =
      sqrt_information_ *
      Eigen::Vector2d(1.0 / sensor_.pixel_size, -1.0 / sensor_.pixel_size).asDiagonal();
  Eigen::Matrix2d shear;  // d(x_mm, y_mm) / d(xl, yl)
  shear << 1.0 + b1, b2, 0.0, 1.0;
  const Eigen::Matrix2d ds = sp * shear;                   // d residual / d(xl, yl)
  const double rp = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);  // d radial / d r2
  Eigen::Matrix2d dl;                                      // d(xl, yl) / d(xu, yu)
  dl(0, 0) = 1.0 + radial + 2.0 * rp * xu * xu + 6.0 * p1 * xu + 2.0 * p2 * yu;
  dl(0, 1) = 2.0 * rp * xu * yu + 2.0 * p1 * yu + 2.0 * p2 * xu;
  dl(1, 0) = 2.0 * rp * xu * yu + 2.0 * p2 * xu + 2.0 * p1 * yu;
  dl(1, 1) = 1.0 + radial + 2.0 * rp * yu * yu + 6.0 * p2 * yu + 2.0 * p1 * xu;
  const Eigen::Matrix2d du = ds * dl;  // d residual / d(xu, yu)

  if (jacobians[0] != nullptr || jacobians[2] != nullptr) {
    Eigen::Matrix<double, 2, 3> proj;  // d(xu, yu) / du
    proj << -c * iz, 0.0, -c * nx * iz, 0.0, -c * iz, -c * ny * iz;
    const Eigen::Matrix<double, 2, 3> dr_du = du * proj;
    const Eigen::Matrix<double, 2, 3> dr_dx = dr_du * m;
    if (jacobians[0] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, camera::kNumExterior, Eigen::RowMajor>> j(jacobians[0]);
      j.block<2, 3>(0, 0) = -dr_dx;
      j.col(3) = dr_du * (mk * mp * DMTheta(ext[3]) * d);
      j.col(4) = dr_du * (mk * DMPhi(ext[4]) * mt * d);
      j.col(5) = dr_du * (DMKappa(ext[5]) * mp * mt * d);
    }
    if (jacobians[2] != nullptr) {
      Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> j(jacobians[2]);
      j = dr_dx;
    }
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, camera::kNumInterior, Eigen::RowMajor>> j(jacobians[1]);
    j.col(camera::kC) = du * Eigen::Vector2d(nx, ny);
    j.col(camera::kX0) = sp.col(0);
    j.col(camera::kY0) = sp.col(1);
    j.col(camera::kK1) = ds * Eigen::Vector2d(xu, yu) * r2;
    j.col(camera::kK2) = ds * Eigen::Vector2d(xu, yu) * (r2 * r2);
    j.col(camera::kK3) = ds * Eigen::Vector2d(xu, yu) * (r2 * r2 * r2);
    j.col(camera::kP1) = ds * Eigen::Vector2d(r2 + 2.0 * xu * xu, 2.0 * xu * yu);
    j.col(camera::kP2) = ds * Eigen::Vector2d(2.0 * xu * yu, r2 + 2.0 * yu * yu);
    j.col(camera::kB1) = sp.col(0) * xl;
    j.col(camera::kB2) = sp.col(0) * yl;
  }
  return true;
}

}  // namespace adjustment
}  // namespace slope_monitor
