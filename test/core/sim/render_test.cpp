// Rendering against geometric truth: target centroids, visibility, displaced
// targets (small scenes, noise-free radiance).
#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/survey.h"
#include "test_scene.h"  // the small simulated slope (header only)

namespace slope_monitor {
namespace sim {
namespace {

// A 40 m x 30 m slope, untextured ground (so a centroid window sees only the
// target), circles and tags; moving body in the middle.
SceneSpec SmallScene() {
  SceneSpec s = testing::SmallSlope(3);
  s.texture.contrast = 0.0;
  s.texture.vegetation_fraction = 0.0;
  s.texture.rock_fraction = 0.0;
  testing::SetSouthwardBody(&s, Eigen::Vector2d(20, 15), 8.0, 6.0, 0.2, 1.0);  // 1 m per hour
  s.scarp.depth = 0.0;
  const std::vector<Eigen::Vector2d> circles = {{20, 15}, {17, 12}, {23, 18},
                                                {14, 20}, {26, 10}, {20, 21}};
  for (size_t k = 0; k < circles.size(); ++k) {
    TargetPlacement p;
    p.family = "circle";
    p.id = static_cast<int>(k);
    p.size = 0.4;
    p.xy = circles[k];
    p.role = s.landslide.Weight(p.xy) > 0 ? io::TargetRole::kMonitoring : io::TargetRole::kControl;
    s.targets.push_back(p);
  }
  TargetPlacement tag;
  tag.family = "tag36h11";
  tag.id = 5;
  tag.size = 0.6;
  tag.xy = Eigen::Vector2d(24, 14);
  s.targets.push_back(tag);
  return s;
}

camera::CameraModel SmallCamera(double c_mm = 8.0) {
  return testing::SmallCamera(320, 240, c_mm, 0.012, -0.008, -1.5e-3, 2e-5, 1e-4);
}

// Intensity centroid of a circle target: weights = radiance - ring radiance
// inside a circular window of 1.5 disc radii around `guess`.
Eigen::Vector2d Centroid(const cv::Mat& img, const Eigen::Vector2d& guess, double radius_px,
                         double ring) {
  double sw = 0, sx = 0, sy = 0;
  const double win = 1.5 * radius_px;
  for (int r = static_cast<int>(std::floor(guess.y() - win));
       r <= static_cast<int>(std::ceil(guess.y() + win)); ++r) {
    for (int c = static_cast<int>(std::floor(guess.x() - win));
         c <= static_cast<int>(std::ceil(guess.x() + win)); ++c) {
      if (std::hypot(c - guess.x(), r - guess.y()) > win) continue;
      const double w = std::max(0.0, img.at<float>(r, c) - ring);
      sw += w;
      sx += w * c;
      sy += w * r;
    }
  }
  return Eigen::Vector2d(sx / sw, sy / sw);
}

// Shoelace sums of a closed polygon: returns twice its signed area; adds to
// *cx, *cy the first moments times 6 (centroid = (cx, cy) / (3 * returned)).
double TwiceSignedArea(const std::vector<Eigen::Vector2d>& poly, double* cx, double* cy) {
  double area = 0;
  for (size_t k = 0; k < poly.size(); ++k) {
    const Eigen::Vector2d& a = poly[k];
    const Eigen::Vector2d& b = poly[(k + 1) % poly.size()];
    const double cr = a.x() * b.y() - b.x() * a.y();
    area += cr;
    *cx += (a.x() + b.x()) * cr;
    *cy += (a.y() + b.y()) * cr;
  }
  return area;
}

// Area centroid of the projected disc (polygon of many projected rim points).
Eigen::Vector2d ProjectedDiscCentroid(const Plate& p, const camera::CameraModel& m,
                                      const camera::ExteriorOrientation& pose) {
  const int n = 2000;
  std::vector<Eigen::Vector2d> poly;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * k / n;
    Eigen::Vector2d px;
    m.Project(pose, p.centre + p.disc_radius * (std::cos(a) * p.right + std::sin(a) * p.up), &px);
    poly.push_back(px);
  }
  double cx = 0, cy = 0;
  const double area = TwiceSignedArea(poly, &cx, &cy);
  return Eigen::Vector2d(cx / (3 * area), cy / (3 * area));
}

double RingRadiance(const Scene& scene, const Plate& p) {
  const Lighting& l = scene.spec().lighting;
  return 0.05 * (l.ambient + (1 - l.ambient) * std::max(0.0, p.normal.dot(l.sun.normalized())));
}

double ProjectedArea(const Plate& p, const camera::CameraModel& m,
                     const camera::ExteriorOrientation& pose) {
  const std::vector<Eigen::Vector3d> outline = p.Outline(512);
  std::vector<Eigen::Vector2d> px(outline.size());
  for (size_t k = 0; k < outline.size(); ++k) m.Project(pose, outline[k], &px[k]);
  double cx = 0, cy = 0;
  return std::abs(0.5 * TwiceSignedArea(px, &cx, &cy));
}

camera::ExteriorOrientation NadirOver(const Scene& scene, double x, double y, double agl) {
  return testing::NadirFrom(Eigen::Vector3d(x, y, scene.AnalyticHeight(x, y) + agl));
}

TEST(RenderTest, CircleCentroidsAgreeWithProjectedCentres) {
  const Scene scene(SmallScene());
  const camera::CameraModel model = SmallCamera();
  const Renderer renderer(scene, model);
  RenderOptions ro;
  ro.target_supersampling = 16;
  // Nadir and an oblique view (30 deg from the south).
  std::vector<camera::ExteriorOrientation> poses = {NadirOver(scene, 20.3, 15.2, 22.0)};
  {
    const Eigen::Vector3d look(20, 15, scene.AnalyticHeight(20, 15));
    const Eigen::Vector3d pos = look + 24.0 * Eigen::Vector3d(0.1, -std::sin(0.4), std::cos(0.4));
    poses.push_back(LookAt(pos, look, Eigen::Vector3d::UnitZ()));
  }
  const Scene::State state = scene.AtTime(0.0);
  int checked = 0;
  double worst_centre = 0.0, worst_area = 0.0;
  for (const auto& pose : poses) {
    const RenderResult rr = renderer.Render(state, pose, ro);
    for (int k : VisiblePlates(state, model, pose, 4.0)) {
      const Plate& p = state.plates[k];
      if (p.is_tag) continue;
      Eigen::Vector2d centre_px;
      ASSERT_TRUE(model.Project(pose, p.centre, &centre_px));
      const double depth = (p.centre - pose.position).norm();
      const double r_px =
          model.principal_distance() / model.sensor().pixel_size * p.disc_radius / depth;
      const Eigen::Vector2d got = Centroid(rr.radiance, centre_px, r_px, RingRadiance(scene, p));
      const Eigen::Vector2d area_centroid = ProjectedDiscCentroid(p, model, pose);
      worst_centre = std::max(worst_centre, (got - centre_px).norm());
      worst_area = std::max(worst_area, (got - area_centroid).norm());
      EXPECT_LT((got - centre_px).norm(), 0.02)
          << "target " << k << " at " << centre_px.transpose();
      EXPECT_LT((got - area_centroid).norm(), 0.01) << "target " << k;
      ++checked;
    }
  }
  std::printf(
      "centroid vs projected centre: worst %.4f px; vs projected disc area centroid: worst %.4f px "
      "(%d)\n",
      worst_centre, worst_area, checked);
  EXPECT_GE(checked, 4);
}

TEST(RenderTest, VisibleTargetsMatchTheGeometricCount) {
  SceneSpec spec = SmallScene();
  // A boulder in front of target 3 (seen from the south-west) and a tree.
  spec.obstacles.push_back(testing::Boulder(14.0, 18.6, 0.7, 0.6));
  const Scene scene(spec);
  const camera::CameraModel model = SmallCamera(5.0);
  const Renderer renderer(scene, model);
  RenderOptions ro;
  ro.target_supersampling = 6;
  const Scene::State state = scene.AtTime(0.0);
  std::vector<camera::ExteriorOrientation> poses = {NadirOver(scene, 20, 15, 25.0),
                                                    NadirOver(scene, 31.5, 14, 20.0)};
  {
    const Eigen::Vector3d look(18, 16, scene.AnalyticHeight(18, 16));
    poses.push_back(LookAt(look + Eigen::Vector3d(-3, -18, 5), look, Eigen::Vector3d::UnitZ()));
  }
  int total_visible = 0, total_hidden = 0;
  for (size_t i = 0; i < poses.size(); ++i) {
    const RenderResult rr = renderer.Render(state, poses[i], ro);
    const std::vector<int> geometric = VisiblePlates(state, model, poses[i], 0.5);
    int rendered = 0;
    for (size_t k = 0; k < state.plates.size(); ++k) {
      const double area = ProjectedArea(state.plates[k], model, poses[i]);
      const bool seen_whole = rr.target_coverage[k] >= 0.99 * area;
      rendered += seen_whole ? 1 : 0;
      const bool listed =
          std::find(geometric.begin(), geometric.end(), static_cast<int>(k)) != geometric.end();
      EXPECT_EQ(seen_whole, listed) << "pose " << i << " plate " << k << " coverage "
                                    << rr.target_coverage[k] << " of " << area << " px";
    }
    EXPECT_EQ(rendered, static_cast<int>(geometric.size())) << "pose " << i;
    total_visible += rendered;
    total_hidden += static_cast<int>(state.plates.size()) - rendered;
  }
  // The scene must exercise both outcomes.
  EXPECT_GE(total_visible, 5);
  EXPECT_GE(total_hidden, 3);
}

TEST(RenderTest, DisplacedTargetIsWhereTheTruthSays) {
  const Scene scene(SmallScene());
  const camera::CameraModel model = SmallCamera();
  const Renderer renderer(scene, model);
  RenderOptions ro;
  ro.target_supersampling = 16;
  const camera::ExteriorOrientation pose = NadirOver(scene, 20.0, 14.0, 22.0);
  const LandslideModel& field = scene.spec().landslide;
  const int target = 0;  // circle at the body centre
  const Eigen::Vector3d x_ref = scene.targets()[target].positions[0];
  Eigen::Vector2d first;
  for (double t : {0.0, 1800.0, 3600.0}) {
    const Scene::State state = scene.AtTime(t);
    const Plate& p = state.plates[target];
    const Eigen::Vector3d truth = x_ref + field.DisplacementAt(x_ref, t);
    EXPECT_LT((p.centre - truth).norm(), 1e-12);
    Eigen::Vector2d proj;
    ASSERT_TRUE(model.Project(pose, truth, &proj));
    const RenderResult rr = renderer.Render(state, pose, ro);
    const double r_px = model.principal_distance() / model.sensor().pixel_size * p.disc_radius /
                        (truth - pose.position).norm();
    const Eigen::Vector2d got = Centroid(rr.radiance, proj, r_px, RingRadiance(scene, p));
    EXPECT_LT((got - proj).norm(), 0.02) << "t = " << t;
    if (t == 0.0) first = got;
  }
  // One hour at 1 m/h must have moved it by many pixels (south = down the image).
  const Eigen::Vector3d x1 = x_ref + field.DisplacementAt(x_ref, 3600.0);
  Eigen::Vector2d p0, p1;
  model.Project(pose, x_ref, &p0);
  model.Project(pose, x1, &p1);
  EXPECT_GT((p1 - p0).norm(), 20.0);
  EXPECT_GT(p1.y() - first.y(), 20.0);
}

TEST(RenderTest, TagPatternComesFromLibapriltag) {
  const Scene scene(SmallScene());
  const Scene::State state = scene.AtTime(0.0);
  const Plate& tag = state.plates.back();
  ASSERT_TRUE(tag.is_tag);
  // tag36h11: 10 x 10 cells, white outer ring, black border ring (libapriltag 3.3 layout).
  ASSERT_EQ(tag.cells, 10);
  for (int i = 0; i < 10; ++i) {
    EXPECT_GT(tag.pattern[i], 127);           // top row white
    EXPECT_GT(tag.pattern[90 + i], 127);      // bottom row white
    EXPECT_GT(tag.pattern[i * 10], 127);      // left column white
    EXPECT_GT(tag.pattern[i * 10 + 9], 127);  // right column white
  }
  for (int i = 1; i < 9; ++i) {
    EXPECT_LT(tag.pattern[10 + i], 128);  // black border
    EXPECT_LT(tag.pattern[80 + i], 128);
    EXPECT_LT(tag.pattern[i * 10 + 1], 128);
    EXPECT_LT(tag.pattern[i * 10 + 8], 128);
  }
  // The black border edge is `size`: cell = size / 8.
  EXPECT_NEAR(tag.cell, 0.6 / 8.0, 1e-12);
  EXPECT_NEAR(tag.half, 0.5 * 10 * 0.6 / 8.0, 1e-12);
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
