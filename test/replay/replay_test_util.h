// Helpers of the replay tests (process_bag_test.cpp, replay_rates_test.cpp):
// the surveys rendered at build time, starting a program as a user does
// (stdout and stderr to files), and the byte-for-byte comparison of two
// runs' reports and histories.
#pragma once

#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sqlite3.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "../ros/run_command.h"

extern char** environ;

namespace slope_monitor {
namespace replay_test {

namespace fs = std::filesystem;

// A survey rendered at build time: rostest_data/<name>/<name><ext>.
inline std::string Survey(const std::string& name, const std::string& ext) {
  return std::string(SM_ROSTEST_DATA_DIR) + "/" + name + "/" + name + ext;
}

// A copy of the rendered survey `from` as <dir>/<name>.bag with its side
// files (.truth.yaml, .targets.yaml and .site.yaml where present), each
// message handed to `copy`, which writes it to `out` (under any topic,
// edited or as it is) or leaves it out. Returns the bag's path.
inline std::string CopySurvey(
    const std::string& from, const fs::path& dir, const std::string& name,
    const std::function<void(const rosbag::MessageInstance&, rosbag::Bag* out)>& copy) {
  fs::create_directories(dir);
  const std::string stem = (dir / name).string();
  {
    rosbag::Bag in(Survey(from, ".bag"), rosbag::bagmode::Read);
    rosbag::Bag out(stem + ".bag", rosbag::bagmode::Write);
    for (const rosbag::MessageInstance& m : rosbag::View(in)) copy(m, &out);
  }
  for (const std::string ext : {".truth.yaml", ".targets.yaml", ".site.yaml"})
    if (fs::exists(Survey(from, ext)))
      fs::copy_file(Survey(from, ext), stem + ext, fs::copy_options::overwrite_existing);
  return stem + ".bag";
}

inline std::string ReadFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A fresh directory <tmp>/<prefix>_<pid>/<name> for one run's outputs.
inline fs::path Scratch(const std::string& prefix, const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / (prefix + "_" + std::to_string(getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Starts argv[0] (a path, or a name looked up in PATH) with stdout and
// stderr to files in `dir`; `env` entries ("KEY=value") are added to the
// environment. Returns the process id, -1 if it could not start.
inline pid_t Spawn(const std::vector<std::string>& argv, const fs::path& dir,
                   const std::vector<std::string>& env = {}) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, (dir / "stdout").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, (dir / "stderr").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  std::vector<std::string> env_strings(env);
  for (char** e = environ; *e; ++e) env_strings.push_back(*e);  // the first of a key wins
  std::vector<char*> envp;
  for (const std::string& e : env_strings) envp.push_back(const_cast<char*>(e.c_str()));
  envp.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  return rc == 0 ? pid : -1;
}

// Exit status, -1 if the process did not exit normally (killed).
inline int Wait(pid_t pid) {
  int status = 0;
  if (pid <= 0 || waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Every .json and .geojson file under `dir` (at least one) parses with
// Python's json module in strict mode: NaN and Infinity, which Python
// accepts by default but JSON does not have, are refused.
inline void ExpectStrictJson(const fs::path& dir) {
  std::vector<std::string> argv = {
      "/usr/bin/python3", "-c",
      "import json, sys\n"
      "def refuse(c): raise ValueError(c + ' is not JSON')\n"
      "bad = 0\n"
      "for path in sys.argv[1:]:\n"
      "    try: json.load(open(path, encoding='utf-8'), parse_constant=refuse)\n"
      "    except ValueError as e: print(path + ': ' + str(e), file=sys.stderr); bad += 1\n"
      "sys.exit(1 if bad else 0)"};
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    const std::string ext = e.path().extension().string();
    if (ext == ".json" || ext == ".geojson") argv.push_back(e.path().string());
  }
  ASSERT_GT(argv.size(), 3u) << "no JSON file under " << dir;
  const fs::path log = fs::temp_directory_path() / ("sm_strict_json_" + std::to_string(getpid()));
  fs::create_directories(log);
  EXPECT_EQ(Wait(Spawn(argv, log)), 0) << ReadFile(log / "stderr");
  fs::remove_all(log);
}

using run_command::FreePort;  // a TCP port for a run's own ROS master

// Waits for `pid` at most `timeout`; a process still running then gets
// SIGINT (roslaunch then stops its nodes), later SIGKILL. The exit status,
// -1 when it did not exit by itself in time.
inline int WaitAtMost(pid_t pid, std::chrono::seconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  int status = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    if (waitpid(pid, &status, WNOHANG) == pid) return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  kill(pid, SIGINT);
  std::this_thread::sleep_for(std::chrono::seconds(10));
  if (waitpid(pid, &status, WNOHANG) != pid) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
  }
  return -1;
}

// `roslaunch slope_monitor replay.launch` with `args` (name:=value), as a
// user runs it, stdout and stderr to files in `dir`; its own master on a
// free port and its own log folder, so that it meets no other test's graph.
// The exit status (printed with `what` and the time taken; the output too
// when not 0), -1 when it did not end within 180 s.
inline int RunReplayLaunch(const fs::path& dir, const std::vector<std::string>& args,
                           const std::string& what) {
  const int port = FreePort();
  EXPECT_GT(port, 0);
  std::vector<std::string> argv = {"roslaunch", "-p", std::to_string(port), "slope_monitor",
                                   "replay.launch"};
  argv.insert(argv.end(), args.begin(), args.end());
  const std::vector<std::string> env = {"ROS_MASTER_URI=http://127.0.0.1:" + std::to_string(port),
                                        "ROS_LOG_DIR=" + (dir / "log").string(),
                                        "ROS_HOME=" + (dir / "ros_home").string()};
  const auto start = std::chrono::steady_clock::now();
  const int status = WaitAtMost(Spawn(argv, dir, env), std::chrono::seconds(180));
  std::cout << what << ": exit " << status << " after "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
            << " s\n";
  if (status != 0) std::cerr << ReadFile(dir / "stdout") << ReadFile(dir / "stderr");
  return status;
}

// process_bag on `name`'s survey, outputs in `dir` (history.db, reports/).
inline std::vector<std::string> ProcessBagArgs(const std::string& name, const fs::path& dir) {
  std::vector<std::string> a = {SM_PROCESS_BAG,
                                "--bag",
                                Survey(name, ".bag"),
                                "--database",
                                (dir / "history.db").string(),
                                "--report-dir",
                                (dir / "reports").string()};
  if (fs::exists(Survey(name, ".site.yaml"))) {
    a.push_back("--site-config");
    a.push_back(Survey(name, ".site.yaml"));
  }
  return a;
}

// The wall-clock fields of the reports and the history (doc/testing.md), the
// only ones left out of the byte comparison: the GeoPackage's
// gpkg_contents.last_change (GDAL writes the time of writing), the history's
// meta 'created' and batches.received.
inline const std::set<std::string>& WallClockFields() {
  static const std::set<std::string> fields = {"gpkg_contents.last_change", "meta:created",
                                               "batches.received"};
  return fields;
}

// Every table of an SQLite file (history, GeoPackage) as text, rows in key
// order. Wall-clock fields are left out: `excluded` names them as
// "table.column" (a column) or "table:key" (the row whose first column is key).
inline std::string DumpSqlite(const fs::path& db, const std::set<std::string>& excluded) {
  sqlite3* h = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << db;
  std::vector<std::string> tables;
  sqlite3_exec(
      h, "SELECT name FROM sqlite_master WHERE type='table' ORDER BY name",
      [](void* out, int, char** v, char**) {
        static_cast<std::vector<std::string>*>(out)->push_back(v[0]);
        return 0;
      },
      &tables, nullptr);
  std::string dump;
  for (const std::string& t : tables) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(h, ("SELECT * FROM \"" + t + "\" ORDER BY 1").c_str(), -1, &st,
                           nullptr) != SQLITE_OK)
      continue;  // virtual tables of a GeoPackage (rtree) without their module
    dump += "table " + t + "\n";
    while (sqlite3_step(st) == SQLITE_ROW) {
      std::string row;
      for (int c = 0; c < sqlite3_column_count(st); ++c) {
        if (excluded.count(t + "." + sqlite3_column_name(st, c))) continue;
        const void* blob = sqlite3_column_blob(st, c);
        row += std::string(static_cast<const char*>(blob), sqlite3_column_bytes(st, c)) + "|";
      }
      const unsigned char* key = sqlite3_column_text(st, 0);
      if (key && excluded.count(t + ":" + reinterpret_cast<const char*>(key))) continue;
      dump += row + "\n";
    }
    sqlite3_finalize(st);
  }
  sqlite3_close(h);
  return dump;
}

// Two runs' outputs (`a` and `b`, each with history.db and reports/): every
// report file (in subfolders too) byte for byte (a GeoPackage as its SQL dump), the same set of
// files, and the history dump, less the wall-clock fields. Report files
// whose extension is in `skip` are left out of both. `what` names the pair
// in the failure messages.
inline void ExpectSameResults(const fs::path& a, const fs::path& b, const std::string& what,
                              const std::set<std::string>& skip = {}) {
  // Files in subfolders too (the UAV blocks' epoch_<n>/<camera>/...).
  const auto list = [&skip](const fs::path& dir) {
    std::set<std::string> files;
    for (const auto& f : fs::recursive_directory_iterator(dir))
      if (f.is_regular_file() && !skip.count(f.path().extension().string()))
        files.insert(fs::relative(f.path(), dir).string());
    return files;
  };
  const std::set<std::string> files = list(a / "reports");
  EXPECT_GE(files.size(), 4u) << what << ": reports in " << a / "reports";
  EXPECT_EQ(files, list(b / "reports")) << what << ": another set of report files";
  for (const std::string& f : files) {
    if (!fs::exists(b / "reports" / f)) continue;
    if (fs::path(f).extension() == ".gpkg") {
      const std::string dump = DumpSqlite(a / "reports" / f, WallClockFields());
      EXPECT_GT(dump.size(), 1000u) << f;
      EXPECT_TRUE(dump == DumpSqlite(b / "reports" / f, WallClockFields()))
          << what << ": report " << f << " differs";
    } else {
      EXPECT_TRUE(ReadFile(a / "reports" / f) == ReadFile(b / "reports" / f))
          << what << ": report " << f << " differs";
    }
  }
  const std::string dump = DumpSqlite(a / "history.db", WallClockFields());
  EXPECT_GT(dump.size(), 1000u);
  EXPECT_TRUE(dump == DumpSqlite(b / "history.db", WallClockFields()))
      << what << ": the histories differ";
}

}  // namespace replay_test
}  // namespace slope_monitor
