// One writer per history (issue 38): two process_bag runs started at the
// same time on one --database (the replay_rates survey, three camera epochs
// and radio blocks: seconds a run). Before, both ran to the end and the
// history held every observation twice. Now one runs, the other ends at once
// with exit status 1 and one line naming the database and the first run's
// process id, and the history holds each (source, epoch, point) once.
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "process_bag_run.h"
#include "replay_test_util.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using namespace process_bag_run;  // NOLINT: the test helpers

// (source, epoch, point) -> how many observations of it the history holds.
std::map<std::string, int> StoredObservations(const fs::path& db) {
  sqlite3* h = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << db;
  std::map<std::string, int> keys;
  sqlite3_exec(
      h, "SELECT source, epoch, point_id FROM observations",
      [](void* out, int, char** v, char**) {
        ++(*static_cast<std::map<std::string, int>*>(
            out))[std::string(v[0]) + "/" + v[1] + "/" + v[2]];
        return 0;
      },
      &keys, nullptr);
  sqlite3_close(h);
  return keys;
}

TEST(ProcessBagLock, SecondWriterOnOneDatabaseFailsAtOnce) {
  const std::string name = "replay_rates";
  const fs::path dir = Scratch("lock");
  const fs::path db = dir / "history.db";
  // Each run its own folder (stdout, stderr, reports), one database.
  std::vector<fs::path> runs = {dir / "a", dir / "b"};
  std::vector<pid_t> pids;
  for (const fs::path& run : runs) {
    fs::create_directories(run);
    std::vector<std::string> args = ProcessBagArgs(name, run);
    for (size_t i = 0; i + 1 < args.size(); ++i)
      if (args[i] == "--database") args[i + 1] = db.string();
    pids.push_back(Spawn(args, run));
    ASSERT_GT(pids.back(), 0);
  }
  // Which ends first, and with what.
  std::vector<int> status(2, -2);
  std::vector<double> ended(2, 0.0);
  const auto start = std::chrono::steady_clock::now();
  while ((status[0] == -2 || status[1] == -2) &&
         std::chrono::steady_clock::now() - start < std::chrono::minutes(5)) {
    for (int k = 0; k < 2; ++k) {
      int w = 0;
      if (status[k] == -2 && waitpid(pids[k], &w, WNOHANG) == pids[k]) {
        status[k] = WIFEXITED(w) ? WEXITSTATUS(w) : -1;
        ended[k] = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  for (int k = 0; k < 2; ++k)
    if (status[k] == -2) kill(pids[k], SIGKILL);
  ASSERT_NE(status[0], -2);
  ASSERT_NE(status[1], -2);
  ASSERT_TRUE((status[0] == 0) != (status[1] == 0))
      << "exit statuses " << status[0] << " and " << status[1] << "\n"
      << ReadFile(runs[0] / "stderr") << ReadFile(runs[1] / "stderr");
  const int ran = status[0] == 0 ? 0 : 1, refused = 1 - ran;
  EXPECT_EQ(status[refused], 1);
  const std::string err = ReadFile(runs[refused] / "stderr");
  std::cout << "the refused run said: " << err;
  EXPECT_EQ(err,
            "process_bag: history database '" + db.string() + "' is in use by process " +
                std::to_string(pids[ran]) + " (process_bag), which holds its writer lock '" +
                db.string() +
                ".lock'; one writer per history: wait for it to end or use another database\n");
  EXPECT_LT(ended[refused], ended[ran]) << "the refused run did not end before the other";
  std::cout << "refused after " << ended[refused] << " s, the other run took " << ended[ran]
            << " s\n";

  const auto stored = StoredObservations(db);
  EXPECT_GT(stored.size(), 10u);
  for (const auto& [key, n] : stored) EXPECT_EQ(n, 1) << key << " stored " << n << " times";
}

// Safe defaults, on bags cut to their first
// messages (no epoch: nothing is solved, a run takes about a second):
//   * without --database every recording of a site keeps the site's one
//     history, ~/.ros/slope_monitor/<site name>.db (the name make_survey_bag
//     wrote beside the bags), and the first line says so; a recording
//     nothing names keeps the history of its own name;
//   * --target-list takes a surveyors' CSV (was: "YAML file '…csv' must hold a map");
//   * the progress goes to a log as plain lines, no '\r', no ESC[K;
//   * a run that solves nothing exits 1 (nothing produced; was 2).
TEST(ProcessBagDefaults, OneHistoryPerSiteACsvTargetListPlainProgress) {
  const fs::path dir = Scratch("defaults");
  const fs::path home = dir / "home";
  fs::create_directories(home);
  // Bag a: the static transforms, the first photo of fixed_cam_1 and its
  // camera_info; bag b: only the transforms and the camera_infos; bag c as
  // b without the files beside it (nothing names its site).
  int photos = 0;
  const std::string bag_a = CopySurvey(
      "replay_rates", dir, "site_a", [&photos](const rosbag::MessageInstance& m, rosbag::Bag* out) {
        const std::string& t = m.getTopic();
        if (t == "/tf_static" || (t.rfind("/fixed_cam_1/camera/", 0) == 0 &&
                                  t.find("/epoch") == std::string::npos && photos < 2)) {
          photos += t != "/tf_static";
          out->write(t, m.getTime(), m);
        }
      });
  auto transforms_and_infos = [](const rosbag::MessageInstance& m, rosbag::Bag* out) {
    const std::string& t = m.getTopic();
    if (t == "/tf_static" || t.find("/camera_info") != std::string::npos)
      out->write(t, m.getTime(), m);
  };
  const std::string bag_b = CopySurvey("replay_rates", dir, "site_b", transforms_and_infos);
  const std::string bag_c = CopySurvey("replay_rates", dir, "site_c", transforms_and_infos);
  for (const char* ext : {".truth.yaml", ".site.yaml"})
    fs::remove(dir / ("site_c" + std::string(ext)));
  // The surveyors' CSV of doc/your_own_site.md, in the site frame.
  const fs::path csv = dir / "targets.csv";
  std::ofstream(csv) << "# crs: site\nid,role,x,y,z,sigma_h,sigma_v\n"
                        "tag36h11/0,control,0.0,0.0,0.0,0.010,0.020\n"
                        "tag36h11/1,monitoring,5.0,5.0,1.0,0.30,0.50\n";
  const std::string site_history = (home / ".ros/slope_monitor/replay_rates.db").string();
  for (const std::string& bag : {bag_a, bag_b, bag_c}) {
    const fs::path run = dir / fs::path(bag).stem();
    fs::create_directories(run);
    const int status = Wait(Spawn({SM_PROCESS_BAG, "--bag", bag, "--target-list", csv.string(),
                                   "--report-dir", (run / "reports").string()},
                                  run, {"HOME=" + home.string()}));
    const std::string err = ReadFile(run / "stderr");
    std::cout << fs::path(bag).filename().string() << ": exit " << status << ", stderr:\n" << err;
    EXPECT_EQ(status, 1) << "nothing solved is nothing produced";
    EXPECT_NE(err.find("process_bag: nothing solved: "), std::string::npos) << err;
    EXPECT_EQ(err.find("must hold a map"), std::string::npos) << "the CSV was refused:\n" << err;
    EXPECT_NE(err.find("process_bag: bag time "), std::string::npos) << "no progress line:\n"
                                                                     << err;
    EXPECT_EQ(err.find('\r'), std::string::npos) << "a carriage return in the log";
    EXPECT_EQ(err.find('\033'), std::string::npos) << "an escape sequence in the log";
    // The first line: which history, of which site.
    const std::string expected =
        bag == bag_c
            ? "process_bag: history '" + (home / ".ros/slope_monitor/site_c.db").string() +
                  "' of site '(unnamed)': a new history"
            : "process_bag: history '" + site_history + "' of site 'replay_rates': a new history";
    EXPECT_EQ(err.rfind(expected, 0), 0u) << err;
  }
  EXPECT_TRUE(fs::is_regular_file(site_history));
  EXPECT_FALSE(fs::exists(home / ".ros/slope_monitor/site_a.db")) << "a history per recording";
  EXPECT_FALSE(fs::exists(home / ".ros/slope_monitor/site_b.db")) << "a history per recording";
  EXPECT_TRUE(fs::is_regular_file(home / ".ros/slope_monitor/site_c.db"));
}

}  // namespace
}  // namespace slope_monitor
