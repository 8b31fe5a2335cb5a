// Running a tool or roslaunch from a test as a user runs it, from a shell:
// its exit status and its output (stdout and stderr, in order).
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace slope_monitor {
namespace run_command {

struct CommandRun {
  int status = -1;  // exit status; 128 + signal when killed
  std::string output;
};

// Runs `command` by /bin/sh with stderr folded into the output.
inline CommandRun Run(const std::string& command) {
  CommandRun r;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int w = pclose(p);
  r.status = WIFEXITED(w) ? WEXITSTATUS(w) : 128 + WTERMSIG(w);
  return r;
}

}  // namespace run_command
}  // namespace slope_monitor
