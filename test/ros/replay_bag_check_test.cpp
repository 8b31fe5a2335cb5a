// replay.launch on a bag that rosbag play cannot play (issue 22): roslaunch
// stops at load time, before the master or any node starts, with status 1
// and bag_check's message naming the bag. Before, the required player died,
// roslaunch shut the graph down and ended with status 0.
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "run_command.h"

namespace {

using LaunchRun = slope_monitor::run_command::CommandRun;

// roslaunch replay.launch bag:=<bag>, stderr folded into the output; a
// launch that gets past the check is ended by `timeout` (status 124).
LaunchRun Replay(const std::string& bag) {
  return slope_monitor::run_command::Run("timeout -s INT 60 roslaunch --skip-log-check " +
                                         std::string(SM_SOURCE_DIR) +
                                         "/launch/replay.launch bag:=" + bag);
}

const std::string kReplayTmp = "/tmp/sm_replay_bag_check_" + std::to_string(getpid());

TEST(ReplayBagCheck, MissingBagEndsTheLaunchWithStatus1NamingIt) {
  const std::string bag = kReplayTmp + "_missing.bag";
  const LaunchRun r = Replay(bag);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("bag_check: " + bag + ": no such file"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("started roslaunch server"), std::string::npos) << r.output;
}

TEST(ReplayBagCheck, TruncatedBagEndsTheLaunchWithStatus1NamingIt) {
  // The first 300 kB of a real 868 kB bag: no index, the last chunk cut.
  std::ifstream in(std::string(SM_TEST_DATA_DIR) + "/rosbag_turtlesim/example.bag",
                   std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 300000u);
  const std::string bag = kReplayTmp + "_truncated.bag";
  std::ofstream(bag, std::ios::binary) << bytes.substr(0, 300000);
  const LaunchRun r = Replay(bag);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("bag_check: " + bag + ": not a readable bag, or truncated"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("started roslaunch server"), std::string::npos) << r.output;
  std::remove(bag.c_str());
}

}  // namespace
