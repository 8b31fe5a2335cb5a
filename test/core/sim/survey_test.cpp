// Survey generation from a site config: determinism, bad configurations,
// consistency of the truth with the rendered images.
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace sim {
namespace {

const std::string kTiny = std::string(SM_TEST_DATA_DIR) + "/sim/tiny_site.yaml";

std::string ReadFile(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::string Replace(std::string s, const std::string& from, const std::string& to) {
  const size_t at = s.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) s.replace(at, from.size(), to);
  return s;
}

std::string ErrorOf(const std::string& yaml) {
  try {
    SurveyConfig c = SurveyConfig::Parse(yaml, "bad_site.yaml");
    SurveyGenerator g(c);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(SurveyTest, SameSeedGivesIdenticalImageBytes) {
  const SurveyConfig config = SurveyConfig::Load(kTiny);
  const Survey a = SurveyGenerator(config).Generate();
  const Survey b = SurveyGenerator(config).Generate();
  ASSERT_EQ(a.images.size(), b.images.size());
  ASSERT_GE(a.images.size(), 6u);
  for (size_t k = 0; k < a.images.size(); ++k) {
    const cv::Mat& x = a.images[k].pixels;
    const cv::Mat& y = b.images[k].pixels;
    ASSERT_EQ(x.total() * x.elemSize(), y.total() * y.elemSize());
    EXPECT_EQ(0, std::memcmp(x.data, y.data, x.total() * x.elemSize())) << "image " << k;
  }
  SurveyConfig other = config;
  other.seed = config.seed + 1;
  other.scene.seed = other.seed;
  const Survey c = SurveyGenerator(other).Generate();
  EXPECT_NE(
      0, std::memcmp(a.images[0].pixels.data, c.images[0].pixels.data, a.images[0].pixels.total()));
}

TEST(SurveyTest, TruthIsConsistent) {
  const SurveyConfig config = SurveyConfig::Load(kTiny);
  const Survey s = SurveyGenerator(config).Generate();
  const SurveyTruth& t = s.truth;
  ASSERT_EQ(t.epochs.size(), 3u);
  EXPECT_DOUBLE_EQ(t.epochs[2].stamp, 1700000000.0 + 7200.0);
  // Images are sorted by stamp; bgr8 for the uav, mono8 for the fixed camera.
  for (size_t k = 1; k < s.images.size(); ++k) EXPECT_LE(s.images[k - 1].stamp, s.images[k].stamp);
  for (const SurveyImage& im : s.images) {
    EXPECT_EQ(im.pixels.channels(), t.cameras[im.camera].encoding == "bgr8" ? 3 : 1);
  }
  // Targets: control points are surveyed with noise, don't move; monitoring points move with the
  // field.
  for (const TargetTruth& tt : t.targets) {
    ASSERT_EQ(tt.positions.size(), 3u);
    if (tt.role == io::TargetRole::kMonitoring) {
      EXPECT_FALSE(tt.surveyed.has_value());
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d expect =
            tt.positions[0] + t.DisplacementAt(tt.positions[0], t.epochs[k].stamp);
        EXPECT_LT((tt.positions[k] - expect).norm(), 1e-9) << tt.key;
      }
      EXPECT_GT((tt.positions[2] - tt.positions[0]).norm(), 0.3) << tt.key;
    } else {
      ASSERT_TRUE(tt.surveyed.has_value());
      EXPECT_EQ(tt.positions[2], tt.positions[0]);
      EXPECT_LT((*tt.surveyed - tt.positions[0]).norm(), 0.2);
    }
  }
  // Every camera sees a control point in the reference epoch; UAV images have GNSS.
  for (const CameraTruth& c : t.cameras) {
    bool control = false;
    for (const ImageTruth& im : c.images) {
      if (c.kind == "uav") EXPECT_TRUE(im.gnss.has_value());
      for (const std::string& key : im.visible) {
        if (im.epoch == 0 && t.FindTarget(key)->role == io::TargetRole::kControl) control = true;
      }
    }
    EXPECT_TRUE(control) << c.name;
  }
  // Radio: ambiguities for every link, transmitters move with the field.
  ASSERT_EQ(t.radio.ambiguities.size(), 5u);
  ASSERT_EQ(t.radio.ambiguities[0].size(), 3u);
  EXPECT_FALSE(t.radio.faults.empty());
  EXPECT_GT((t.radio.transmitters[0].positions[2] - t.radio.transmitters[0].positions[0]).norm(),
            0.3);
  // Surfaces: the GeoTIFF grid holds the mesh heights.
  ASSERT_EQ(s.surfaces.size(), 3u);
  const Scene scene(config.scene);
  const double z = s.surfaces[0].Interpolate(0, 10.0, 40.0);
  EXPECT_NEAR(z, scene.reference_grid().HeightAt(10.0, 40.0), 1e-4);
}

TEST(SurveyTest, BadConfigurationsNameTheKey) {
  const std::string good = ReadFile(kTiny);
  EXPECT_EQ(ErrorOf(good), "");
  // Unknown key.
  std::string e = ErrorOf(Replace(good, "relief: 10.0", "releif: 10.0"));
  EXPECT_NE(e.find("releif"), std::string::npos) << e;
  e = ErrorOf(Replace(good, "overlap: 0.5", "overlap: 0.5, speed: 3"));
  EXPECT_NE(e.find("speed"), std::string::npos) << e;
  // Out of range.
  e = ErrorOf(Replace(good, "grid_spacing: 0.5", "grid_spacing: -1"));
  EXPECT_NE(e.find("grid_spacing"), std::string::npos) << e;
  // Camera looking away from the slope (at the sky behind it).
  e = ErrorOf(Replace(good, "look_at: [30.0, 22.0, 4.0]", "look_at: [30.0, -60.0, 30.0]"));
  EXPECT_NE(e.find("look_at"), std::string::npos) << e;
  EXPECT_NE(e.find("cameras[0]"), std::string::npos) << e;
  // UAV strip over the sky.
  e = ErrorOf(Replace(good, "overlap: 0.5}", "overlap: 0.5, tilt_deg: 80, tilt_azimuth_deg: -90}"));
  EXPECT_NE(e.find("strips[0]"), std::string::npos) << e;
  // No control point in view: all control points made monitoring... on stable ground -> check role
  std::string no_control = good;
  for (int k = 0; k < 5; ++k) no_control = Replace(no_control, "role: control", "role: check");
  e = ErrorOf(no_control);
  EXPECT_NE(e.find("no control point"), std::string::npos) << e;
  EXPECT_NE(e.find("cameras[0]"), std::string::npos) << e;
  // A control point on the moving body.
  e = ErrorOf(
      Replace(good, "role: control, position: [30, 7]", "role: control, position: [30, 20]"));
  EXPECT_NE(e.find("targets: list[4]"), std::string::npos) << e;
  // A radio receiver on the body.
  e = ErrorOf(Replace(good, "position: [5, 42], xi", "position: [30, 21], xi"));
  EXPECT_NE(e.find("receivers[0]"), std::string::npos) << e;
}

TEST(SurveyTest, FacingPlatesStandOnPostsTurnedToThePoint) {
  const std::string good = ReadFile(kTiny);
  const Eigen::Vector3d face(30.0, -40.0, 40.0);
  const SurveyConfig config = SurveyConfig::Parse(
      Replace(good, "mount_height: 0.03", "mount_height: 0.8\n  face_toward: [30.0, -40.0, 40.0]"),
      "facing.yaml");
  const Scene scene(config.scene);
  ASSERT_FALSE(scene.targets().empty());
  for (const TargetTruth& t : scene.targets()) {
    const Eigen::Vector3d c = t.positions[0];
    const double ground = scene.AnalyticHeight(c.x(), c.y());
    EXPECT_NEAR(c.z() - ground, 0.8, 0.05) << t.key;  // mesh vs analytic surface differ by mm
    EXPECT_LT((t.normal - (face - c).normalized()).norm(), 1e-12) << t.key;
    EXPECT_NEAR(t.up_in_plate.dot(t.normal), 0.0, 1e-12) << t.key;
    EXPECT_GT(t.up_in_plate.z(), 0.0) << t.key;  // the tag's top row is up
  }
  // A plate whose lower edge would be in the ground is refused, naming the fix.
  const std::string e = ErrorOf(Replace(good, "mount_height: 0.03",
                                        "mount_height: 0.05\n  face_toward: [30.0, -40.0, 40.0]"));
  EXPECT_NE(e.find("mount_height"), std::string::npos) << e;
  // Facing below the horizon is refused too.
  const std::string e2 = ErrorOf(Replace(
      good, "mount_height: 0.03", "mount_height: 1.0\n  face_toward: [30.0, -40.0, -400.0]"));
  EXPECT_NE(e2.find("face_toward"), std::string::npos) << e2;
}

TEST(SurveyTest, ShippedConfigsLoad) {
  for (const char* name : {"demo_site", "fixed_only", "uav_only", "faults"}) {
    const std::string path = std::string(SM_SOURCE_DIR) + "/config/sim/" + name + ".yaml";
    EXPECT_NO_THROW(SurveyConfig::Load(path)) << path;
  }
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
