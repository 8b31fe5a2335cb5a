// SolveCeresProblem gives the same numbers wherever the parameter blocks lie
// in memory. Ceres orders the blocks of one ordering group by their address;
// with the exteriors and the interior in one group, an interior allocated
// before the exteriors or after them changed the reduced camera system's
// column order, and a weak datum amplified the rounding (copr through
// process_bag: cameras 0.5 mm and 0.001 deg apart from run to run). The
// same problem is built twice, the interior placed before and after the
// exteriors in one buffer, and solved: every value bit for bit equal.
#include <array>
#include <cstring>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/control_point_prior.h"
#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr int kImages = 6, kPoints = 40;

// A nadir strip over rolling ground, four control points to 1 m (a weak
// datum), k1 free; `interior_first`: where the interior lies.
std::vector<double> Solve(bool interior_first) {
  const camera::Sensor sensor{4000, 3000, 0.004};
  std::array<double, camera::kNumInterior> truth_interior{};
  truth_interior[camera::kC] = 24.0;
  truth_interior[camera::kK1] = -2e-4;
  std::vector<std::array<double, 6>> truth_exterior;
  for (int i = 0; i < kImages; ++i)
    truth_exterior.push_back({12.0 * i, 0.3 * (i % 2), 60.0 + (i % 3), 0.01 * i, -0.02, 0.03});
  std::vector<std::array<double, 3>> truth_points;
  for (int j = 0; j < kPoints; ++j)
    truth_points.push_back({-10.0 + 2.2 * j, -12.0 + 6.0 * (j % 5), 2.0 * std::sin(0.7 * j)});

  // One buffer: [interior | exteriors | points] or [exteriors | interior | points].
  const int ni = camera::kNumInterior, ne = 6 * kImages;
  std::vector<double> buffer(ni + ne + 3 * kPoints);
  double* interior = buffer.data() + (interior_first ? 0 : ne);
  double* exterior = buffer.data() + (interior_first ? ni : 0);
  double* points = buffer.data() + ni + ne;
  // Start values off the truth by a fixed pattern.
  for (int k = 0; k < ni; ++k) interior[k] = truth_interior[k];
  interior[camera::kK1] = 0.0;
  for (int i = 0; i < kImages; ++i)
    for (int k = 0; k < 6; ++k) exterior[6 * i + k] = truth_exterior[i][k] + 0.01 * ((i + k) % 3);
  for (int j = 0; j < kPoints; ++j)
    for (int k = 0; k < 3; ++k) points[3 * j + k] = truth_points[j][k] + 0.1 * ((j + k) % 4);

  ceres::Problem problem;
  std::vector<double*> point_blocks;
  for (int i = 0; i < kImages; ++i)
    for (int j = 0; j < kPoints; ++j) {
      std::array<double, 6> e = truth_exterior[i];
      std::array<double, 3> x = truth_points[j];
      const double* at[] = {e.data(), truth_interior.data(), x.data()};
      Eigen::Vector2d px;
      const CollinearityErrorAnalytic zero(sensor, Eigen::Vector2d::Zero(),
                                           Eigen::Matrix2d::Identity());
      if (!zero.Evaluate(at, px.data(), nullptr)) continue;
      if (px.x() < 0 || px.y() < 0 || px.x() > 4000 || px.y() > 3000) continue;
      problem.AddResidualBlock(
          new CollinearityErrorAnalytic(sensor, px + Eigen::Vector2d(0.3 * ((i * j) % 3 - 1), 0.2),
                                        Eigen::Matrix2d::Identity()),
          nullptr, exterior + 6 * i, interior, points + 3 * j);
    }
  for (int j = 0; j < kPoints; ++j)
    if (problem.HasParameterBlock(points + 3 * j)) point_blocks.push_back(points + 3 * j);
  for (int j : {0, 9, 30, 39})
    problem.AddResidualBlock(
        ControlPointPrior::Create(
            Eigen::Vector3d(truth_points[j][0], truth_points[j][1], truth_points[j][2]),
            Eigen::Matrix3d::Identity()),
        nullptr, points + 3 * j);
  std::vector<int> fixed;
  for (int k = 0; k < ni; ++k)
    if (k != camera::kK1) fixed.push_back(k);
  problem.SetManifold(interior, new ceres::SubsetManifold(ni, fixed));
  Options options;
  const SolveReport report =
      SolveCeresProblem(options, point_blocks, kImages, &problem, {interior});
  EXPECT_TRUE(report.converged) << report.termination;
  // In a fixed order: interior, exteriors, points.
  std::vector<double> out(interior, interior + ni);
  out.insert(out.end(), exterior, exterior + ne);
  out.insert(out.end(), points, points + 3 * kPoints);
  return out;
}

TEST(SolveCeresProblem, SameNumbersWhereverTheBlocksLie) {
  const std::vector<double> a = Solve(true), b = Solve(false);
  ASSERT_EQ(a.size(), b.size());
  int differ = 0;
  for (size_t k = 0; k < a.size(); ++k) differ += std::memcmp(&a[k], &b[k], sizeof(double)) != 0;
  EXPECT_EQ(differ, 0) << "values not bit-identical between the two memory layouts";
  EXPECT_NEAR(a[camera::kK1], -2e-4, 2e-5);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
