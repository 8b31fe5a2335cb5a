// Reprojection error of the Snavely (Bundler / BAL) camera, the alternative
// camera model used for the Bundle Adjustment in the Large problems.
//
// Model (Agarwal et al. 2010, BAL format):
//   P = R(w) X + t                 R from the angle-axis vector w (Rodrigues)
//   p = -P_xy / P_z                (the camera looks along -z)
//   r2 = |p|^2,  d = 1 + k1 r2 + k2 r2^2
//   residual = f d p - observed    [px] (BAL image coordinates: origin at the
//                                  image centre, x right, y up). Sign: predicted minus observed.
//
// Parameter blocks:
//   0  camera[9]  w (3) [rad] angle-axis of cam_from_world, t (3) [world units],
//                 f [px], k1 [px^-2 normalised: r2 is in normalised units], k2
//   1  point[3]   X Y Z [world units]
//
// Two implementations: SnavelyReprojectionError (automatic differentiation) and
// SnavelyReprojectionErrorAnalytic (hand-written Jacobian; checked against the
// automatic one by ceres::GradientChecker in the tests; timed in
// bench/bal_ladybug.cpp).
#pragma once

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>
#include <ceres/sized_cost_function.h>
#include <Eigen/Core>

namespace slope_monitor {
namespace adjustment {

class SnavelyReprojectionError {
 public:
  SnavelyReprojectionError(double observed_x, double observed_y)
      : observed_x_(observed_x), observed_y_(observed_y) {}

  template <typename T>
  bool operator()(const T* camera, const T* point, T* residuals) const {
    T p[3];
    ceres::AngleAxisRotatePoint(camera, point, p);
    p[0] += camera[3];
    p[1] += camera[4];
    p[2] += camera[5];
    const T xp = -p[0] / p[2];
    const T yp = -p[1] / p[2];
    const T r2 = xp * xp + yp * yp;
    const T distortion = T(1) + r2 * (camera[7] + camera[8] * r2);
    residuals[0] = camera[6] * distortion * xp - T(observed_x_);
    residuals[1] = camera[6] * distortion * yp - T(observed_y_);
    return true;
  }

  static ceres::CostFunction* Create(double observed_x, double observed_y) {
    return new ceres::AutoDiffCostFunction<SnavelyReprojectionError, 2, 9, 3>(
        new SnavelyReprojectionError(observed_x, observed_y));
  }

 private:
  double observed_x_;
  double observed_y_;
};

class SnavelyReprojectionErrorAnalytic : public ceres::SizedCostFunction<2, 9, 3> {
 public:
  SnavelyReprojectionErrorAnalytic(double observed_x, double observed_y)
      : observed_x_(observed_x), observed_y_(observed_y) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  static ceres::CostFunction* Create(double observed_x, double observed_y) {
    return new SnavelyReprojectionErrorAnalytic(observed_x, observed_y);
  }

 private:
  double observed_x_;
  double observed_y_;
};

}  // namespace adjustment
}  // namespace slope_monitor
