// Bundle adjustment on synthetic fixed-camera and UAV scenes with known truth
// (test/core/adjustment/synthetic_scene.h, fixed seeds): coordinates within 3
// sigma, camera poses, self-calibration, epoch displacements, and bad input.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/adjustment/initialization.h"
#include "slope_monitor/core/common/error.h"
#include "synthetic_scene.h"

namespace slope_monitor {
namespace adjustment {
namespace {

using testing::MakeScene;
using testing::SceneSpec;
using testing::TruthScene;

// Fraction of adjusted points within "3 sigma" of the truth in 3-D: the squared
// Mahalanobis distance e^T C^-1 e below the chi-square(3) quantile of the
// one-dimensional 3-sigma probability 0.9973 (14.16).
double FractionWithin3Sigma(const Scene& truth, const Scene& solved, const Summary& s, int* n_out) {
  int n = 0, ok = 0;
  for (size_t j = 0; j < solved.points.size(); ++j) {
    const Eigen::Matrix3d& c = s.precision.point_covariance[j];
    if (c.isZero()) continue;
    ++n;
    const Eigen::Vector3d e = solved.points[j].position - truth.points[j].position;
    ok += e.dot(c.inverse() * e) <= 14.16;
  }
  *n_out = n;
  return n > 0 ? static_cast<double>(ok) / n : 0.0;
}

double AngleError(const camera::AttitudeAngles& a, const camera::AttitudeAngles& b) {
  return Eigen::AngleAxisd(camera::RotationFromAngles(a) *
                           camera::RotationFromAngles(b).transpose())
      .angle();
}

// Fixed cameras: 0.05 px (good circular / tag targets) must reach the issue's
// 5 mm; 0.1 px is reported and held to 7 mm.
class FixedCameraTest : public ::testing::TestWithParam<std::pair<double, double>> {};

TEST_P(FixedCameraTest, TwoEpochsDisplacements) {
  const double pixel_sigma = GetParam().first;
  const double max_rms = GetParam().second;
  Options options;
  Config config;  // interior fixed: the fixed cameras are calibrated
  BundleAdjuster adjuster(options, config);

  std::vector<EpochPoints> epochs;
  std::vector<TruthScene> scenes;
  int total_n = 0;
  double total_within = 0.0;
  for (int epoch = 0; epoch < 2; ++epoch) {
    SceneSpec spec;
    spec.seed = 10 + epoch;
    spec.pixel_sigma = pixel_sigma;
    spec.motion = epoch == 0 ? 0.0 : 0.06;
    spec.camera_drift = epoch == 0 ? 0.0 : 0.002;
    TruthScene ts = MakeScene(spec);
    Scene scene = ts.observed;
    const Summary s = adjuster.Solve(&scene);
    ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
    std::printf("fixed epoch %d: %s\n", epoch, s.BriefReport().c_str());
    EXPECT_EQ(s.num_outliers, 0);
    EXPECT_NEAR(s.sigma0, 1.0, 0.25);
    int n;
    const double f = FractionWithin3Sigma(ts.truth, scene, s, &n);
    total_n += n;
    total_within += f * n;
    EXPECT_GE(f, 0.97) << n << " points";
    for (size_t i = 0; i < scene.images.size(); ++i) {
      const double dp =
          (scene.images[i].exterior.position - ts.truth.images[i].exterior.position).norm();
      const double da =
          AngleError(scene.images[i].exterior.angles, ts.truth.images[i].exterior.angles);
      std::printf("  %s: position error %.4f m (sigma %.4f), attitude error %.3f mrad\n",
                  scene.images[i].name.c_str(), dp,
                  std::sqrt(s.precision.exterior_covariance[i].topLeftCorner<3, 3>().trace()),
                  da * 1e3);
      EXPECT_LT(dp, 0.05);
      EXPECT_LT(da, 2e-4);
    }
    epochs.push_back(EpochPointsFromSolution(scene, s, epoch, 1000.0 * epoch));
    ts.observed = scene;
    scenes.push_back(ts);
  }
  std::printf("fixed: %.4f of %d point-epochs within 3 sigma\n", total_within / total_n, total_n);
  EXPECT_GE(total_within / total_n, 0.99);

  const EpochComparison cmp = CompareEpochs(epochs[0], epochs[1]);
  ASSERT_TRUE(cmp.success) << cmp.message;
  double ss = 0.0;
  int n = 0, significant_ok = 0, moving = 0;
  for (const Displacement& d : cmp.displacements) {
    const int j = scenes[1].truth.FindPoint(d.id);
    const int j0 = scenes[0].truth.FindPoint(d.id);
    const Eigen::Vector3d truth =
        scenes[1].truth.points[j].position - scenes[0].truth.points[j0].position;
    ss += (d.displacement - truth).squaredNorm();
    ++n;
    if (truth.norm() > 0.02) {
      ++moving;
      significant_ok += d.significant;
    }
  }
  const double rms = std::sqrt(ss / n);
  std::printf(
      "fixed cameras at 100-200 m, %.2f px: displacement RMS vs truth = %.2f mm over %d monitoring "
      "points\n",
      pixel_sigma, rms * 1e3, n);
  EXPECT_EQ(n, 20);
  EXPECT_LT(rms, max_rms);
  EXPECT_EQ(significant_ok, moving);
}

INSTANTIATE_TEST_SUITE_P(PixelNoise, FixedCameraTest,
                         ::testing::Values(std::make_pair(0.05, 0.005),
                                           std::make_pair(0.1, 0.007)));

TEST(BundleAdjusterTest, UavSelfCalibrationWithGnssPriors) {
  Options options;
  Config config;
  config.FreeInteriorOfAll(1, {camera::kC, camera::kX0, camera::kY0, camera::kK1, camera::kK2});
  BundleAdjuster adjuster(options, config);
  std::vector<EpochPoints> epochs;
  std::vector<TruthScene> scenes;
  for (int epoch = 0; epoch < 2; ++epoch) {
    SceneSpec spec;
    spec.uav = true;
    spec.seed = 30 + epoch;
    spec.pixel_sigma = 0.3;
    spec.survey_sigma_h = 0.01;
    spec.survey_sigma_v = 0.01;
    spec.motion = epoch == 0 ? 0.0 : 0.10;
    spec.num_tie = 120;
    TruthScene ts = MakeScene(spec);
    Scene scene = ts.observed;
    const Summary s = adjuster.Solve(&scene);
    ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
    std::printf("uav epoch %d: %s\n", epoch, s.BriefReport().c_str());
    int n;
    const double f = FractionWithin3Sigma(ts.truth, scene, s, &n);
    std::printf("uav epoch %d: %.4f of %d points within 3 sigma\n", epoch, f, n);
    EXPECT_GE(f, 0.99);
    // Self-calibration against the truth.
    const auto& est = scene.cameras[0].model.interior();
    const auto& tru = ts.truth.cameras[0].model.interior();
    const auto& sig = s.precision.interior_sigma[0];
    for (int k : {camera::kC, camera::kX0, camera::kY0, camera::kK1}) {
      std::printf("  %s: estimated %.6g, truth %.6g, sigma %.3g\n", camera::InteriorNames()[k],
                  est[k], tru[k], sig[k]);
      EXPECT_LE(std::abs(est[k] - tru[k]), 3.5 * sig[k] + 1e-12) << camera::InteriorNames()[k];
    }
    EXPECT_NEAR(est[camera::kC], tru[camera::kC], 0.005);  // 5 um on 8.85 mm
    EXPECT_NEAR(est[camera::kX0], tru[camera::kX0], 0.005);
    EXPECT_NEAR(est[camera::kY0], tru[camera::kY0], 0.005);
    EXPECT_NEAR(est[camera::kK1], tru[camera::kK1], 5e-6);
    double worst_pos = 0.0, worst_att = 0.0;
    for (size_t i = 0; i < scene.images.size(); ++i) {
      worst_pos = std::max(
          worst_pos,
          (scene.images[i].exterior.position - ts.truth.images[i].exterior.position).norm());
      worst_att = std::max(worst_att, AngleError(scene.images[i].exterior.angles,
                                                 ts.truth.images[i].exterior.angles));
    }
    std::printf("  %zu images: worst position error %.4f m, worst attitude error %.3f mrad\n",
                scene.images.size(), worst_pos, worst_att * 1e3);
    EXPECT_LT(worst_pos, 0.08);
    EXPECT_LT(worst_att, 1e-3);
    epochs.push_back(EpochPointsFromSolution(scene, s, epoch, 1000.0 * epoch));
    ts.observed = scene;
    scenes.push_back(ts);
  }
  const EpochComparison cmp = CompareEpochs(epochs[0], epochs[1]);
  ASSERT_TRUE(cmp.success) << cmp.message;
  double ss = 0.0;
  int n = 0;
  for (const Displacement& d : cmp.displacements) {
    const Eigen::Vector3d truth = scenes[1].truth.points[scenes[1].truth.FindPoint(d.id)].position -
                                  scenes[0].truth.points[scenes[0].truth.FindPoint(d.id)].position;
    ss += (d.displacement - truth).squaredNorm();
    ++n;
  }
  const double rms = std::sqrt(ss / n);
  std::printf(
      "uav at ~60 m, 0.3 px: displacement RMS vs truth = %.2f mm over %d monitoring points\n",
      rms * 1e3, n);
  EXPECT_GE(n, 15);
  EXPECT_LT(rms, 0.02);
}

TEST(BundleAdjusterTest, InitializationFromControlPointsOnly) {
  SceneSpec spec;
  spec.seed = 5;
  TruthScene ts = MakeScene(spec);
  Scene scene = ts.observed;
  for (Image& im : scene.images) {
    im.exterior = camera::ExteriorOrientation();
    im.exterior_known = false;
  }
  for (ObjectPoint& p : scene.points) {
    p.position = Eigen::Vector3d::Zero();
    p.position_known = false;
  }
  const std::string init = InitializeScene(&scene);
  EXPECT_EQ(init, "");
  for (size_t i = 0; i < scene.images.size(); ++i)
    EXPECT_LT((scene.images[i].exterior.position - ts.truth.images[i].exterior.position).norm(),
              0.5);
  BundleAdjuster adjuster{Options(), Config()};
  const Summary s = adjuster.Solve(&scene);
  ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
  for (size_t i = 0; i < scene.images.size(); ++i)
    EXPECT_LT((scene.images[i].exterior.position - ts.truth.images[i].exterior.position).norm(),
              0.05);
}

TEST(BundleAdjusterTest, ReportsOutliers) {
  SceneSpec spec;
  spec.seed = 7;
  TruthScene ts = MakeScene(spec);
  Scene scene = ts.observed;
  const std::vector<int> bad = {3, 40, 77};
  for (int k : bad) scene.observations[k].pixel += Eigen::Vector2d(6.0, -4.0);  // 70 sigma
  const Summary s = BundleAdjuster(Options(), Config()).Solve(&scene);
  ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
  EXPECT_EQ(s.outliers, bad);
  EXPECT_NEAR(s.sigma0, 1.0, 0.3);
}

// Bad input: the Summary says why, and the scene keeps its previous values.
class BadInputTest : public ::testing::Test {
 protected:
  void SetUp() override { scene_ = MakeScene(SceneSpec()).observed; }
  void ExpectRejected(const Summary& s, const Scene& before, const std::string& phrase) {
    EXPECT_FALSE(s.IsSolutionUsable());
    EXPECT_NE(s.reason.find(phrase), std::string::npos) << s.reason;
    ASSERT_EQ(before.points.size(), scene_.points.size());
    for (size_t j = 0; j < before.points.size(); ++j)
      EXPECT_EQ(before.points[j].position, scene_.points[j].position);
    for (size_t i = 0; i < before.images.size(); ++i)
      EXPECT_EQ(before.images[i].exterior.position, scene_.images[i].exterior.position);
  }
  Scene scene_;
};

TEST_F(BadInputTest, TooFewControlPoints) {
  int kept = 0;
  for (ObjectPoint& p : scene_.points)
    if (p.role == PointRole::kControl && ++kept > 2) p.role = PointRole::kTie;
  const Scene before = scene_;
  ExpectRejected(BundleAdjuster(Options(), Config()).Solve(&scene_), before,
                 "too few control points");
}

TEST_F(BadInputTest, CollinearControlPoints) {
  int k = 0;
  for (ObjectPoint& p : scene_.points) {
    if (p.role != PointRole::kControl) continue;
    *p.surveyed = Eigen::Vector3d(10.0 + 15.0 * k, 5.0 + 12.0 * k, 3.0 * k);  // all on one line
    ++k;
  }
  const Scene before = scene_;
  ExpectRejected(BundleAdjuster(Options(), Config()).Solve(&scene_), before, "one line");
}

TEST_F(BadInputTest, ImageWithoutObservations) {
  Image extra = scene_.images[0];
  extra.name = "fixed_cam_9";
  scene_.images.push_back(extra);
  const Scene before = scene_;
  ExpectRejected(BundleAdjuster(Options(), Config()).Solve(&scene_), before,
                 "'fixed_cam_9' has no observations");
}

TEST_F(BadInputTest, NanObservation) {
  scene_.observations[5].pixel.y() = std::nan("");
  const Scene before = scene_;
  ExpectRejected(BundleAdjuster(Options(), Config()).Solve(&scene_), before, "not finite");
}

TEST_F(BadInputTest, DivergingSolver) {
  // Wildly wrong initial poses and two iterations: the solver cannot converge.
  for (Image& im : scene_.images) {
    im.exterior.angles.theta += 1.0;
    im.exterior.position += Eigen::Vector3d(40, 60, -30);
  }
  Options options;
  options.max_iterations = 2;
  const Scene before = scene_;
  const Summary s = BundleAdjuster(options, Config()).Solve(&scene_);
  ExpectRejected(s, before, "");
  EXPECT_TRUE(s.reason.find("did not converge") != std::string::npos ||
              s.reason.find("behind") != std::string::npos ||
              s.reason.find("sigma0") != std::string::npos ||
              s.reason.find("outliers") != std::string::npos)
      << s.reason;
}

TEST(BundleAdjusterOptionsTest, BadOptionsNameTheField) {
  Options o;
  o.loss = "tukey";
  try {
    BundleAdjuster(o, Config());
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("loss"), std::string::npos);
  }
  o = Options();
  o.max_iterations = 0;
  EXPECT_THROW(BundleAdjuster(o, Config()), ConfigError);
}

TEST(ErrorEllipsoidTest, HandCheckedAxes) {
  Eigen::Matrix3d c = Eigen::Vector3d(4e-6, 1e-6, 9e-6).asDiagonal();
  const ErrorEllipsoid e = ErrorEllipsoidOf(c, 2.0);
  EXPECT_NEAR(e.semi_axes(0), 2e-3, 1e-12);
  EXPECT_NEAR(e.semi_axes(1), 4e-3, 1e-12);
  EXPECT_NEAR(e.semi_axes(2), 6e-3, 1e-12);
  EXPECT_NEAR(std::abs(e.axes(2, 2)), 1.0, 1e-12);
  EXPECT_NEAR(Significance(Eigen::Vector3d(0, 0, 0.009), c), 3.0, 1e-9);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
