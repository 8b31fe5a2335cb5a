// Running process_bag from a test (test/replay/*_test.cpp): the simulated
// surveys rendered at build time (SM_ROSTEST_DATA_DIR), a scratch folder per
// run, the tool started with stdout / stderr to files (posix_spawn, so a
// test can also kill it).
#pragma once

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace slope_monitor {
namespace process_bag_run {

namespace fs = std::filesystem;

inline std::string Survey(const std::string& name, const std::string& ext) {
  return std::string(SM_ROSTEST_DATA_DIR) + "/" + name + "/" + name + ext;
}

inline std::string ReadFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// A fresh directory for one run's outputs.
inline fs::path Scratch(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("process_bag_test_" + std::to_string(getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// Starts a process with stdout and stderr to files in `dir`.
inline pid_t Spawn(const std::vector<std::string>& argv, const fs::path& dir) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, (dir / "stdout").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&actions, 2, (dir / "stderr").c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  return rc == 0 ? pid : -1;
}

inline int Wait(pid_t pid) {
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// process_bag on `name`'s survey, outputs in `dir` (history.db, reports/, out.bag).
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

inline int RunProcessBag(const std::string& name, const fs::path& dir, bool output_bag = false) {
  std::vector<std::string> args = ProcessBagArgs(name, dir);
  if (output_bag) {
    args.push_back("--output-bag");
    args.push_back((dir / "out.bag").string());
  }
  const int status = Wait(Spawn(args, dir));
  if (status != 0) std::cerr << ReadFile(dir / "stderr");
  return status;
}

}  // namespace process_bag_run
}  // namespace slope_monitor
