// The photo pair matcher (photo_pair_matcher.h, defaults) on the package's
// simulator against its geometric truth: two nadir photos of the simulated
// slope (the UAV camera at half resolution, as uav_sequence_test.cpp), the
// second flown the other way round a turn (heading 160 deg: the image turned
// by 160 deg), 14 % lower (ground 1.14 times larger) and 6 m further along.
// Truth of a tie point: the ray of xa through the true camera a intersected
// with the true terrain, projected with the true camera b. Checked: count,
// rotation and scale of the relation, error RMS, points beyond 1 px, and the
// mean chi2 of the errors under the reported covariance.
// Links slope_monitor_core_sim (CMakeLists.txt: this test only).
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "slope_monitor/core/matching/photo_pair_matcher.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"

#include "../sim/test_scene.h"  // the small simulated slope (header only)

namespace slope_monitor {
namespace matching {
namespace {

constexpr int kPairW = 640, kPairH = 480;
constexpr double kHeight = 60.0;  // [m] photo a above the ground
constexpr double kC = 9.1667;  // [mm] the UAV camera's field of view on 640 x 480 pixels of 0.01 mm
constexpr double kHeading = 160.0;  // [deg] of photo b (a: 0)
constexpr double kScale = 1.14;     // ground size in b / in a

sim::SceneSpec PairSite() {
  sim::SceneSpec s = sim::testing::SmallSlope(11);
  s.terrain.extent = Eigen::Vector4d(0, 60, 0, 60);
  s.texture.coarsest_wavelength = 8.0;
  s.landslide.velocity0 = 0.0;
  s.scarp.depth = 0.0;
  return s;
}

TEST(PhotoPairSim, TurnedLowerPhotoAgainstTruth) {
  const sim::Scene scene(PairSite());
  const camera::CameraModel model =
      sim::testing::SmallCamera(kPairW, kPairH, kC, 0.02, -0.01, -1.0e-3);
  const sim::Scene::State state = scene.AtTime(0.0);
  const double ground = scene.AnalyticHeight(30, 30);
  const double h = kHeading * M_PI / 180.0;
  const Eigen::Vector3d pa(30, 27, ground + kHeight), pb(30, 33, ground + kHeight / kScale);
  const camera::ExteriorOrientation a = sim::testing::NadirFrom(pa);
  const camera::ExteriorOrientation b = sim::LookAt(pb, pb - Eigen::Vector3d::UnitZ(),
                                                    Eigen::Vector3d(std::sin(h), std::cos(h), 0.0));
  const sim::Renderer renderer(scene, model);
  const cv::Mat ia = sim::testing::Photo(renderer, state, a, sim::RenderOptions(), 100);
  const cv::Mat ib = sim::testing::Photo(renderer, state, b, sim::RenderOptions(), 101);

  const PhotoFeatureOptions fo;
  const PhotoFeatures fa(ia, "sim_a", fo), fb(ib, "sim_b", fo);
  const PhotoPairResult r = MatchPhotoPair(fa, fb, PhotoPairOptions());
  double sum = 0.0, chi2 = 0.0, sum_precise = 0.0;
  int n = 0, far = 0, precise = 0;
  for (const PhotoTiePoint& t : r.tie_points) {
    const camera::Ray ray = model.ImageToRay(a, t.xa);
    const Eigen::Vector3d d = ray.direction.normalized();
    const double s = state.grid.IntersectRay(ray.origin, d, 500.0);
    Eigen::Vector2d truth;
    if (!std::isfinite(s) || !model.Project(b, ray.origin + s * d, &truth)) continue;
    const Eigen::Vector2d err = t.xb - truth;
    const double e = err.norm();
    sum += e * e;
    chi2 += err.dot(t.covariance.inverse() * err);
    ++n;
    // Windows that LSC itself rates precise (larger sigma below 0.15 px).
    if (t.covariance.eigenvalues().real().maxCoeff() < 0.15 * 0.15) {
      sum_precise += e * e;
      ++precise;
    }
    if (e > 1.0) ++far;
  }
  const double rms = n > 0 ? std::sqrt(sum / n) : 1e9;
  const double rms_precise = precise > 0 ? std::sqrt(sum_precise / precise) : 1e9;
  std::printf(
      "simulated turn: %d tie points (%d with truth), rotation %.1f deg, scale %.3f, error rms "
      "%.3f px, "
      "%d beyond 1 px, mean chi2 %.2f (2 when the covariance is right), %d with sigma < 0.15 px: "
      "rms %.3f px; epipolar rms %.3f px\n",
      r.summary.matched, n, r.summary.rotation_deg, r.summary.scale, rms, far,
      n > 0 ? chi2 / n : 0.0, precise, rms_precise, r.summary.epipolar_rms);
  EXPECT_NEAR(std::abs(r.summary.rotation_deg), kHeading, 3.0);
  EXPECT_NEAR(r.summary.scale, kScale, 0.05);
  EXPECT_GE(n, 300);
  // Measured: 0.303 px (chi2 6.1: LSC's covariance is optimistic by ~1.7 on
  // this texture). The simulator's ground texture is weak (gradient ~ noise):
  // the hexagonal matcher reaches 0.16 px here only with a 19 x 19 window on
  // images low-passed by 1 px (uav_sequence_test.cpp); these are the
  // defaults a user gets for real photos, 11 x 11.
  EXPECT_LT(rms, 0.35);
  EXPECT_LE(far, n / 100);
  EXPECT_LT(chi2 / n, 8.0);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
