// Wind in the tree crowns (SceneSpec::foliage_motion): off, the scene is as
// before (no crown offset, static foliage, identical images); on, every stamp
// has its own crown sway (within the configured bound) and leaf pattern,
// deterministic from seed and stamp, and only pixels near the tree change.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace sim {
namespace {

SceneSpec TreeScene(bool wind) {
  SceneSpec s;
  s.seed = 4;
  s.terrain.extent = Eigen::Vector4d(0, 40, 0, 30);
  s.terrain.grid_spacing = 0.5;
  s.terrain.relief = 6.0;
  s.landslide.centre = Eigen::Vector2d(20, 15);
  s.landslide.length = 5.0;
  s.landslide.width = 4.0;
  s.landslide.velocity0 = 0.0;
  s.scarp.depth = 0.0;
  Obstacle tree;
  tree.kind = Obstacle::Kind::kTree;
  tree.base = Eigen::Vector3d(28, 19, std::numeric_limits<double>::quiet_NaN());
  tree.radius = 1.5;
  tree.height = 5.0;
  Obstacle boulder;
  boulder.base = Eigen::Vector3d(12, 12, std::numeric_limits<double>::quiet_NaN());
  s.obstacles = {tree, boulder};
  s.foliage_motion = wind;
  return s;
}

camera::CameraModel Camera() {
  camera::Sensor sensor{320, 240, 0.02};
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 8.0;
  return camera::CameraModel(sensor, camera::DistortionModel::kBrownAffinity, in);
}

cv::Mat Render(const Scene& scene, double t) {
  const Renderer renderer(scene, Camera());
  const Eigen::Vector3d look(20, 15, scene.AnalyticHeight(20, 15));
  const Eigen::Vector3d pos(20, -10, scene.AnalyticHeight(20, 0) + 10);
  RenderOptions ro;
  return renderer.Render(scene.AtTime(t), LookAt(pos, look, Eigen::Vector3d::UnitZ()), ro).radiance;
}

TEST(Foliage, OffByDefaultAndDeterministicWhenOn) {
  EXPECT_FALSE(SceneSpec().foliage_motion);
  const Scene still(TreeScene(false)), windy(TreeScene(true));
  for (double t : {0.0, 3600.0}) {
    for (const Obstacle& o : still.AtTime(t).obstacles) {
      EXPECT_EQ(o.crown_offset, Eigen::Vector3d::Zero());
      EXPECT_EQ(o.foliage_phase, 0u);
    }
  }
  const Scene::State a = windy.AtTime(100.0), a2 = windy.AtTime(100.0), b = windy.AtTime(100.5);
  const Obstacle &ta = a.obstacles[0], &ta2 = a2.obstacles[0], &tb = b.obstacles[0];
  EXPECT_EQ(ta.crown_offset, ta2.crown_offset);  // same seed and stamp -> same wind
  EXPECT_EQ(ta.foliage_phase, ta2.foliage_phase);
  EXPECT_NE(ta.foliage_phase, tb.foliage_phase);  // another stamp -> another leaf pattern
  EXPECT_GT((ta.crown_offset - tb.crown_offset).norm(), 1e-3);
  for (const Scene::State* s : {&a, &b}) {
    const Obstacle& tree = s->obstacles[0];
    EXPECT_NE(tree.foliage_phase, 0u);
    EXPECT_EQ(tree.crown_offset.z(), 0.0);
    EXPECT_LE(tree.crown_offset.norm(), 0.15 * 1.5 + 1e-12);  // foliage_sway x radius
    EXPECT_GE(tree.crown_offset.norm(), 0.3 * 0.15 * 1.5 - 1e-12);
    EXPECT_EQ(s->obstacles[1].crown_offset, Eigen::Vector3d::Zero());  // boulders do not sway
    EXPECT_EQ(s->obstacles[1].foliage_phase, 0u);
  }
  SceneSpec bad = TreeScene(true);
  bad.foliage_sway = 1.5;
  EXPECT_THROW(Scene{bad}, InvalidArgument);
}

TEST(Foliage, OnlyTheCrownChangesBetweenStamps) {
  const Scene still(TreeScene(false)), windy(TreeScene(true));
  const cv::Mat s0 = Render(still, 0.0), w0 = Render(windy, 0.0), w1 = Render(windy, 3600.0);
  const cv::Mat s0b = Render(still, 0.0);
  EXPECT_EQ(cv::norm(s0, s0b, cv::NORM_INF), 0.0);  // deterministic
  // Pixels that differ between the two windy stamps, and between still and windy.
  int changed = 0, changed_vs_still = 0;
  double max_far = 0.0;
  const int tree_col_min = s0.cols / 2;  // the tree stands east of the axis: right half
  for (int r = 0; r < s0.rows; ++r)
    for (int c = 0; c < s0.cols; ++c) {
      const float d = std::fabs(w0.at<float>(r, c) - w1.at<float>(r, c));
      if (d > 1e-6f) ++changed;
      if (std::fabs(w0.at<float>(r, c) - s0.at<float>(r, c)) > 1e-6f) ++changed_vs_still;
      if (c < tree_col_min) max_far = std::max(max_far, double(d));
    }
  std::printf("foliage: %d pixels change between stamps, %d differ from the still scene\n", changed,
              changed_vs_still);
  EXPECT_GT(changed, 500);  // the crown (~40 px across here: measured 2049 pixels) changes
  EXPECT_LT(changed, s0.total() / 20);  // ... and nothing else
  EXPECT_EQ(max_far, 0.0);              // the left half (boulder, ground) is identical
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
