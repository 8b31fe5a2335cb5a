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

}  // namespace
}  // namespace slope_monitor
