// PruneScene: weak images, orphaned points and empty cameras leave the
// scene; what stays is re-indexed consistently. InitializeScene orients a
// GNSS image that sees too few control points to resect.
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/initialization.h"
#include "slope_monitor/core/camera/rotation.h"

namespace slope_monitor {
namespace adjustment {
namespace {

Scene MakePruneScene() {
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
  const Scene in = MakePruneScene();
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
  Scene in = MakePruneScene();
  in.points[7].position_known = true;
  const Scene out = PruneScene(in, 3, nullptr);
  EXPECT_EQ(out.images.size(), 3u);
  EXPECT_EQ(out.points.size(), 8u);
  EXPECT_EQ(out.observations.size(), in.observations.size());
  EXPECT_EQ(out.cameras.size(), 2u);
}

TEST(PruneScene, UnorientedImageIsDropped) {
  Scene in = MakePruneScene();
  in.points[7].position_known = true;
  in.images[2].exterior_known = false;
  PruneReport report;
  const Scene out = PruneScene(in, 3, &report);
  EXPECT_EQ(out.images.size(), 2u);
  EXPECT_EQ(out.FindImage("uav@2"), -1);
  EXPECT_EQ(out.FindPoint("tag36h11/7"), -1);  // only uav@2 saw it
}

// A nadir UAV photo 60 m above ground seeing three control points: resection
// needs four, the GNSS centre (3 cm off) and the three rays fix the attitude.
TEST(InitializeScene, OrientsAGnssImageFromTwoOrThreeKnownPoints) {
  camera::Sensor sensor{1280, 960, 0.0048};
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 8.8;
  const camera::CameraModel model(sensor, camera::DistortionModel::kBrown, interior);
  camera::ExteriorOrientation truth;
  truth.position = Eigen::Vector3d(100.0, 60.0, 80.0);
  truth.angles.theta = 0.01;
  truth.angles.phi = -0.02;
  truth.angles.kappa = 0.3;
  const std::vector<Eigen::Vector3d> points = {
      {95.0, 55.0, 20.0}, {108.0, 57.0, 21.0}, {101.0, 70.0, 22.0}};
  for (size_t n : {2u, 3u}) {
    Scene s;
    s.cameras.push_back({"uav", model});
    Image im;
    im.name = "uav@1";
    im.exterior_known = false;
    im.position_prior = truth.position + Eigen::Vector3d(0.03, -0.02, 0.04);
    s.images.push_back(im);
    for (size_t j = 0; j < n; ++j) {
      ObjectPoint p;
      p.id = "tag36h11/" + std::to_string(j);
      p.role = PointRole::kControl;
      p.position_known = false;
      p.surveyed = points[j];
      s.points.push_back(p);
      Observation o;
      o.image = 0;
      o.point = static_cast<int>(j);
      ASSERT_TRUE(model.Project(truth, points[j], &o.pixel));
      s.observations.push_back(o);
    }
    InitializeScene(&s);
    ASSERT_TRUE(s.images[0].exterior_known) << n << " points";
    EXPECT_LT((s.images[0].exterior.position - *im.position_prior).norm(), 1e-9);
    // 5 cm at ~60 m: the attitude is right to about a milliradian.
    const Eigen::Matrix3d r_true =
        camera::RotationFromAngles(truth.angles.theta, truth.angles.phi, truth.angles.kappa);
    const Eigen::Matrix3d r = camera::RotationFromAngles(s.images[0].exterior.angles.theta,
                                                         s.images[0].exterior.angles.phi,
                                                         s.images[0].exterior.angles.kappa);
    EXPECT_LT(Eigen::AngleAxisd(r_true.transpose() * r).angle(), 2e-3) << n << " points";
    // Without the prior the image stays unknown (resection needs four).
    Scene no_prior = s;
    no_prior.images[0].exterior_known = false;
    no_prior.images[0].position_prior.reset();
    for (auto& p : no_prior.points) p.position_known = false;
    InitializeScene(&no_prior);
    EXPECT_FALSE(no_prior.images[0].exterior_known);
  }
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
