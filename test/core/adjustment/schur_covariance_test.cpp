// ComputeSchurCovariance (reduced camera system, points by back-substitution)
// against the full computation by ceres::Covariance on a small block: four
// UAV photos, 40 points, a camera with c and k1 free (SubsetManifold), a
// Huber loss, four surveyed control points; and the datum-free covariance
// (control held) against ceres::Covariance with the control points constant.
#include <algorithm>
#include <array>
#include <memory>
#include <random>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/control_point_prior.h"
#include "slope_monitor/core/adjustment/schur_covariance.h"
#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace adjustment {
namespace {

template <typename M>
double RelativeError(const M& a, const Eigen::MatrixXd& b) {
  return (Eigen::MatrixXd(a) - b).norm() / b.norm();
}

TEST(SchurCovarianceTest, EqualsCeresCovarianceOnASmallBlockAndWithControlHeld) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  const camera::Sensor sensor{4000, 3000, 0.004};
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 24.0;
  interior[camera::kK1] = 1e-4;
  std::vector<std::array<double, 6>> exterior;
  for (int i = 0; i < 4; ++i)
    exterior.push_back(
        {-30.0 + 20.0 * i, 5.0 * (i % 2), 60.0, 0.1 * uni(rng), 0.1 * uni(rng), 0.1 * uni(rng)});
  std::vector<std::array<double, 3>> points;
  for (int j = 0; j < 40; ++j)
    points.push_back({40.0 * uni(rng), 25.0 * uni(rng), 15.0 * uni(rng)});

  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  ceres::HuberLoss huber(1.0);
  const Eigen::Matrix2d sqrt_info = SqrtInformation<2>(Eigen::Matrix2d::Identity() * 0.25);
  for (size_t i = 0; i < exterior.size(); ++i) {
    for (size_t j = 0; j < points.size(); ++j) {
      const double* params[] = {exterior[i].data(), interior.data(), points[j].data()};
      Eigen::Vector2d predicted;
      const CollinearityErrorAnalytic zero(sensor, Eigen::Vector2d::Zero(),
                                           Eigen::Matrix2d::Identity());
      ASSERT_TRUE(zero.Evaluate(params, predicted.data(), nullptr));
      // 0.5 px noise, so some residuals are in the Huber linear range.
      const Eigen::Vector2d observed = predicted + 0.5 * Eigen::Vector2d(noise(rng), noise(rng));
      problem.AddResidualBlock(new CollinearityErrorAnalytic(sensor, observed, sqrt_info), &huber,
                               exterior[i].data(), interior.data(), points[j].data());
    }
  }
  const std::vector<int> control = {0, 1, 2, 3};
  for (const int j : control) {
    const Eigen::Vector3d surveyed = Eigen::Vector3d(points[j][0], points[j][1], points[j][2]) +
                                     0.01 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    problem.AddResidualBlock(
        ControlPointPrior::Create(surveyed, SqrtInformation<3>(Eigen::Matrix3d::Identity() * 1e-4)),
        nullptr, points[j].data());
  }
  // c and k1 free, the rest held.
  std::vector<int> fixed;
  for (int k = 0; k < camera::kNumInterior; ++k)
    if (k != camera::kC && k != camera::kK1) fixed.push_back(k);
  problem.SetManifold(interior.data(), new ceres::SubsetManifold(camera::kNumInterior, fixed));

  std::vector<double*> cameras;
  for (auto& e : exterior) cameras.push_back(e.data());
  cameras.push_back(interior.data());
  std::vector<double*> point_blocks;
  for (auto& p : points) point_blocks.push_back(p.data());

  const SchurCovarianceResult schur =
      ComputeSchurCovariance(SchurCovarianceOptions(), cameras, point_blocks, control, &problem);
  ASSERT_TRUE(schur.ok) << schur.message;
  ASSERT_EQ(schur.camera_covariance.size(), cameras.size());
  ASSERT_EQ(schur.point_covariance.size(), points.size());
  ASSERT_EQ(schur.point_covariance_held.size(), points.size());

  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;  // the reference: no sparsity tricks
  co.apply_loss_function = true;
  {
    ceres::Covariance full(co);
    std::vector<std::pair<const double*, const double*>> blocks;
    for (double* b : cameras) blocks.emplace_back(b, b);
    for (double* b : point_blocks) blocks.emplace_back(b, b);
    ASSERT_TRUE(full.Compute(blocks, &problem));
    for (size_t i = 0; i + 1 < cameras.size(); ++i) {
      Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
      full.GetCovarianceBlock(cameras[i], cameras[i], c.data());
      EXPECT_LT(RelativeError(c, schur.camera_covariance[i]), 1e-8) << "exterior " << i;
    }
    Eigen::Matrix<double, camera::kNumInterior, camera::kNumInterior, Eigen::RowMajor> ci;
    full.GetCovarianceBlock(interior.data(), interior.data(), ci.data());
    EXPECT_LT(RelativeError(ci, schur.camera_covariance.back()), 1e-8);
    EXPECT_EQ(schur.camera_covariance.back()(camera::kX0, camera::kX0),
              0.0);  // held: zero variance
    for (size_t j = 0; j < points.size(); ++j) {
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c;
      full.GetCovarianceBlock(point_blocks[j], point_blocks[j], c.data());
      EXPECT_LT(RelativeError(c, schur.point_covariance[j]), 1e-8) << "point " << j;
    }
  }
  // Datum-free: control held constant, the full computation again.
  for (const int j : control) problem.SetParameterBlockConstant(point_blocks[j]);
  ceres::Covariance held(co);
  std::vector<std::pair<const double*, const double*>> free_points;
  for (size_t j = 4; j < points.size(); ++j)
    free_points.emplace_back(point_blocks[j], point_blocks[j]);
  ASSERT_TRUE(held.Compute(free_points, &problem));
  for (size_t j = 0; j < points.size(); ++j) {
    if (j < 4) {
      EXPECT_EQ(schur.point_covariance_held[j].norm(), 0.0);
      continue;
    }
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c;
    held.GetCovarianceBlock(point_blocks[j], point_blocks[j], c.data());
    EXPECT_LT(RelativeError(c, schur.point_covariance_held[j]), 1e-8) << "point " << j;
    // Holding the control removes its error: smaller than the full covariance.
    EXPECT_LT(c.trace(), schur.point_covariance[j].trace()) << "point " << j;
  }
}

// Every point observed in every photo without error (1 px sigma).
void AddExactObservations(const camera::Sensor& sensor,
                          std::vector<std::array<double, 6>>* exterior,
                          std::array<double, camera::kNumInterior>* interior,
                          std::vector<std::array<double, 3>>* points, ceres::Problem* problem) {
  for (auto& e : *exterior)
    for (auto& p : *points) {
      const double* params[] = {e.data(), interior->data(), p.data()};
      Eigen::Vector2d predicted;
      const CollinearityErrorAnalytic zero(sensor, Eigen::Vector2d::Zero(),
                                           Eigen::Matrix2d::Identity());
      ASSERT_TRUE(zero.Evaluate(params, predicted.data(), nullptr));
      problem->AddResidualBlock(
          new CollinearityErrorAnalytic(sensor, predicted, Eigen::Matrix2d::Identity()), nullptr,
          e.data(), interior->data(), p.data());
    }
}

TEST(SchurCovarianceTest, DatumDefectIsReportedNotInverted) {
  // Two photos, points, no control and no prior: seven datum parameters free.
  const camera::Sensor sensor{4000, 3000, 0.004};
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 24.0;
  std::vector<std::array<double, 6>> exterior = {{0, 0, 60, 0, 0, 0}, {20, 0, 60, 0, 0, 0}};
  std::vector<std::array<double, 3>> points;
  for (int j = 0; j < 12; ++j)
    points.push_back({-10.0 + 4.0 * (j % 4), -6.0 + 5.0 * (j / 4), 0.5 * (j % 3)});
  ceres::Problem problem;
  AddExactObservations(sensor, &exterior, &interior, &points, &problem);
  problem.SetParameterBlockConstant(interior.data());
  std::vector<double*> cameras = {exterior[0].data(), exterior[1].data()};
  std::vector<double*> point_blocks;
  for (auto& p : points) point_blocks.push_back(p.data());
  const SchurCovarianceResult r =
      ComputeSchurCovariance(SchurCovarianceOptions(), cameras, point_blocks, {}, &problem);
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.message.find("singular"), std::string::npos) << r.message;
}

TEST(SchurCovarianceTest, ControlWithoutHeightsGivesTheCovarianceRelativeToTheHeldControl) {
  // A nadir pair over flat ground, four control points surveyed in x and y
  // only (a gcp list without heights): the block's height and tilt are not
  // determined, so the absolute covariance is singular; with the control
  // held it is not, and that is what comes back, as ceres::Covariance gives
  // it with the control points constant.
  const camera::Sensor sensor{4000, 3000, 0.004};
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 24.0;
  std::vector<std::array<double, 6>> exterior = {{0, 0, 60, 0.01, -0.02, 0.0},
                                                 {20, 1, 61, -0.01, 0.01, 0.02}};
  std::vector<std::array<double, 3>> points;
  for (int j = 0; j < 16; ++j) points.push_back({-10.0 + 6.0 * (j % 4), -8.0 + 5.0 * (j / 4), 0.0});
  ceres::Problem problem;
  AddExactObservations(sensor, &exterior, &interior, &points, &problem);
  const std::vector<int> control = {0, 3, 12, 15};  // the corners
  Eigen::Matrix3d horizontal_only = Eigen::Matrix3d::Zero();
  horizontal_only(0, 0) = horizontal_only(1, 1) = 1.0;  // 1 m in x and y, nothing in z
  for (const int j : control)
    problem.AddResidualBlock(
        ControlPointPrior::Create(Eigen::Vector3d(points[j][0], points[j][1], points[j][2]),
                                  horizontal_only),
        nullptr, points[j].data());
  problem.SetParameterBlockConstant(interior.data());
  std::vector<double*> cameras = {exterior[0].data(), exterior[1].data()};
  std::vector<double*> point_blocks;
  for (auto& p : points) point_blocks.push_back(p.data());

  const SchurCovarianceResult absolute =
      ComputeSchurCovariance(SchurCovarianceOptions(), cameras, point_blocks, {}, &problem);
  EXPECT_FALSE(absolute.ok) << "the tilt of a horizontal-only datum is not determined";
  const SchurCovarianceResult r =
      ComputeSchurCovariance(SchurCovarianceOptions(), cameras, point_blocks, control, &problem);
  ASSERT_TRUE(r.ok) << r.message;
  EXPECT_TRUE(r.relative_to_held);
  EXPECT_NE(r.message.find("relative to the held points"), std::string::npos) << r.message;
  ASSERT_EQ(r.point_covariance.size(), points.size());
  ASSERT_EQ(r.point_covariance_held.size(), points.size());

  for (const int j : control) problem.SetParameterBlockConstant(point_blocks[j]);
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance held(co);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (double* b : cameras) blocks.emplace_back(b, b);
  for (size_t j = 0; j < points.size(); ++j)
    if (std::find(control.begin(), control.end(), static_cast<int>(j)) == control.end())
      blocks.emplace_back(point_blocks[j], point_blocks[j]);
  ASSERT_TRUE(held.Compute(blocks, &problem));
  for (size_t i = 0; i < cameras.size(); ++i) {
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
    held.GetCovarianceBlock(cameras[i], cameras[i], c.data());
    EXPECT_LT(RelativeError(c, r.camera_covariance[i]), 1e-8) << "exterior " << i;
  }
  for (size_t j = 0; j < points.size(); ++j) {
    if (std::find(control.begin(), control.end(), static_cast<int>(j)) != control.end()) {
      EXPECT_EQ(r.point_covariance[j].norm(), 0.0) << "a held point has no variance";
      continue;
    }
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c;
    held.GetCovarianceBlock(point_blocks[j], point_blocks[j], c.data());
    EXPECT_LT(RelativeError(c, r.point_covariance[j]), 1e-8) << "point " << j;
    EXPECT_LT(RelativeError(c, r.point_covariance_held[j]), 1e-8) << "point " << j;
  }
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
