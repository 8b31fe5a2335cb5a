// A progress line for the command-line tools (process_bag, make_survey_bag),
// one rule for all of them: on a terminal the line is redrawn in
// place ('\r', and "ESC[K" to clear it before a log line); written to
// anything else (a log file, a pipe) it is a plain line of its own, now and
// then, with no carriage return and no escape sequence.
//
//   ProgressLine progress(stderr);
//   for (...) if (progress.Due()) progress.Show("tool: 40 % ...");
//   progress.Print("tool: a log line");   // on a line of its own
//   if (progress.Due(true)) progress.Show("tool: 100 %");
//   progress.End();
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

namespace slope_monitor {

struct ProgressLineOptions {
  double terminal_interval = 0.2;  // [s] least time between two redraws on a terminal
  double log_interval = 30.0;      // [s] least time between two plain progress lines elsewhere
};

class ProgressLine {
 public:
  // `out` is a terminal when isatty() says so.
  explicit ProgressLine(FILE* out, const ProgressLineOptions& options = {});
  // `terminal` given (the tests).
  ProgressLine(FILE* out, bool terminal, const ProgressLineOptions& options = {});

  // Whether a progress line is to be shown now (the interval since the last
  // one has passed, or `force`: the final state); if so, the time is noted.
  bool Due(bool force = false);
  // The progress (one line, no '\n'): redrawn in place on a terminal, a plain line elsewhere.
  void Show(const std::string& text);
  // A line of its own; on a terminal the progress line is cleared first.
  void Print(const std::string& text);
  // Ends a progress line left open on a terminal.
  void End();
  bool terminal() const { return terminal_; }

 private:
  FILE* out_;
  bool terminal_;
  ProgressLineOptions options_;
  bool drawn_ = false;  // a progress line is open on the terminal
  bool shown_ = false;  // a line was shown (Due's interval counts from it)
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace slope_monitor
