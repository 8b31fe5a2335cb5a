// The hexagonal matcher on the package's simulator, against its geometric
// truth (small scene, 640 x 480 images rendered in-process):
//  * natural-feature tracking of one fixed camera from the reference epoch to
//    a later one with the displacement prior (stable ground gives the global
//    shift, the landslide is searched wider): image displacement of every
//    match against the projection of the true 3-D displacement with the true
//    camera; matches on the occluding obstacles (tree, boulder) counted;
//  * tie points between two fixed cameras of the same epoch with the
//    epipolar prior from their orientations, against the projection of the
//    surface point seen by camera a into camera b.
// Links slope_monitor_core_sim (CMakeLists.txt: this test only).
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"

#include "../sim/test_scene.h"  // the small simulated slope (header only)

namespace slope_monitor {
namespace matching {
namespace {

constexpr double kEpoch1 = 3600.0;  // [s] the later epoch; the reference epoch is t = 0

// A 40 m x 30 m textured slope, a landslide body in the middle moving
// 0.5 m per hour towards the south (down the slope, towards the cameras),
// a boulder and a tree (unmatchable), no targets, no scarp.
sim::SceneSpec TrackingSite(bool foliage_motion = false, unsigned seed = 5) {
  sim::SceneSpec s = sim::testing::SmallSlope(seed);
  s.foliage_motion = foliage_motion;
  s.texture.coarsest_wavelength = 8.0;
  sim::testing::SetSouthwardBody(&s, Eigen::Vector2d(20, 16), 7.0, 5.0, 0.2, 0.5);
  s.landslide.taper = 0.3;
  s.scarp.depth = 0.0;
  s.obstacles = {sim::testing::Boulder(12, 12, 0.9, 0.5), sim::testing::Tree(28, 19)};
  return s;
}

camera::CameraModel Camera() {
  return sim::testing::SmallCamera(640, 480, 8.0, 0.02, -0.01, -1.0e-3);
}

// A fixed camera on the opposite side, x_offset [m] east of the axis.
camera::ExteriorOrientation FixedPose(const sim::Scene& scene, double x_offset) {
  const Eigen::Vector3d look(20, 15, scene.AnalyticHeight(20, 15));
  const Eigen::Vector3d pos(20 + x_offset, -10, scene.AnalyticHeight(20, 0) + 10);
  return sim::LookAt(pos, look, Eigen::Vector3d::UnitZ());
}

cv::Mat Shoot(const sim::Renderer& renderer, const sim::Scene::State& state,
              const camera::ExteriorOrientation& pose, int epoch, unsigned seed) {
  // (With SceneSpec::foliage_motion the state's crowns also sway and change
  // their leaf pattern with the stamp.)
  sim::RenderOptions ro;
  ro.epoch_salt = epoch;  // the tree's foliage changes (wind)
  return sim::testing::Photo(renderer, state, pose, ro, seed);
}

// What the pixel of camera (model, pose) sees in `state`: the ground, a tree
// crown (its foliage moves in the wind), a rigid obstacle (trunk, boulder) or
// nothing; *x (if given) the hit point in site, unset for the sky.
enum class Seen { kGround, kCrown, kRigid, kSky };
Seen WhatIsSeen(const sim::Scene::State& state, const camera::CameraModel& model,
                const camera::ExteriorOrientation& pose, const Eigen::Vector2d& pixel,
                Eigen::Vector3d* x = nullptr) {
  const camera::Ray ray = model.ImageToRay(pose, pixel);
  const Eigen::Vector3d d = ray.direction.normalized();
  const double t_ground = state.grid.IntersectRay(ray.origin, d, 500.0);
  double t_obstacle = std::numeric_limits<double>::infinity();
  Seen what = Seen::kSky;
  for (const sim::Obstacle& o : state.obstacles) {
    Eigen::Vector3d n;
    const double t = sim::IntersectObstacle(o, ray.origin, d, &n);
    if (t > 0 && t < t_obstacle) {
      t_obstacle = t;
      // The trunk's normal is horizontal; the crown ellipsoid's is not (but at its equator).
      const bool trunk = n.z() == 0.0 && (ray.origin + t * d - o.base).z() < 0.4 * o.height;
      what = o.kind == sim::Obstacle::Kind::kTree && !trunk ? Seen::kCrown : Seen::kRigid;
    }
  }
  if (!std::isfinite(t_ground) && !std::isfinite(t_obstacle)) return Seen::kSky;
  if (x != nullptr) *x = ray.origin + std::min(t_ground, t_obstacle) * d;
  if (std::isfinite(t_ground) && t_ground < t_obstacle) return Seen::kGround;
  return what;
}

// True when the pixel sees the ground; *x the hit point in site.
bool SeesGround(const sim::Scene::State& state, const camera::CameraModel& model,
                const camera::ExteriorOrientation& pose, const Eigen::Vector2d& pixel,
                Eigen::Vector3d* x) {
  return WhatIsSeen(state, model, pose, pixel, x) == Seen::kGround;
}

// Pixels within `margin` px of an obstacle's image (the LSC window reaches
// that far): matches there are on or next to an unmatchable object.
bool NearObstacle(const sim::Scene::State& state, const camera::CameraModel& model,
                  const camera::ExteriorOrientation& pose, const Eigen::Vector2d& pixel,
                  double margin) {
  Eigen::Vector3d x;
  for (int dy = -1; dy <= 1; ++dy)
    for (int dx = -1; dx <= 1; ++dx) {
      if (!SeesGround(state, model, pose, pixel + margin * Eigen::Vector2d(dx, dy), &x))
        return true;
    }
  return false;
}

// Matcher settings for the simulator's ground: its texture is weak at pixel
// scale (Sobel gradient RMS 2.4 DN/px against 2.7 DN noise at mid grey), so
// LSC runs on a 15 x 15 window of images low-passed by 1 px (measured on
// this scene: stable-ground error RMS 0.37 px with the defaults, 0.27 px
// with these).
HexMatcherOptions TrackingSimOptions() {
  HexMatcherOptions o;
  o.lsc.half_window = 7;
  o.lsc_prefilter_sigma = 1.0;
  return o;
}

// One fixed camera (FixedPose(scene, 0)) photographing the scene at the
// reference epoch (t = 0, noise seed 1) and at kEpoch1 (noise seed 2).
struct FixedCameraRun {
  explicit FixedCameraRun(const sim::SceneSpec& spec)
      : scene(spec),
        model(Camera()),
        pose(FixedPose(scene, 0.0)),
        s0(scene.AtTime(0.0)),
        s1(scene.AtTime(kEpoch1)) {
    const sim::Renderer renderer(scene, model);
    img0 = Shoot(renderer, s0, pose, 0, 1);
    img1 = Shoot(renderer, s1, pose, 1, 2);
  }
  const sim::LandslideModel& Slide() const { return scene.spec().landslide; }

  // The tracking prior: the camera is fixed, so stable ground does not move
  // (6 px, global shift estimated); the operator's outline of the unstable
  // area (the body plus a 3 m margin) is searched 20 px wide. The prior
  // refers to this run: it must outlive the match.
  MatchPrior Prior() const {
    MatchPrior prior;
    prior.radius = 6.0;
    prior.moving_radius = 20.0;
    prior.estimate_global_shift = true;
    prior.moving = [this](const Eigen::Vector2d& px) {
      Eigen::Vector3d x;
      if (!SeesGround(s0, model, pose, px, &x)) return false;
      const Eigen::Vector2d rel = x.head<2>() - Slide().centre;
      return std::hypot(rel.x() / (Slide().length + 3), rel.y() / (Slide().width + 3)) < 1.0;
    };
    return prior;
  }

  const sim::Scene scene;
  const camera::CameraModel model;
  const camera::ExteriorOrientation pose;
  const sim::Scene::State s0, s1;
  cv::Mat img0, img1;
};

TEST(SimTracking, NaturalFeaturesAcrossEpochsAgainstTruth) {
  const FixedCameraRun run(TrackingSite());
  const camera::CameraModel& model = run.model;
  const camera::ExteriorOrientation& pose = run.pose;
  const sim::Scene::State& s0 = run.s0;
  const sim::LandslideModel& slide = run.Slide();

  const HexMatcher matcher(TrackingSimOptions());
  const HexMatchResult r = matcher.Match(run.img0, run.img1, run.Prior());

  int ground = 0, correct = 0, moving = 0, moving_correct = 0, on_obstacle = 0,
      on_obstacle_wrong = 0;
  double sum2 = 0, sum2_moving = 0, max_disp = 0;
  for (const HexMatch& m : r.matches) {
    Eigen::Vector3d x_ref;
    if (NearObstacle(s0, model, pose, m.xa, 6.0)) {
      ++on_obstacle;
      // Truth of an obstacle pixel: it does not move (the tree's crown changes).
      if ((m.xb - m.xa).norm() > 1.0) ++on_obstacle_wrong;
      continue;
    }
    if (!SeesGround(s0, model, pose, m.xa, &x_ref)) continue;
    const Eigen::Vector3d x_now = x_ref + slide.DisplacementAt(x_ref, kEpoch1);
    Eigen::Vector2d xb_true;
    ASSERT_TRUE(model.Project(pose, x_now, &xb_true));
    const double e = (m.xb - xb_true).norm();
    ++ground;
    const bool mv = slide.Weight(x_ref.head<2>()) > 0.05;
    if (mv) {
      ++moving;
      max_disp = std::max(max_disp, (xb_true - m.xa).norm());
    }
    if (e <= 1.0) {
      ++correct;
      sum2 += e * e;
      if (mv) {
        ++moving_correct;
        sum2_moving += e * e;
      }
    }
  }
  const double rms = std::sqrt(sum2 / std::max(1, correct));
  const double rms_moving = std::sqrt(sum2_moving / std::max(1, moving_correct));
  std::printf("sim tracking: %d candidates, %d matches, %.2f s; global shift (%.2f, %.2f) px\n",
              r.summary.candidates, r.summary.matched, r.summary.seconds,
              r.summary.global_shift.x(), r.summary.global_shift.y());
  std::printf("  ground: %d matches, %d within 1 px of truth (%.1f %%), RMS %.3f px\n", ground,
              correct, 100.0 * correct / std::max(1, ground), rms);
  std::printf(
      "  moving body: %d matches (true image displacement up to %.1f px), %d within 1 px, RMS %.3f "
      "px\n",
      moving, max_disp, moving_correct, rms_moving);
  std::printf("  on/next to obstacles: %d matches, %d of them moved > 1 px\n", on_obstacle,
              on_obstacle_wrong);
  for (const auto& kv : r.summary.rejects)
    std::printf("  reject %s: %d\n", kv.first.c_str(), kv.second);

  EXPECT_LT(r.summary.global_shift.norm(), 0.2);  // fixed camera: the stable ground does not move
  EXPECT_GT(ground, 100);
  EXPECT_GT(moving, 20);
  EXPECT_GT(max_disp, 4.0);  // the body really moves several pixels
  EXPECT_GE(correct, 0.95 * ground);
  EXPECT_GE(moving_correct, 0.9 * moving);
  // Measured 0.27 px (ground) and 0.31 px (moving body): the limit of the
  // simulator's weak ground texture, see TrackingSimOptions().
  EXPECT_LT(rms, 0.35);
  EXPECT_LT(rms_moving, 0.4);
  // The obstacles do not move; without wind (foliage_motion off) the
  // tree's crown texture changes a little between epochs: matches on/next to
  // them (measured 30) are geometrically right except at most one (measured:
  // one at 1.08 px). With wind: OccludingFoliageIsNotReportedWithNormalQuality.
  EXPECT_LE(on_obstacle_wrong, 1);
}

TEST(SimTracking, TiePointsBetweenTwoFixedCamerasAgainstTruth) {
  const sim::Scene scene(TrackingSite());
  const camera::CameraModel model = Camera();
  const sim::Renderer renderer(scene, model);
  const camera::ExteriorOrientation pose_a = FixedPose(scene, -2.0), pose_b = FixedPose(scene, 2.0);
  const sim::Scene::State s0 = scene.AtTime(0.0);
  const cv::Mat img_a = Shoot(renderer, s0, pose_a, 0, 3),
                img_b = Shoot(renderer, s0, pose_b, 0, 4);

  const HexMatcher matcher(TrackingSimOptions());
  MatchPrior prior;
  prior.has_epipolar = true;
  prior.fundamental = FundamentalFromOrientation(model, pose_a, model, pose_b);
  prior.epipolar_band = 3.0;  // distortion is left to the band
  prior.radius = 80.0;        // along the epipolar line: the parallax range of the slope
  const HexMatchResult r = matcher.Match(img_a, img_b, prior);

  int checked = 0, correct = 0;
  double sum2 = 0;
  for (const HexMatch& m : r.matches) {
    Eigen::Vector3d x, xb_hit;
    if (!SeesGround(s0, model, pose_a, m.xa, &x)) continue;
    Eigen::Vector2d xb_true;
    ASSERT_TRUE(model.Project(pose_b, x, &xb_true));
    // Visible from b too (not hidden behind the relief or an obstacle).
    if (!SeesGround(s0, model, pose_b, xb_true, &xb_hit) || (xb_hit - x).norm() > 0.05) continue;
    ++checked;
    const double e = (m.xb - xb_true).norm();
    if (e <= 1.0) {
      ++correct;
      sum2 += e * e;
    }
  }
  const double rms = std::sqrt(sum2 / std::max(1, correct));
  std::printf(
      "sim tie points (4 m baseline): %d candidates, %d matches, %d checked against truth, %d "
      "within 1 px "
      "(%.1f %%), RMS %.3f px, %.2f s\n",
      r.summary.candidates, r.summary.matched, checked, correct,
      100.0 * correct / std::max(1, checked), rms, r.summary.seconds);
  for (const auto& kv : r.summary.rejects)
    std::printf("  reject %s: %d\n", kv.first.c_str(), kv.second);
  EXPECT_GT(checked, 100);
  EXPECT_GE(correct, 0.95 * checked);
  EXPECT_LT(rms, 0.4);  // measured 0.31 px (weak simulated texture, see TrackingSimOptions())
}

// Occluding objects with wind in the tree crown (SceneSpec::foliage_motion:
// the crown sways by up to 0.22 m ~ 6 px and its leaf pattern is new at each
// stamp). Truth of "unmatchable": the pixel xa sees an obstacle in the
// reference epoch, or the ground point it sees is hidden behind an obstacle
// in the later epoch (ray tests against the scene state at each stamp).
// No match on an unmatchable pixel may be reported with normal quality; the
// ground away from the obstacles keeps >= 95 % of the matches of the run
// without foliage motion and without quality control, at the same RMS.
struct TrackingStats {
  int matches = 0, low_quality = 0;
  int ground = 0, ground_correct = 0;  // normal quality, away from the obstacles
  double ground_rms = 0.0;
  int crown = 0, crown_normal = 0;  // a crown pixel in either epoch (or ground hidden by it)
  int rigid = 0, rigid_normal = 0, rigid_normal_wrong = 0;  // trunk or boulder
  int near = 0, near_normal = 0, near_normal_wrong = 0;     // ground, window reaches an obstacle
  int ground_low_quality = 0;
};

// Counts a match on/at an obstacle (error e [px] against truth): all, those
// of normal quality, and those of normal quality more than 1 px off.
void CountOnObstacle(const HexMatch& m, double e, int* all, int* normal, int* normal_wrong) {
  ++*all;
  if (m.IsLowQuality()) return;
  ++*normal;
  if (e > 1.0) ++*normal_wrong;
}

// The operator's outline of the obstacles in the image: pixels whose ray
// hits an obstacle grown by 0.25 m (crown / boulder radius; a margin like
// the one an operator leaves when drawing around a tree or a boulder).
bool InObstacleOutline(const sim::Scene::State& state, const camera::CameraModel& model,
                       const camera::ExteriorOrientation& pose, const Eigen::Vector2d& pixel) {
  const camera::Ray ray = model.ImageToRay(pose, pixel);
  const Eigen::Vector3d d = ray.direction.normalized();
  for (sim::Obstacle o : state.obstacles) {
    o.radius += 0.25;
    if (o.kind == sim::Obstacle::Kind::kTree) o.height += 0.25;
    if (sim::IntersectObstacle(o, ray.origin, d, nullptr) > 0) return true;
  }
  return false;
}

TrackingStats TrackWith(bool foliage_motion, bool quality_control, unsigned seed,
                        bool outline = false) {
  const FixedCameraRun run(TrackingSite(foliage_motion, seed));
  const camera::CameraModel& model = run.model;
  const camera::ExteriorOrientation& pose = run.pose;
  const sim::Scene::State &s0 = run.s0, &s1 = run.s1;
  const sim::LandslideModel& slide = run.Slide();
  HexMatcherOptions options = TrackingSimOptions();
  options.quality.enabled = quality_control;
  const HexMatcher matcher(options);
  MatchPrior prior = run.Prior();
  if (outline)
    prior.excluded = [&](const Eigen::Vector2d& px) {
      return InObstacleOutline(s0, model, pose, px);
    };
  const HexMatchResult r = matcher.Match(run.img0, run.img1, prior);
  TrackingStats st;
  st.matches = r.summary.matched;
  st.low_quality = r.summary.low_quality;
  double sum2 = 0;
  const int h = options.lsc.half_window;
  for (const HexMatch& m : r.matches) {
    Eigen::Vector3d x_ref, x_hit;
    const Seen seen0 = WhatIsSeen(s0, model, pose, m.xa);
    Eigen::Vector2d xb_true = m.xa;  // the obstacles here stand off the body: they do not move
    bool crown = seen0 == Seen::kCrown, rigid = seen0 == Seen::kRigid;
    if (seen0 == Seen::kGround) {
      SeesGround(s0, model, pose, m.xa, &x_ref);
      const Eigen::Vector3d x_now = x_ref + slide.DisplacementAt(x_ref, kEpoch1);
      EXPECT_TRUE(model.Project(pose, x_now, &xb_true));
      // Hidden in the later epoch (behind the swaying crown)?
      const Seen seen1 = WhatIsSeen(s1, model, pose, xb_true);
      crown = seen1 == Seen::kCrown;
      rigid = seen1 == Seen::kRigid;
    } else if (WhatIsSeen(s1, model, pose, m.xa) == Seen::kCrown) {
      crown = true;
    }
    const bool near = NearObstacle(s0, model, pose, m.xa, h + 1.0) ||
                      NearObstacle(s1, model, pose, xb_true, h + 1.0);
    const double e = (m.xb - xb_true).norm();
    if (crown) {
      ++st.crown;
      if (!m.IsLowQuality()) {
        ++st.crown_normal;
        if (quality_control)
          std::printf(
              "  normal-quality match on a crown pixel: xa (%.1f, %.1f) xb (%.1f, %.1f) corr %.3f "
              "sigma0 %.2f two-way %.3f\n",
              m.xa.x(), m.xa.y(), m.xb.x(), m.xb.y(), m.correlation, m.sigma0, m.two_way_error);
      }
      continue;
    }
    if (rigid) {
      CountOnObstacle(m, e, &st.rigid, &st.rigid_normal, &st.rigid_normal_wrong);
      continue;
    }
    if (near) {
      CountOnObstacle(m, e, &st.near, &st.near_normal, &st.near_normal_wrong);
      continue;
    }
    if (m.IsLowQuality()) {
      ++st.ground_low_quality;
      continue;
    }
    ++st.ground;
    if (e <= 1.0) {
      ++st.ground_correct;
      sum2 += e * e;
    }
  }
  st.ground_rms = std::sqrt(sum2 / std::max(1, st.ground_correct));
  std::printf("scene seed %u, foliage motion %s, quality control %s%s: %d matches (%d low quality",
              seed, foliage_motion ? "on" : "off", quality_control ? "on" : "off",
              outline ? " + obstacle outline" : "", st.matches, st.low_quality);
  for (const auto& kv : r.summary.flags) std::printf(", %s %d", kv.first.c_str(), kv.second);
  std::printf(")\n  crown pixels: %d matches, %d of normal quality\n", st.crown, st.crown_normal);
  std::printf("  trunk/boulder pixels: %d matches, %d of normal quality, %d of those > 1 px off\n",
              st.rigid, st.rigid_normal, st.rigid_normal_wrong);
  std::printf(
      "  window reaching an obstacle: %d matches, %d of normal quality, %d of those > 1 px off\n",
      st.near, st.near_normal, st.near_normal_wrong);
  std::printf("  ground: %d normal quality, %d within 1 px, RMS %.3f px; %d flagged low quality\n",
              st.ground, st.ground_correct, st.ground_rms, st.ground_low_quality);
  return st;
}

TEST(SimTracking, OccludingFoliageIsNotReportedWithNormalQuality) {
  for (const unsigned seed : {5u, 11u}) {  // two scenes (texture, foliage pattern, sway)
    SCOPED_TRACE(seed);
    const TrackingStats base = TrackWith(false, false, seed);  // no wind, no quality control
    const TrackingStats wind = TrackWith(true, true, seed);
    EXPECT_GT(wind.crown + wind.rigid + wind.near,
              5);  // the matcher does find candidates on/at the obstacles
    EXPECT_EQ(wind.crown_normal, 0);
    // Trunks and boulders are rigid and static: matches on them are reported
    // and must be geometrically right (see doc/nodes/hex_matcher.md).
    EXPECT_EQ(wind.rigid_normal_wrong, 0);
    EXPECT_EQ(wind.near_normal_wrong, 0);
    EXPECT_GE(wind.ground_correct, 0.95 * base.ground_correct);
    EXPECT_LT(std::fabs(wind.ground_rms - base.ground_rms), 0.02);
    // With the operator's outline of the obstacles (MatchPrior::excluded)
    // the rigid ones are marked too: nothing on any obstacle has normal
    // quality, and the ground keeps its matches.
    const TrackingStats outlined = TrackWith(true, true, seed, true);
    EXPECT_GT(outlined.crown + outlined.rigid, 5);
    EXPECT_EQ(outlined.crown_normal, 0);
    EXPECT_EQ(outlined.rigid_normal, 0);
    EXPECT_GE(outlined.ground_correct, 0.95 * base.ground_correct);
    EXPECT_LT(std::fabs(outlined.ground_rms - base.ground_rms), 0.02);
  }
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
