// Running process_bag from a test (test/replay/*_test.cpp) on the simulated
// surveys rendered at build time: a scratch folder per run and the tool
// started as a user does (the helpers of replay_test_util.h).
#pragma once

#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "replay_test_util.h"

namespace slope_monitor {
namespace process_bag_run {

namespace fs = std::filesystem;
using replay_test::CopySurvey;
using replay_test::ProcessBagArgs;
using replay_test::ReadFile;
using replay_test::Spawn;
using replay_test::Survey;
using replay_test::Wait;

// A fresh directory for one run's outputs.
inline fs::path Scratch(const std::string& name) {
  return replay_test::Scratch("process_bag_test", name);
}

// process_bag on `name`'s survey, outputs in `dir` (history.db, reports/,
// out.bag with output_bag); its stderr printed when it fails.
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
