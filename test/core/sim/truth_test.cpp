#include "slope_monitor/core/sim/truth.h"

#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {
namespace {

LandslideModel Body() {
  LandslideModel l;
  l.centre = Eigen::Vector2d(100.0, 75.0);
  l.length = 40.0;
  l.width = 25.0;
  l.taper = 0.25;
  l.azimuth = -M_PI / 2.0;  // moving south
  l.plunge = 0.3;
  l.velocity0 = 1e-5;  // m/s
  l.reference_time = 1000.0;
  return l;
}

TEST(LandslideModelTest, ConstantVelocityMovesTheCoreAtV0) {
  const LandslideModel l = Body();
  const Eigen::Vector3d centre(100.0, 75.0, 20.0);
  const double t = 1000.0 + 3600.0;
  const Eigen::Vector3d d = l.DisplacementAt(centre, t);
  EXPECT_NEAR(d.norm(), 1e-5 * 3600.0, 1e-12);
  // South and down by the plunge.
  EXPECT_NEAR(d.x(), 0.0, 1e-12);
  EXPECT_NEAR(d.y(), -0.036 * std::cos(0.3), 1e-12);
  EXPECT_NEAR(d.z(), -0.036 * std::sin(0.3), 1e-12);
  // Off the body nothing moves; before the reference nothing moves.
  EXPECT_EQ(l.DisplacementAt(Eigen::Vector3d(10.0, 10.0, 0.0), t).norm(), 0.0);
  EXPECT_EQ(l.DisplacementAt(centre, 999.0).norm(), 0.0);
  // Halfway through the taper (rho = 0.875 along the across-slope axis): smoothstep(0.5) = 0.5.
  const Eigen::Vector3d half(100.0 + 0.875 * 25.0, 75.0, 0.0);
  EXPECT_NEAR(l.DisplacementAt(half, t).norm(), 0.5 * 0.036, 1e-12);
}

TEST(LandslideModelTest, AcceleratingInverseVelocityIsLinearToFailure) {
  LandslideModel l = Body();
  l.velocity = LandslideModel::Velocity::kAccelerating;
  l.failure_time = 1000.0 + 10 * 86400.0;
  // 1/v falls linearly and reaches zero at tf.
  const double t1 = 1000.0 + 86400.0, t2 = 1000.0 + 5 * 86400.0;
  const double iv1 = 1.0 / l.VelocityAt(t1), iv2 = 1.0 / l.VelocityAt(t2);
  const double slope = (iv2 - iv1) / (t2 - t1);
  EXPECT_NEAR(t1 - iv1 / slope, l.failure_time, 1e-3);
  // s(t) is the integral of v: compare with a numerical derivative.
  const double h = 1.0;
  EXPECT_NEAR((l.Travel(t2 + h) - l.Travel(t2 - h)) / (2 * h), l.VelocityAt(t2), 1e-12);
  EXPECT_NEAR(l.VelocityAt(1000.0), 1e-5, 1e-15);
}

TEST(LandslideModelTest, ReferencePositionInvertsTheMotion) {
  LandslideModel l = Body();
  l.velocity0 = 1e-3;  // big motion: 3.6 m per hour
  const double t = 1000.0 + 3600.0;
  for (const Eigen::Vector3d& x : {Eigen::Vector3d(100, 75, 20), Eigen::Vector3d(118, 80, 21),
                                   Eigen::Vector3d(100, 108, 25), Eigen::Vector3d(30, 30, 3)}) {
    const Eigen::Vector3d now = x + l.DisplacementAt(x, t);
    const Eigen::Vector3d back = l.ReferencePositionOf(now, t);
    EXPECT_NEAR((back - x).norm(), 0.0, 1e-8) << x.transpose();
  }
}

SurveyTruth Example() {
  SurveyTruth t;
  t.seed = 7;
  t.config = "config/sim/demo_site.yaml";
  t.origin = Eigen::Vector3d(47.0, 8.0, 500.0);
  t.epochs = {{0, 1.7e9}, {1, 1.7e9 + 21600.0}};
  t.landslide = Body();
  t.obstacles.push_back({Obstacle::Kind::kTree, Eigen::Vector3d(50, 60, 10), 2.0, 8.0, false});
  CameraTruth c;
  c.name = "fixed_cam_1";
  camera::Sensor s{1280, 960, 0.0048};
  std::array<double, camera::kNumInterior> in{12.0, 0.01, -0.02, -1e-3, 2e-6,
                                              0,    1e-5, -2e-5, 1e-4,  0};
  c.model = camera::CameraModel(s, camera::DistortionModel::kBrownAffinity, in);
  c.nominal = c.model;
  c.nominal.mutable_interior()[camera::kC] = 12.1;
  camera::ExteriorOrientation eo;
  eo.position = Eigen::Vector3d(100, -60, 40);
  eo.angles = {0.1, 1.3, -0.05};
  c.nominal_pose = eo;
  c.images.push_back({0, 1.7e9 + 1.0, eo, {"tag36h11/3", "circle/1"}, std::nullopt, 1.0});
  t.cameras.push_back(c);
  TargetTruth tt;
  tt.key = "tag36h11/3";
  tt.id = 3;
  tt.size = 0.6;
  tt.positions = {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 1.9, 2.95)};
  tt.surveyed = Eigen::Vector3d(1.01, 2.02, 3.0);
  t.targets.push_back(tt);
  t.radio.receivers.push_back({"rx1", Eigen::Vector3d(10, 150, 40), 0.3});
  t.radio.transmitters.push_back({"tx1", 2.4e9 + 1000.0, 1.1, {Eigen::Vector3d(100, 75, 20)}});
  t.radio.ambiguities = {{-1234}};
  t.surfaces.push_back({0, "demo.surface_e00.tif"});
  return t;
}

TEST(SurveyTruthTest, YamlRoundTripKeepsEveryField) {
  const SurveyTruth a = Example();
  const SurveyTruth b = SurveyTruth::FromYaml(a.ToYaml(), "roundtrip");
  EXPECT_EQ(b.seed, 7u);
  ASSERT_EQ(b.epochs.size(), 2u);
  EXPECT_EQ(b.epochs[1].stamp, 1.7e9 + 21600.0);
  ASSERT_EQ(b.cameras.size(), 1u);
  EXPECT_EQ(b.cameras[0].model.interior(), a.cameras[0].model.interior());
  EXPECT_EQ(b.cameras[0].nominal.interior()[camera::kC], 12.1);
  ASSERT_EQ(b.cameras[0].images.size(), 1u);
  EXPECT_EQ(b.cameras[0].images[0].exterior.ToArray(), a.cameras[0].images[0].exterior.ToArray());
  EXPECT_EQ(b.cameras[0].images[0].visible, a.cameras[0].images[0].visible);
  ASSERT_TRUE(b.cameras[0].nominal_pose.has_value());
  const TargetTruth* t = b.FindTarget("tag36h11/3");
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->positions[1], Eigen::Vector3d(1, 1.9, 2.95));
  ASSERT_TRUE(t->surveyed.has_value());
  EXPECT_EQ(b.TargetPositions(1).at("tag36h11/3"), Eigen::Vector3d(1, 1.9, 2.95));
  EXPECT_EQ(b.radio.ambiguities[0][0], -1234);
  EXPECT_EQ(b.radio.transmitters[0].frequency, 2.4e9 + 1000.0);
  EXPECT_EQ(b.surfaces[0].geotiff, "demo.surface_e00.tif");
  const Eigen::Vector3d x(105, 70, 20);
  EXPECT_EQ(b.DisplacementAt(x, 1e4), a.DisplacementAt(x, 1e4));
}

TEST(SurveyTruthTest, UnmatchableFlagsObstaclesAndScarp) {
  SurveyTruth t = Example();
  t.scarp.depth = 3.0;
  t.scarp.band = 0.05;
  EXPECT_TRUE(t.Unmatchable(Eigen::Vector3d(51.0, 60.5, 0)));   // under the tree crown
  EXPECT_FALSE(t.Unmatchable(Eigen::Vector3d(53.5, 60.0, 0)));  // beside it
  // The head is upslope (north, motion is south): rho = 0.98 at the head is scarp.
  EXPECT_TRUE(t.Unmatchable(Eigen::Vector3d(100.0, 75.0 + 0.98 * 40.0, 0)));
  EXPECT_FALSE(t.Unmatchable(Eigen::Vector3d(100.0, 75.0 - 0.98 * 40.0, 0)));  // the toe is not
  EXPECT_FALSE(t.Unmatchable(Eigen::Vector3d(100.0, 75.0, 0)));
}

TEST(SurveyTruthTest, MissingKeyIsNamed) {
  std::string yaml = Example().ToYaml();
  const size_t at = yaml.find("landslide:");
  ASSERT_NE(at, std::string::npos);
  yaml.replace(at, 10, "landslid_:");
  try {
    SurveyTruth::FromYaml(yaml, "bad.truth.yaml");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("landslide"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("bad.truth.yaml"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
