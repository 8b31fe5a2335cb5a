// adjustment::ResectCamera and io::ReadSurveyedPoints (issue 19): a camera
// resected from surveyed points picked in its photo, from a nominal camera and
// no attitude guess.
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "resect_scenario.h"
#include "slope_monitor/core/adjustment/resect_camera.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/surveyed_points.h"

namespace slope_monitor {
namespace {

constexpr double kResectDeg = M_PI / 180.0;

using resect_scenario::Camera;
using resect_scenario::Survey;
using resect_scenario::TruePose;

using resect_scenario::Sigma;

TEST(ResectCamera, SimulatedSurveyRecoversAttitudeAndFocalWithinThreeSigma) {
  const camera::CameraModel truth = Camera(16.0);
  const camera::ExteriorOrientation pose = TruePose();
  for (int n : {10, 20, 30}) {
    const auto points = Survey(truth, pose, n, 0.01, 0.5, 7 + n);
    adjustment::ResectCameraOptions o;  // frees c
    o.pixel_sigma = 0.5;
    o.point_sigma = 0.01;
    const auto s = adjustment::ResectCamera(points, Camera(15.0), o);  // nominal c 6 % off
    ASSERT_TRUE(s.success) << s.message;
    SCOPED_TRACE("n = " + std::to_string(n) + ", start: " + s.start);
    EXPECT_LT(std::abs(s.exterior.angles.theta - pose.angles.theta), 3 * Sigma(s, "theta"));
    EXPECT_LT(std::abs(s.exterior.angles.phi - pose.angles.phi), 3 * Sigma(s, "phi"));
    EXPECT_LT(std::abs(s.exterior.angles.kappa - pose.angles.kappa), 3 * Sigma(s, "kappa"));
    EXPECT_LT(std::abs(s.model.principal_distance() - 16.0), 3 * Sigma(s, "c"));
    const char* xyz[3] = {"X0", "Y0", "Z0"};
    for (int k = 0; k < 3; ++k)
      EXPECT_LT(std::abs(s.exterior.position(k) - pose.position(k)), 3 * Sigma(s, xyz[k]));
    // A sigma that means something: c to 1 % (theta and kappa are nearly
    // the same axis for a camera looking horizontally, phi near 90 deg).
    EXPECT_LT(Sigma(s, "c"), 0.16);
    EXPECT_GT(s.sigma0, 0.5);
    EXPECT_LT(s.sigma0, 1.6);
    EXPECT_EQ(s.points.size(), static_cast<size_t>(n));
  }
}

TEST(ResectCamera, KnownPositionStartsFromDirectionsAndFlagsABadPick) {
  const camera::CameraModel truth = Camera(16.0);
  const camera::ExteriorOrientation pose = TruePose();
  auto points = Survey(truth, pose, 12, 0.0, 0.3, 3);
  points[5].pixel += Eigen::Vector2d(12.0, -9.0);  // a mis-picked point
  adjustment::ResectCameraOptions o;
  o.pixel_sigma = 0.3;
  o.has_position = true;
  o.position = pose.position;
  const auto s = adjustment::ResectCamera(points, Camera(17.0), o);
  ASSERT_TRUE(s.success) << s.message;
  EXPECT_NE(s.start.find("known position"), std::string::npos);
  EXPECT_EQ(s.parameters.size(), 4u);  // theta phi kappa c: the position is held
  // The mis-pick fails data snooping with the largest |w| (least squares
  // spreads a 50-sigma error, so neighbours may fail too).
  EXPECT_TRUE(s.points[5].snooping_failed);
  for (size_t i = 0; i < s.points.size(); ++i)
    if (i != 5) EXPECT_LT(s.points[i].w, s.points[5].w) << i;
  EXPECT_EQ((s.exterior.position - pose.position).norm(), 0.0);
}

TEST(ResectCamera, FreeingK1NeedsNoNonZeroNominal) {
  camera::CameraModel truth = Camera(16.0);
  truth = camera::CameraModel(truth.sensor(), camera::DistortionModel::kRadial, [] {
    std::array<double, camera::kNumInterior> in{};
    in[camera::kC] = 16.0;
    in[camera::kK1] = -4e-4;
    return in;
  }());
  const auto points = Survey(truth, TruePose(), 30, 0.0, 0.3, 11);
  adjustment::ResectCameraOptions o;
  o.free_interior = {"c", "k1"};
  o.pixel_sigma = 0.3;
  const auto s = adjustment::ResectCamera(points, Camera(16.5), o);
  ASSERT_TRUE(s.success) << s.message;
  EXPECT_EQ(s.model.model(), camera::DistortionModel::kRadial);
  EXPECT_LT(std::abs(s.model.interior()[camera::kK1] + 4e-4), 3 * Sigma(s, "k1"));
  EXPECT_LT(s.rms_px, 0.5);
}

TEST(ResectCamera, BadInputIsNamed) {
  const camera::CameraModel truth = Camera(16.0);
  const camera::ExteriorOrientation pose = TruePose();
  auto points = Survey(truth, pose, 10, 0.0, 0.3, 5);
  adjustment::ResectCameraOptions o;
  const std::vector<io::PickedPoint> three(points.begin(), points.begin() + 3);
  try {
    adjustment::ResectCamera(three, truth, o);
    FAIL() << "3 points accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("3 points; need at least 4"), std::string::npos)
        << e.what();
  }
  o.free_interior = {"c", "k9"};
  EXPECT_THROW(adjustment::ResectCamera(points, truth, o), InvalidArgument);
  // A point behind the camera (the position known).
  o.free_interior = {"c"};
  o.has_position = true;
  o.position = pose.position;
  points[2].xyz = 2 * pose.position - points[2].xyz;
  try {
    adjustment::ResectCamera(points, truth, o);
    FAIL() << "a point behind the camera accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("behind the camera: p2"), std::string::npos) << e.what();
  }
}

TEST(SurveyedPoints, ParsesIdsCommentsAndTheCornerConvention) {
  const auto p = io::ParseSurveyedPoints(
      "% header\norb 498773.49 6775715.87 394.45 983.85 308.85  # picked\n\n1 2 3 10.5 20.5\n",
      "gcp.txt", io::PixelOrigin::kCorner);
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].id, "orb");
  EXPECT_EQ(p[0].line, 2);
  EXPECT_DOUBLE_EQ(p[0].xyz.x(), 498773.49);
  EXPECT_DOUBLE_EQ(p[0].pixel.x(), 983.35);
  EXPECT_EQ(p[1].id, "#4");
  EXPECT_DOUBLE_EQ(p[1].pixel.y(), 20.0);
}

TEST(SurveyedPoints, BadLinesNameFileLineAndProblem) {
  auto message = [](const std::string& text) {
    try {
      io::ParseSurveyedPoints(text, "gcp.txt", io::PixelOrigin::kOpenCv);
    } catch (const InvalidArgument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message("a 1 2 3 4 5\n# c\nb 1 1951+9 3 4 5\n"),
            "gcp.txt:3: malformed number '1951+9' in column Y");
  EXPECT_EQ(message("1951+9 2 3 4 5\n"), "gcp.txt:1: malformed number '1951+9' in column X");
  EXPECT_NE(message("c 1 2 3 4\n").find("gcp.txt:1: too few columns: 4"), std::string::npos);
  EXPECT_NE(message("1 2 3 4 5 6\n").find("gcp.txt:1: too many columns: 6"), std::string::npos);
  EXPECT_THROW(io::ReadSurveyedPoints("/nonexistent/gcp.txt", io::PixelOrigin::kOpenCv), IoError);
}

// Real: the AK10 time-lapse camera at Columbia Glacier (ImGRAFT demo), four
// picked control points 5-10 km away, the position from cameras.csv held, the
// view direction and c free, from a nominal 20 mm lens on the D200's 23.6 mm wide
// sensor (see doc/targetless_camera.md).
TEST(ResectCamera, ColumbiaAk10FourControlPoints) {
  const auto points = io::ReadSurveyedPoints(
      std::string(SM_TEST_DATA_DIR) + "/timelapse_columbia/AK10_20090821_gcp.txt",
      io::PixelOrigin::kCorner);
  ASSERT_EQ(points.size(), 4u);
  camera::Sensor s;
  s.width = 3872;
  s.height = 2592;
  s.pixel_size = 23.6 / 3872;
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 20.0;
  adjustment::ResectCameraOptions o;
  o.has_position = true;
  o.position = Eigen::Vector3d(499211.336, 6783755.954, 478.96);  // cameras.csv, AK10
  const auto r = adjustment::ResectCamera(
      points, camera::CameraModel(s, camera::DistortionModel::kNone, in), o);
  ASSERT_TRUE(r.success) << r.message;
  // cameras.csv gives the view direction as yaw -165 deg (clockwise from
  // north), pitch -10 deg; the optical axis in site:
  const Eigen::Vector3d axis =
      camera::RotationFromAngles(r.exterior.angles).transpose() * Eigen::Vector3d(0, 0, -1);
  const double yaw = std::atan2(axis.x(), axis.y()) / kResectDeg,
               pitch = std::asin(axis.z()) / kResectDeg;
  EXPECT_NEAR(yaw, -165.0, 5.0);
  EXPECT_NEAR(pitch, -10.0, 5.0);
  EXPECT_EQ(r.redundancy, 4);
  EXPECT_LT(r.rms_px, 5.0);
  RecordProperty("rms_px", std::to_string(r.rms_px));
  std::printf("AK10: RMS %.3f px over 4 points, yaw %.3f pitch %.3f deg, c %.3f mm\n", r.rms_px,
              yaw, pitch, r.model.principal_distance());
  for (const auto& p : r.points)
    std::printf("  %s du %.3f dv %.3f\n", p.id.c_str(), p.residual.x(), p.residual.y());
}

}  // namespace
}  // namespace slope_monitor
