// CollinearityErrorAnalytic against the automatic-differentiation reference
// CollinearityError: same residuals, same Jacobians (to rounding), and
// ceres::GradientChecker (numeric differences) on random poses, including
// elevations phi at and next to the singular +-90 deg of the theta-phi-kappa
// rotation.
#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr int kSizes[3] = {camera::kNumExterior, camera::kNumInterior, 3};

struct Case {
  std::array<double, 6> ext;
  std::array<double, 10> in;
  std::array<double, 3> point;
};

// A camera at a random position looking at a random point 50-150 m ahead with
// attitude (theta, kappa random, phi given), full distortion of a 50 mm lens.
Case RandomCase(std::mt19937* rng, double phi) {
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Case k;
  k.ext = {20 * uni(*rng),  20 * uni(*rng), 100 + 10 * uni(*rng), M_PI * uni(*rng), phi,
           M_PI * uni(*rng)};
  k.in = {50.0 + uni(*rng), 0.05 * uni(*rng),  0.05 * uni(*rng), 3e-5 * uni(*rng),
          1e-8 * uni(*rng), 1e-11 * uni(*rng), 5e-6 * uni(*rng), 5e-6 * uni(*rng),
          1e-4 * uni(*rng), 1e-4 * uni(*rng)};
  // Object point on the optical axis (-w in the camera frame) plus a lateral offset.
  const Eigen::Matrix3d m = camera::RotationFromAngles(k.ext[3], k.ext[4], k.ext[5]);
  const Eigen::Vector3d in_cam(15 * uni(*rng), 10 * uni(*rng), -(100 + 50 * uni(*rng)));
  const Eigen::Vector3d x = Eigen::Vector3d(k.ext[0], k.ext[1], k.ext[2]) + m.transpose() * in_cam;
  k.point = {x.x(), x.y(), x.z()};
  return k;
}

Eigen::Matrix2d RandomSqrtInformation(std::mt19937* rng) {
  std::uniform_real_distribution<double> uni(0.2, 1.0);
  Eigen::Matrix2d cov;
  const double sx = uni(*rng), sy = uni(*rng), rho = uni(*rng) - 0.6;
  cov << sx * sx, rho * sx * sy, rho * sx * sy, sy * sy;
  return SqrtInformation<2>(cov);
}

const camera::Sensor kSensor{6000, 4000, 0.0039};

TEST(CollinearityErrorAnalyticTest, MatchesAutodiffAndNumericOnRandomPosesIncludingPhiNear90Deg) {
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> obs(-40.0, 40.0);
  const double half_pi = 0.5 * M_PI;
  std::vector<double> phis = {half_pi,        -half_pi, half_pi - 1e-7, -half_pi + 1e-7,
                              half_pi - 1e-3, 1.2,      -0.7,           0.0};
  for (int i = 0; i < 12; ++i)
    phis.push_back(std::uniform_real_distribution<double>(-half_pi, half_pi)(rng));
  int checked = 0;
  for (const double phi : phis) {
    const Case k = RandomCase(&rng, phi);
    const double* params[] = {k.ext.data(), k.in.data(), k.point.data()};
    // Observation near the prediction (residuals of a few pixels).
    Eigen::Vector2d predicted;
    {
      const CollinearityErrorAnalytic zero(kSensor, Eigen::Vector2d::Zero(),
                                           Eigen::Matrix2d::Identity());
      ASSERT_TRUE(zero.Evaluate(params, predicted.data(), nullptr));
    }
    const Eigen::Vector2d observed = predicted + Eigen::Vector2d(obs(rng), obs(rng)) * 0.1;
    const Eigen::Matrix2d s = RandomSqrtInformation(&rng);
    std::unique_ptr<ceres::CostFunction> autodiff(CollinearityError::Create(kSensor, observed, s));
    const CollinearityErrorAnalytic analytic(kSensor, observed, s);

    double r_auto[2], r_an[2];
    std::array<std::vector<double>, 3> j_auto, j_an;
    double* ja[3];
    double* jn[3];
    for (int b = 0; b < 3; ++b) {
      j_auto[b].assign(2 * kSizes[b], 0.0);
      j_an[b].assign(2 * kSizes[b], 0.0);
      ja[b] = j_auto[b].data();
      jn[b] = j_an[b].data();
    }
    ASSERT_TRUE(autodiff->Evaluate(params, r_auto, ja));
    ASSERT_TRUE(analytic.Evaluate(params, r_an, jn));
    for (int i = 0; i < 2; ++i) EXPECT_NEAR(r_an[i], r_auto[i], 1e-9) << "phi " << phi;
    for (int b = 0; b < 3; ++b) {
      for (int row = 0; row < 2; ++row) {
        for (int col = 0; col < kSizes[b]; ++col) {
          const double a = j_auto[b][row * kSizes[b] + col], n = j_an[b][row * kSizes[b] + col];
          EXPECT_NEAR(n, a, 1e-9 * (1.0 + std::abs(a)))
              << "phi " << phi << " block " << b << " row " << row << " col " << col;
        }
      }
    }
    // Numeric differences (the parameters of very different scale make the
    // check coarser than the autodiff comparison above).
    const std::vector<const ceres::Manifold*>* none = nullptr;
    ceres::GradientChecker checker(&analytic, none, ceres::NumericDiffOptions());
    ceres::GradientChecker::ProbeResults results;
    EXPECT_TRUE(checker.Probe(params, 1e-5, &results)) << "phi " << phi << "\n"
                                                       << results.error_log;
    ++checked;
  }
  EXPECT_EQ(checked, static_cast<int>(phis.size()));
}

TEST(CollinearityErrorAnalyticTest, PointInTheCameraPlaneIsRejectedLikeAutodiff) {
  const std::array<double, 6> ext = {0, 0, 100, 0, 0, 0};
  std::array<double, 10> in{};
  in[camera::kC] = 50.0;
  const std::array<double, 3> x = {10, 0, 100};  // u_z = 0
  const double* params[] = {ext.data(), in.data(), x.data()};
  double r[2];
  const CollinearityErrorAnalytic analytic(kSensor, Eigen::Vector2d(0, 0),
                                           Eigen::Matrix2d::Identity());
  std::unique_ptr<ceres::CostFunction> autodiff(
      CollinearityError::Create(kSensor, Eigen::Vector2d(0, 0), Eigen::Matrix2d::Identity()));
  EXPECT_FALSE(analytic.Evaluate(params, r, nullptr));
  EXPECT_FALSE(autodiff->Evaluate(params, r, nullptr));
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
