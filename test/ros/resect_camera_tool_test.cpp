// resect_camera as a crew runs it (issue 19), on real control points: the
// AK10 time-lapse camera at Columbia Glacier (ImGRAFT demo, test/data/README.md),
// four points picked in the photo, X Y Z in UTM zone 6N (EPSG:32606) with
// ellipsoidal heights, the camera's position from cameras.csv held, from a
// nominal 20 mm lens on the D200's 23.6 mm sensor. The tool reads only the
// photo's size, so a blank image of the photo's 3872 x 2592 px stands in for it.
//  * Without --site the coordinates are used as given: the pose file holds
//    the given position exactly, the printed RMS line has the 2-D convention.
//  * With --site (a site file in EPSG:32606, local ENU at the camera) the
//    pose is in the site frame: the camera at the origin (PROJ round trip,
//    < 1 mm), position_crs = the given position, the optical axis at
//    cameras.csv's yaw -165 deg and pitch -10 deg (within 5 deg, as the
//    core test), and the graph's pose-file reader takes the file.
//  * --site with --crs, or a missing site file: exit 1 naming them.
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "run_command.h"
#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/io/camera_pose_file.h"

namespace {

namespace sm = slope_monitor;

const std::string kResectDir = "/tmp/sm_resect_tool_" + std::to_string(getpid());
constexpr double kResectDeg = M_PI / 180.0;

class ResectCameraTool : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::system(("mkdir -p " + kResectDir).c_str());
    cv::imwrite(kResectDir + "/ak10.png", cv::Mat::zeros(2592, 3872, CV_8UC1));
    std::ofstream(kResectDir + "/site.yaml")
        << "name: columbia_ak10\ncrs: EPSG:32606\norigin: [499211.336, 6783755.954, 478.96]\n";
  }
  static void TearDownTestSuite() { std::system(("rm -rf " + kResectDir).c_str()); }

  // resect_camera with the AK10 points and camera, plus `extra`.
  static sm::run_command::CommandRun Resect(const std::string& extra, const std::string& out) {
    return sm::run_command::Run(std::string(SM_TOOL_DIR) + "/resect_camera --image " + kResectDir +
                                "/ak10.png --gcp " + SM_TEST_DATA_DIR +
                                "/timelapse_columbia/AK10_20090821_gcp.txt --pixel-origin corner "
                                "--focal-mm 20 --sensor-mm 23.6 15.8 "
                                "--position 499211.336 6783755.954 478.96 " +
                                extra + " --out " + kResectDir + "/" + out);
  }
};

double RmsOf(const std::string& output) {
  std::smatch m;
  const std::regex line("\nRMS ([0-9.]+) px over 4 points\n");
  return std::regex_search(output, m, line) ? std::stod(m[1]) : -1.0;
}

TEST_F(ResectCameraTool, CoordinatesAsGiven) {
  const auto r = Resect("--crs EPSG:32606", "plain");
  ASSERT_EQ(r.status, 0) << r.output;
  const double rms = RmsOf(r.output);
  EXPECT_GT(rms, 0.0) << r.output;
  EXPECT_LT(rms, 5.0) << r.output;
  const auto pose = sm::io::ReadCameraPoseFile(kResectDir + "/plain.pose.yaml", "test");
  EXPECT_EQ(pose.position.x(), 499211.336);
  EXPECT_EQ(pose.position.y(), 6783755.954);
  EXPECT_EQ(pose.position.z(), 478.96);
  std::ifstream calibration(kResectDir + "/plain.yaml");
  EXPECT_TRUE(calibration.good());
}

TEST_F(ResectCameraTool, SiteFileGivesThePoseInTheSiteFrame) {
  const auto r = Resect("--site " + kResectDir + "/site.yaml", "site");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("frame: site of " + kResectDir +
                          "/site.yaml (points and --position in EPSG:32606)"),
            std::string::npos)
      << r.output;
  const double rms = RmsOf(r.output);
  EXPECT_GT(rms, 0.0) << r.output;
  EXPECT_LT(rms, 5.0) << r.output;
  const auto pose = sm::io::ReadCameraPoseFile(kResectDir + "/site.pose.yaml", "test");
  EXPECT_LT(pose.position.norm(), 1e-3) << pose.position.transpose();
  // The optical axis in site (x east, y north, z up).
  const Eigen::Vector3d axis =
      sm::camera::RotationFromAngles(pose.angles).transpose() * Eigen::Vector3d(0, 0, -1);
  EXPECT_NEAR(std::atan2(axis.x(), axis.y()) / kResectDeg, -165.0, 5.0);
  EXPECT_NEAR(std::asin(axis.z()) / kResectDeg, -10.0, 5.0);
  std::ifstream in(kResectDir + "/site.pose.yaml");
  std::stringstream buffer;
  buffer << in.rdbuf();
  const std::string text = buffer.str();
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      text, m, std::regex("position_crs: \\[([-0-9.e]+), ([-0-9.e]+), ([-0-9.e]+)\\]")))
      << text;
  EXPECT_NEAR(std::stod(m[1]), 499211.336, 1e-3);
  EXPECT_NEAR(std::stod(m[2]), 6783755.954, 1e-3);
  EXPECT_NEAR(std::stod(m[3]), 478.96, 1e-3);
  EXPECT_NE(text.find("crs: \"EPSG:32606\""), std::string::npos) << text;
}

TEST_F(ResectCameraTool, SiteAndCrsTogetherOrAMissingSiteFileAreNamed) {
  auto r = Resect("--site " + kResectDir + "/site.yaml --crs EPSG:32606", "both");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("give either --site FILE"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--crs"), std::string::npos) << r.output;
  r = Resect("--site " + kResectDir + "/no_such_site.yaml", "missing");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(kResectDir + "/no_such_site.yaml"), std::string::npos) << r.output;
}

}  // namespace
