// Runs an external program with a time limit: its standard input from a
// string, its standard output captured (standard error is inherited, so its
// messages reach the caller's log). Started by posix_spawnp (a bare name is
// looked up in PATH); killed (SIGKILL) when it outlives the time limit.
//
//   RunResult r = RunProgram({"/usr/bin/python3", "script.py", "--out", dir}, "", 60.0);
//   if (!r.ok()) throw IoError("script failed: " + r.failure);
#pragma once

#include <string>
#include <vector>

namespace slope_monitor {

struct RunResult {
  std::string output;   // what it wrote to stdout
  std::string failure;  // "" when it exited 0; else why not ("exit status 2", "no exit within 5 s
                        // (killed)", ...)
  bool ok() const { return failure.empty(); }
};

// argv[0] is the program. `input` goes to its stdin (then closed); at most
// 4096 bytes (InvalidArgument otherwise), so writing it never blocks.
RunResult RunProgram(const std::vector<std::string>& argv, const std::string& input,
                     double timeout);

}  // namespace slope_monitor
