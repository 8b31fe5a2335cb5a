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
  const ToolRun r = Tool("dense_surface", "--truth " + kTmp + ".truth.yaml --bag x.bag --epoch abc --out-dir " + kTmp);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--epoch 'abc'"), std::string::npos) << r.output;
}

TEST(ToolErrors, MakeSurveyBagNegativeSeed) {
  const ToolRun r = Tool("make_survey_bag", "--config " + kTmp + ".yaml --out " + kTmp + ".bag --seed -5");
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

}  // namespace
