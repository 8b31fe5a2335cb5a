// Cost functions: residuals at hand-checkable poses and ceres::GradientChecker
// on every cost function (analytic Jacobians against numeric differences).
#include <memory>
#include <vector>

#include <ceres/gradient_checker.h>
#include <ceres/rotation.h>
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/control_point_prior.h"
#include "slope_monitor/core/adjustment/cost_functions/position_prior.h"
#include "slope_monitor/core/adjustment/cost_functions/snavely_reprojection_error.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {
namespace {

// Ceres 2.1: the nullptr overload of the constructor is ambiguous.
bool GradientOk(const ceres::CostFunction* cost, const std::vector<const double*>& params,
                double precision, std::string* error) {
  const std::vector<const ceres::Manifold*>* none = nullptr;
  ceres::NumericDiffOptions nd;
  ceres::GradientChecker checker(cost, none, nd);
  ceres::GradientChecker::ProbeResults results;
  const bool ok = checker.Probe(params.data(), precision, &results);
  *error = results.error_log;
  return ok;
}

camera::Sensor TestSensor() { return camera::Sensor{6000, 4000, 0.0039}; }

TEST(CollinearityErrorTest, ZeroResidualAtTheProjectedPixel) {
  // Nadir camera 100 m above the origin, c = 50 mm: a point 10 m east of the
  // nadir point images at x = -c * U / W = 50 * 10 / 100 = 5 mm -> 5 / 0.0039 px right of centre.
  const std::array<double, 6> ext = {0, 0, 100, 0, 0, 0};
  std::array<double, 10> in{};
  in[camera::kC] = 50.0;
  const std::array<double, 3> x = {10, 0, 0};
  const Eigen::Vector2d expected(0.5 * 5999 + 5.0 / 0.0039, 0.5 * 3999);
  std::unique_ptr<ceres::CostFunction> cost(
      CollinearityError::Create(TestSensor(), expected, Eigen::Matrix2d::Identity()));
  const double* params[] = {ext.data(), in.data(), x.data()};
  double r[2];
  ASSERT_TRUE(cost->Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], 0.0, 1e-9);
  EXPECT_NEAR(r[1], 0.0, 1e-9);
  // One pixel off in the observation and a 0.5 px sigma: whitened residual -2.
  std::unique_ptr<ceres::CostFunction> cost2(
      CollinearityError::Create(TestSensor(), expected + Eigen::Vector2d(1.0, 0.0),
                                SqrtInformation<2>(Eigen::Matrix2d::Identity() * 0.25)));
  ASSERT_TRUE(cost2->Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], -2.0, 1e-9);
}

TEST(CollinearityErrorTest, GradientCheckWithFullDistortion) {
  const std::array<double, 6> ext = {3.0, -2.0, 120.0, 0.05, -0.08, 0.3};
  const std::array<double, 10> in = {50.0,  0.02, -0.03, 2e-5, -1e-8,
                                     1e-11, 3e-6, -2e-6, 1e-4, -5e-5};
  const std::array<double, 3> x = {12.0, 8.0, 4.0};
  Eigen::Matrix2d cov;
  cov << 0.04, 0.01, 0.01, 0.09;
  std::unique_ptr<ceres::CostFunction> cost(CollinearityError::Create(
      TestSensor(), Eigen::Vector2d(3400, 1800), SqrtInformation<2>(cov)));
  std::string error;
  EXPECT_TRUE(GradientOk(cost.get(), {ext.data(), in.data(), x.data()}, 1e-6, &error)) << error;
}

TEST(ControlPointPriorTest, ResidualAndGradient) {
  const Eigen::Vector3d surveyed(10, 20, 30);
  Eigen::Matrix3d cov = Eigen::Vector3d(0.03 * 0.03, 0.03 * 0.03, 0.01 * 0.01).asDiagonal();
  std::unique_ptr<ceres::CostFunction> cost(
      ControlPointPrior::Create(surveyed, SqrtInformation<3>(cov)));
  const std::array<double, 3> x = {10.03, 20.0, 29.98};  // +1 sigma east, -2 sigma down
  const double* params[] = {x.data()};
  double r[3];
  ASSERT_TRUE(cost->Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], 1.0, 1e-9);
  EXPECT_NEAR(r[1], 0.0, 1e-9);
  EXPECT_NEAR(r[2], -2.0, 1e-9);
  std::string error;
  EXPECT_TRUE(GradientOk(cost.get(), {x.data()}, 1e-7, &error)) << error;
}

TEST(PositionPriorTest, ResidualAndGradient) {
  Eigen::Matrix3d cov;
  cov << 0.0009, 0.0003, 0.0, 0.0003, 0.0009, 0.0, 0.0, 0.0, 0.0025;
  std::unique_ptr<ceres::CostFunction> cost(
      PositionPriorError::Create(Eigen::Vector3d(1, 2, 80), SqrtInformation<3>(cov)));
  const std::array<double, 6> e = {1.0, 2.0, 80.05, 0.1, 0.2, 0.3};  // 1 sigma high
  const double* params[] = {e.data()};
  double r[3];
  ASSERT_TRUE(cost->Evaluate(params, r, nullptr));
  EXPECT_NEAR(Eigen::Vector3d(r[0], r[1], r[2]).norm(), 1.0, 1e-9);
  std::string error;
  EXPECT_TRUE(GradientOk(cost.get(), {e.data()}, 1e-7, &error)) << error;
}

TEST(SnavelyTest, AnalyticEqualsAutodiffAndPassesGradientCheck) {
  const std::vector<std::array<double, 9>> cameras = {
      {0.01, -0.02, 0.005, 0.1, -0.2, -3.0, 500.0, -1e-7 * 250000, 2e-13 * 250000 * 250000},
      {0.0, 0.0, 0.0, 0.0, 0.0, -5.0, 800.0, 0.1, -0.01},  // angle-axis exactly zero
      {1.2, -0.7, 2.1, 0.3, 0.4, -8.0, 1200.0, -0.05, 0.002}};
  const std::array<double, 3> x = {0.4, -0.3, 1.5};
  for (const auto& cam : cameras) {
    std::unique_ptr<ceres::CostFunction> ad(SnavelyReprojectionError::Create(12.0, -7.0));
    std::unique_ptr<ceres::CostFunction> an(SnavelyReprojectionErrorAnalytic::Create(12.0, -7.0));
    const double* params[] = {cam.data(), x.data()};
    double r1[2], r2[2], j1c[18], j1p[6], j2c[18], j2p[6];
    double* j1[] = {j1c, j1p};
    double* j2[] = {j2c, j2p};
    ASSERT_TRUE(ad->Evaluate(params, r1, j1));
    ASSERT_TRUE(an->Evaluate(params, r2, j2));
    EXPECT_NEAR(r1[0], r2[0], 1e-9);
    EXPECT_NEAR(r1[1], r2[1], 1e-9);
    for (int i = 0; i < 18; ++i)
      EXPECT_NEAR(j1c[i], j2c[i], 1e-7 * (1.0 + std::abs(j1c[i]))) << "camera jac " << i;
    for (int i = 0; i < 6; ++i)
      EXPECT_NEAR(j1p[i], j2p[i], 1e-7 * (1.0 + std::abs(j1p[i]))) << "point jac " << i;
    std::string error;
    EXPECT_TRUE(GradientOk(an.get(), {cam.data(), x.data()}, 1e-6, &error)) << error;
    EXPECT_TRUE(GradientOk(ad.get(), {cam.data(), x.data()}, 1e-6, &error)) << error;
  }
}

TEST(SqrtInformationTest, RejectsBadCovariance) {
  Eigen::Matrix2d c;
  c << 1.0, 2.0, 2.0, 1.0;  // indefinite
  EXPECT_THROW(SqrtInformation<2>(c), InvalidArgument);
  c << 1.0, std::nan(""), 0.0, 1.0;
  EXPECT_THROW(SqrtInformation<2>(c), InvalidArgument);
  c << 4.0, 0.0, 0.0, 0.25;
  const Eigen::Matrix2d s = SqrtInformation<2>(c);
  EXPECT_TRUE((s.transpose() * s).isApprox(c.inverse(), 1e-12));
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
