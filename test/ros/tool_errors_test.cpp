// Tools fail cleanly on bad input (issue 22): exit status 1 (no abort, no
// silent acceptance) and a message naming the input. The tools are run as
// the user runs them, from the folder rosrun finds them in.
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "run_command.h"

namespace {

// The tools as rosrun finds them (tests are built elsewhere: CMakeLists.txt).
std::string BinDir() { return SM_TOOL_DIR; }

using ToolRun = slope_monitor::run_command::CommandRun;

// Runs `tool args` with stderr folded into the output.
ToolRun Tool(const std::string& tool, const std::string& args) {
  return slope_monitor::run_command::Run(BinDir() + "/" + tool + " " + args);
}

const std::string kTmp = "/tmp/sm_tool_errors_" + std::to_string(getpid());

TEST(ToolErrors, CentroidTargetsMissingImageFolder) {
  const ToolRun r = Tool("centroid_targets", "--images /nonexistent --out " + kTmp + ".csv");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("/nonexistent"), std::string::npos) << r.output;
  std::remove((kTmp + ".csv").c_str());
}

TEST(ToolErrors, DenseSurfaceEpochNotANumber) {
  const ToolRun r = Tool(
      "dense_surface", "--truth " + kTmp + ".truth.yaml --bag x.bag --epoch abc --out-dir " + kTmp);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--epoch 'abc'"), std::string::npos) << r.output;
}

TEST(ToolErrors, MakeSurveyBagNegativeSeed) {
  const ToolRun r =
      Tool("make_survey_bag", "--config " + kTmp + ".yaml --out " + kTmp + ".bag --seed -5");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--seed '-5'"), std::string::npos) << r.output;
}

TEST(ToolErrors, SolveBalHugeDeclaredCounts) {
  const std::string path = kTmp + ".bal";
  std::ofstream(path) << "2000000000 2000000000 200000";  // 28 bytes
  const ToolRun r = Tool("solve_bal", path);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(path), std::string::npos) << r.output;
  std::remove(path.c_str());
}

// Issue 19: a stable mask that is not the photos' size is named with both sizes.
TEST(ToolErrors, TrackCameraStableMaskOfTheWrongSize) {
  const std::string dir = kTmp + "_track";
  ASSERT_EQ(system(("mkdir -p '" + dir + "'").c_str()), 0);
  std::ofstream(dir + "/cam.yaml")
      << "image_width: 64\nimage_height: 48\ncamera_name: cam\n"
         "camera_matrix: {rows: 3, cols: 3, data: [100, 0, 31.5, 0, 100, 23.5, 0, 0, 1]}\n"
         "distortion_model: plumb_bob\n"
         "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
         "rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\n"
         "projection_matrix: {rows: 3, cols: 4, data: [100, 0, 31.5, 0, 0, 100, 23.5, 0, 0, 0, 1, "
         "0]}\n";
  std::ofstream(dir + "/cam.pose.yaml")
      << "position: [0, 0, 0]\nangles_deg: {theta: 0, phi: 90, kappa: 0}\n";
  cv::Mat photo(48, 64, CV_8UC1);
  cv::randu(photo, 0, 255);
  ASSERT_TRUE(cv::imwrite(dir + "/a.png", photo));
  ASSERT_TRUE(cv::imwrite(dir + "/b.png", photo));
  ASSERT_TRUE(cv::imwrite(dir + "/mask.png", cv::Mat(24, 32, CV_8UC1, cv::Scalar(255))));
  const ToolRun r =
      Tool("track_camera", "--camera " + dir + "/cam --reference " + dir + "/a.png --image " + dir +
                               "/b.png --stable-mask " + dir + "/mask.png --out " + dir + "/out");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--stable-mask '" + dir + "/mask.png' is 32x24 px, the images are 64x48"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(system(("rm -rf '" + dir + "'").c_str()), 0);
}

}  // namespace
