// The simulated UAV flies like a real one when asked (crab_deg,
// altitude_variation, turn_images): two strips flown both ways on the tiny
// site, checked against the same flight without them (the plan).
#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace sim {
namespace {

const std::string kUavTiny = std::string(SM_TEST_DATA_DIR) + "/sim/tiny_site.yaml";
constexpr double kDeg = M_PI / 180.0;
constexpr double kAltitude = 25.0;  // [m] both strips

std::string Flight(const std::string& extra) {
  std::ifstream f(kUavTiny);
  std::stringstream ss;
  ss << f.rdbuf();
  std::string yaml = ss.str();
  const std::string from =
      "      - {start: [30.0, 12.0], end: [30.0, 32.0], altitude: 25.0, overlap: 0.5}\n";
  const size_t at = yaml.find(from);
  EXPECT_NE(at, std::string::npos);
  yaml.replace(at, from.size(),
               "      - {start: [22.0, 12.0], end: [22.0, 32.0], altitude: 25.0, overlap: 0.5}\n"
               "      - {start: [38.0, 32.0], end: [38.0, 12.0], altitude: 25.0, overlap: 0.5}\n" +
                   extra);
  return yaml;
}

const CameraTruth& Uav(const SurveyGenerator& g) {
  for (const CameraTruth& c : g.planned_truth().cameras)
    if (c.kind == "uav") return c;
  throw std::runtime_error("no uav camera");
}

// Azimuth [rad] of the image's y axis in site (the heading up to a constant).
double Azimuth(const camera::ExteriorOrientation& e) {
  const Eigen::Vector3d y = camera::RotationFromAngles(e.angles).row(1).transpose();
  return std::atan2(y.y(), y.x());
}

double Wrap(double a) { return std::remainder(a, 2.0 * M_PI); }

TEST(UavFlightTest, CrabAltitudeAndTurns) {
  const SurveyGenerator plan(SurveyConfig::Parse(Flight(""), "plan.yaml"));
  const SurveyGenerator real(SurveyConfig::Parse(
      Flight("    crab_deg: 20.0\n    altitude_variation: 0.15\n    turn_images: 3\n"),
      "real.yaml"));
  const CameraTruth &p = Uav(plan), &r = Uav(real);
  const int epochs = 3;
  ASSERT_EQ(p.images.size() % epochs, 0u);
  const int per_epoch = static_cast<int>(p.images.size()) / epochs;  // both strips
  ASSERT_EQ(static_cast<int>(r.images.size()), epochs * (per_epoch + 3));
  const int first = per_epoch / 2;  // images of the first strip (both equally long)

  double z_min = 1e9, z_max = -1e9;
  for (int e = 0; e < epochs; ++e) {
    for (int i = 0; i < per_epoch; ++i) {
      const ImageTruth& a = p.images[e * per_epoch + i];
      const ImageTruth& b = r.images[e * (per_epoch + 3) + (i < first ? i : i + 3)];
      // Crab: +20 deg flying north, -20 deg flying south (0.57 deg attitude noise each).
      const double crab = Wrap(Azimuth(b.exterior) - Azimuth(a.exterior));
      EXPECT_NEAR(crab, (i < first ? 20.0 : -20.0) * kDeg, 3.0 * kDeg) << "image " << i;
      // Height within +-15 % of the altitude (0.15 m track noise each).
      const double dz = b.exterior.position.z() - a.exterior.position.z();
      EXPECT_LE(std::abs(dz), 0.15 * kAltitude + 1.0) << "image " << i;
      z_min = std::min(z_min, dz);
      z_max = std::max(z_max, dz);
    }
    // The turn: beyond the first strip's end (y 32), between the strips, the
    // heading turning through 180 deg in 45-deg steps.
    for (int q = 0; q < 3; ++q) {
      const ImageTruth& t = r.images[e * (per_epoch + 3) + first + q];
      EXPECT_GT(t.exterior.position.y(), 32.0 + 2.0);
      EXPECT_NEAR(t.exterior.position.x(), 30.0 - 8.0 * std::cos(M_PI * (q + 1) / 4.0), 1.5);
    }
  }
  EXPECT_GT(z_max - z_min, 0.1 * kAltitude);  // it does wander
}

// The flight log's attitude: the truth turned by N(0, sigma) about each axis,
// the same for the same (seed, camera, image), different for another image.
// A camera's name is only its topic namespace: a UAV camera named as a crew
// names it (issue 36) flies the same flight as one named uav.
TEST(UavFlightTest, UavCameraMayHaveAnyName) {
  const std::string yaml = Flight("");
  std::string renamed = yaml;
  const std::string from = "  - name: uav\n";
  const size_t at = renamed.find(from);
  ASSERT_NE(at, std::string::npos);
  renamed.replace(at, from.size(), "  - name: drone\n");
  const SurveyGenerator uav(SurveyConfig::Parse(yaml, "uav.yaml"));
  const SurveyGenerator drone(SurveyConfig::Parse(renamed, "drone.yaml"));
  const CameraTruth &a = Uav(uav), &b = Uav(drone);
  EXPECT_EQ(a.name, "uav");
  EXPECT_EQ(b.name, "drone");
  ASSERT_EQ(a.images.size(), b.images.size());
  ASSERT_GT(a.images.size(), 0u);
  for (size_t i = 0; i < a.images.size(); ++i)
    EXPECT_EQ(a.images[i].exterior.position, b.images[i].exterior.position) << i;
}

TEST(UavFlightTest, FlightLogAttitudeScattersBySigma) {
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(10, 20, 80);
  pose.angles.theta = 0.03;
  pose.angles.phi = -0.02;
  pose.angles.kappa = 2.0;
  const Eigen::Quaterniond truth = pose.SiteFromOptical().rotation;
  const double sigma = 0.3 * kDeg;
  double sum = 0.0;
  const int n = 4000;
  for (int i = 0; i < n; ++i) sum += FlightLogAttitude(pose, sigma, 7, 0, i).angularDistance(truth);
  // |w| of three N(0, sigma) components has mean sigma sqrt(8 / pi) = 1.596 sigma;
  // its standard deviation over 4000 draws is ~0.011 sigma.
  EXPECT_NEAR(sum / n / sigma, std::sqrt(8.0 / M_PI), 0.05);
  EXPECT_EQ(FlightLogAttitude(pose, sigma, 7, 0, 5).coeffs(),
            FlightLogAttitude(pose, sigma, 7, 0, 5).coeffs());
  EXPECT_GT(FlightLogAttitude(pose, sigma, 7, 0, 5)
                .angularDistance(FlightLogAttitude(pose, sigma, 7, 0, 6)),
            1e-6);
  EXPECT_LT(FlightLogAttitude(pose, 0.0, 7, 0, 5).angularDistance(truth), 1e-12);
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
