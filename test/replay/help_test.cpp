// --help on every command-line tool and every script a crew runs (issue 38):
// it prints the help, exits 0 and changes nothing. Each runs in an empty
// working folder with an empty HOME, which must stay empty (a script that
// installed, built or wrote a history would leave something there).
#include <signal.h>
#include <sys/wait.h>

#include <chrono>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "replay_test_util.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using replay_test::ReadFile;
using replay_test::Spawn;
using replay_test::Wait;

// The tools (devel/lib/slope_monitor, beside process_bag) a user runs by hand,
// and replay_player / replay_start / replay_end, which replay.launch starts
// (their --help before ros::init: no master is contacted). Not here: the graph's nodes and
// the test nodes (*_node, rostest_*).
const std::vector<std::string> kTools = {
    "bag_check",    "centroid_targets", "deformation_summary", "dense_surface", "make_survey_bag",
    "match_images", "process_bag",      "process_flight",      "replay_end",    "replay_player",
    "replay_start", "resect_camera",    "solve_bal",           "track_camera"};

// Every script of scripts/ but lib.sh and env.sh (sourced, not run), and
// the notification hooks of scripts/hooks.
const std::vector<std::string> kScripts = {"bench",
                                           "build",
                                           "check_format",
                                           "check_launch",
                                           "check_listeners",
                                           "compare_columbia",
                                           "demo",
                                           "fuzz_long",
                                           "long_functions",
                                           "plot_report",
                                           "render_survey",
                                           "rviz_screenshot",
                                           "summarize_tests.py",
                                           "test",
                                           "tidy",
                                           "uav_block_process_bag",
                                           "hooks/notify_email",
                                           "hooks/notify_mqtt"};

void ExpectHelp(const std::string& program) {
  const fs::path dir = replay_test::Scratch("help_test", fs::path(program).filename().string());
  fs::create_directories(dir / "cwd");
  fs::create_directories(dir / "home");
  // The program runs in cwd (this process's working folder while it starts);
  // its stdout and stderr go to dir.
  const fs::path here = fs::current_path();
  fs::current_path(dir / "cwd");
  const pid_t pid = Spawn({program, "--help"}, dir, {"HOME=" + (dir / "home").string()});
  fs::current_path(here);
  // At most 60 s: a program that waits for something (replay_start for a
  // ROS master, before issue 38) fails here instead of hanging the suite.
  int status = pid > 0 ? -2 : -1;  // -1: not started
  for (int i = 0; i < 600 && status == -2; ++i) {
    int w = 0;
    if (waitpid(pid, &w, WNOHANG) == pid)
      status = WIFEXITED(w) ? WEXITSTATUS(w) : -1;
    else
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (status == -2) {
    kill(pid, SIGKILL);
    Wait(pid);
  }
  const std::string out = ReadFile(dir / "stdout"), err = ReadFile(dir / "stderr");
  EXPECT_EQ(status, 0) << program << " --help (-2: still running after 60 s):\n" << out << err;
  // The help on stdout (a usage error goes to stderr), nothing on stderr.
  EXPECT_GT(out.size(), 40u) << program << " --help printed no help on stdout:\n" << out << err;
  EXPECT_EQ(err, "") << program << " --help wrote on stderr";
  EXPECT_TRUE(fs::is_empty(dir / "cwd")) << program << " --help wrote into its working folder";
  EXPECT_TRUE(fs::is_empty(dir / "home")) << program << " --help wrote into HOME";
}

TEST(Help, EveryToolPrintsItsUsageAndChangesNothing) {
  const fs::path tools = fs::path(SM_PROCESS_BAG).parent_path();
  for (const std::string& t : kTools) ExpectHelp((tools / t).string());
}

TEST(Help, EveryScriptPrintsItsHelpAndChangesNothing) {
  for (const std::string& s : kScripts) ExpectHelp(std::string(SM_SOURCE_DIR) + "/scripts/" + s);
}

}  // namespace
}  // namespace slope_monitor
