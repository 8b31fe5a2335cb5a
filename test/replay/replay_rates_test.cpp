// replay.launch, run as a user does (roslaunch, its own master), on one
// small simulated survey (test/replay/replay_rates.sim.yaml: two fixed
// cameras, five radio transmitters, three epochs in four minutes of bag
// time) at two rates: the reports and the history are byte for byte the
// same, and the same as process_bag's on that bag (the graph and the
// offline processor are one product). Issue 16, "Determinism".
#include <sqlite3.h>

#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "slope_monitor/EpochMarker.h"

#include "replay_test_util.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using replay_test::ReadFile;
using replay_test::Spawn;
using replay_test::Survey;

const char kSurvey[] = "replay_rates";

// replay.launch on the survey at `rate`, with the launch file's defaults but
// for the survey's cameras (no UAV flight, so no dense surface either) and
// the outputs in `dir` (history.db, reports/).
int RunReplayLaunch(const fs::path& dir, int rate,
                    const std::string& bag = Survey(kSurvey, ".bag")) {
  std::vector<std::string> args = {"bag:=" + bag,
                                   "rate:=" + std::to_string(rate),
                                   "uav:=false",
                                   "dense:=false",
                                   "database:=" + (dir / "history.db").string(),
                                   "report_dir:=" + (dir / "reports").string()};
  if (fs::exists(Survey(kSurvey, ".site.yaml")))
    args.push_back("site_config:=" + Survey(kSurvey, ".site.yaml"));
  return replay_test::RunReplayLaunch(dir, args, "replay.launch rate " + std::to_string(rate));
}

// Observations in the history per source (1 target, 3 radio).
std::map<int, int> ObservationsBySource(const fs::path& db) {
  sqlite3* h = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << db;
  std::map<int, int> n;
  sqlite3_exec(
      h, "SELECT source, COUNT(*) FROM observations GROUP BY source",
      [](void* out, int, char** v, char**) {
        (*static_cast<std::map<int, int>*>(out))[std::stoi(v[0])] = std::stoi(v[1]);
        return 0;
      },
      &n, nullptr);
  sqlite3_close(h);
  return n;
}

TEST(ReplayLaunch, TwoRatesGiveTheReportsOfProcessBag) {
  const fs::path offline = replay_test::Scratch("replay_rates_test", "process_bag");
  ASSERT_EQ(replay_test::Wait(Spawn(replay_test::ProcessBagArgs(kSurvey, offline), offline)), 0)
      << ReadFile(offline / "stderr");
  // Both sources measured: targets in the two epochs after the reference,
  // radio in every block after the first.
  const std::map<int, int> sources = ObservationsBySource(offline / "history.db");
  EXPECT_GT(sources.count(1) ? sources.at(1) : 0, 0) << "no target observation";
  EXPECT_GT(sources.count(3) ? sources.at(3) : 0, 0) << "no radio observation";

  const fs::path fast = replay_test::Scratch("replay_rates_test", "rate_200");
  ASSERT_EQ(RunReplayLaunch(fast, 200), 0);
  const fs::path slow = replay_test::Scratch("replay_rates_test", "rate_20");
  ASSERT_EQ(RunReplayLaunch(slow, 20), 0);

  replay_test::ExpectSameResults(slow, fast, "replay.launch rate 20 vs rate 200");
  // The pictures are drawn by another renderer: replay.launch gives the
  // estimator scripts/plot_report (matplotlib, from the history), process_bag
  // draws them with OpenCV. Every other report and the history: byte for byte.
  replay_test::ExpectSameResults(offline, slow, "process_bag vs replay.launch rate 20", {".png"});
  EXPECT_EQ(ObservationsBySource(offline / "history.db"),
            ObservationsBySource(fast / "history.db"));
}

// A copy of `in` without the last end marker of `camera` (its last epoch
// then never ends by the messages). Returns that marker's epoch.
uint32_t WithoutLastEndMarker(const std::string& in, const std::string& out,
                              const std::string& camera) {
  rosbag::Bag src(in);
  rosbag::View view(src);
  const std::string topic = "/" + camera + "/camera/epoch";
  ros::Time last;
  uint32_t epoch = 0;
  for (const rosbag::MessageInstance& m : view) {
    if (m.getTopic() != topic) continue;
    const auto marker = m.instantiate<slope_monitor::EpochMarker>();
    if (marker && marker->end) {
      last = m.getTime();
      epoch = marker->epoch;
    }
  }
  rosbag::Bag dst(out, rosbag::bagmode::Write);
  for (const rosbag::MessageInstance& m : view) {
    if (m.getTopic() == topic && m.getTime() == last) continue;
    dst.write(m.getTopic(), m.getTime(), m, m.getConnectionHeader());
  }
  return epoch;
}

// The live graph has no time-out in a replay: an epoch whose camera never
// sends its end marker is solved at the end of the replay (replay_end's end
// of input, doc/nodes/replay_end.md) with what was collected, as process_bag
// solves it at the end of its bag: the same reports and history.
TEST(ReplayLaunch, AnEpochWithoutItsEndMarkerIsSolvedAtTheEndOfTheReplay) {
  const fs::path dir = replay_test::Scratch("replay_rates_test", "truncated");
  const std::string bag = (dir / "truncated.bag").string();
  const uint32_t epoch = WithoutLastEndMarker(Survey(kSurvey, ".bag"), bag, "fixed_cam_2");
  ASSERT_GT(epoch, 0u) << "no end marker of fixed_cam_2 in the survey";
  // The survey's files beside the bag, where both tools look for them.
  for (const char* ext : {".targets.yaml", ".truth.yaml"})
    fs::copy_file(Survey(kSurvey, ext), dir / (std::string("truncated") + ext));
  const fs::path offline = dir / "process_bag";
  fs::create_directories(offline);
  std::vector<std::string> args = replay_test::ProcessBagArgs(kSurvey, offline);
  args[2] = bag;  // --bag
  ASSERT_EQ(replay_test::Wait(Spawn(args, offline)), 0) << ReadFile(offline / "stderr");
  const fs::path live = dir / "replay";
  fs::create_directories(live);
  ASSERT_EQ(RunReplayLaunch(live, 200, bag), 0);
  EXPECT_NE(ReadFile(live / "stdout").find("end of the replay: solving the epoch still open"),
            std::string::npos)
      << "the bundle adjuster did not solve the open epoch at the end of the replay";
  replay_test::ExpectSameResults(offline, live, "process_bag vs replay.launch, truncated bag",
                                 {".png"});
  EXPECT_EQ(ObservationsBySource(offline / "history.db"),
            ObservationsBySource(live / "history.db"));
}

}  // namespace
}  // namespace slope_monitor
