// PruneScene: weak images, orphaned points and empty cameras leave the
// scene; what stays is re-indexed consistently.
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/initialization.h"

namespace slope_monitor {
namespace adjustment {
namespace {

Scene MakeScene() {
  Scene s;
  s.cameras.resize(2);
  s.cameras[0].name = "fixed_cam_1";
  s.cameras[1].name = "uav";
  for (int i = 0; i < 3; ++i) {
    Image im;
    im.name = i == 0 ? "fixed_cam_1@1" : "uav@" + std::to_string(i);
    im.camera = i == 0 ? 0 : 1;
    s.images.push_back(im);
  }
  for (int j = 0; j < 8; ++j) {
    ObjectPoint p;
    p.id = "tag36h11/" + std::to_string(j);
    s.points.push_back(p);
  }
  auto observe = [&](int i, int j) {
    Observation o;
    o.image = i;
    o.point = j;
    o.pixel = Eigen::Vector2d(10.0 * j, 5.0 * i);
    s.observations.push_back(o);
  };
  for (int j = 0; j < 6; ++j) observe(0, j);  // fixed camera: 6 points
  for (int j : {4, 5, 6}) observe(1, j);      // uav@1: 3 points (too few)
  for (int j : {2, 3, 4, 7}) observe(2, j);   // uav@2: 4 points, but point 7 is unknown
  s.points[7].position_known = false;
  return s;
}

TEST(PruneScene, DropsWeakImagesOrphansAndCascades) {
  const Scene in = MakeScene();
  PruneReport report;
  const Scene out = PruneScene(in, 4, &report);
  // uav@1 has 3 observations; uav@2 loses point 7 (unknown) and then has 3.
  ASSERT_EQ(out.images.size(), 1u);
  EXPECT_EQ(out.images[0].name, "fixed_cam_1@1");
  ASSERT_EQ(out.cameras.size(), 1u);
  EXPECT_EQ(out.cameras[0].name, "fixed_cam_1");
  EXPECT_EQ(out.images[0].camera, 0);
  // Points 0..5 stay (seen by the fixed camera); 6 only by uav@1, 7 unknown.
  ASSERT_EQ(out.points.size(), 6u);
  EXPECT_EQ(out.FindPoint("tag36h11/6"), -1);
  EXPECT_EQ(out.FindPoint("tag36h11/7"), -1);
  EXPECT_EQ(out.observations.size(), 6u);
  for (const Observation& o : out.observations) {
    EXPECT_EQ(o.image, 0);
    // Pixels travel with their point: x = 10 * original index.
    EXPECT_DOUBLE_EQ(o.pixel.x(), 10.0 * in.FindPoint(out.points[o.point].id));
  }
  EXPECT_EQ(report.dropped_images.size(), 2u);
  EXPECT_EQ(report.dropped_cameras.size(), 1u);
  EXPECT_EQ(report.dropped_points.size(), 2u);
  EXPECT_NE(report.Summary().find("uav@1"), std::string::npos) << report.Summary();
  EXPECT_NO_THROW(out.CheckIndices());
}

TEST(PruneScene, KeepsEverythingWhenAllImagesAreStrong) {
  Scene in = MakeScene();
  in.points[7].position_known = true;
  const Scene out = PruneScene(in, 3, nullptr);
  EXPECT_EQ(out.images.size(), 3u);
  EXPECT_EQ(out.points.size(), 8u);
  EXPECT_EQ(out.observations.size(), in.observations.size());
  EXPECT_EQ(out.cameras.size(), 2u);
}

TEST(PruneScene, UnorientedImageIsDropped) {
  Scene in = MakeScene();
  in.points[7].position_known = true;
  in.images[2].exterior_known = false;
  PruneReport report;
  const Scene out = PruneScene(in, 3, &report);
  EXPECT_EQ(out.images.size(), 2u);
  EXPECT_EQ(out.FindImage("uav@2"), -1);
  EXPECT_EQ(out.FindPoint("tag36h11/7"), -1);  // only uav@2 saw it
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
