#include "slope_monitor/core/common/progress_line.h"

#include <unistd.h>

namespace slope_monitor {

ProgressLine::ProgressLine(FILE* out, const ProgressLineOptions& options)
    : ProgressLine(out, isatty(fileno(out)) == 1, options) {}

ProgressLine::ProgressLine(FILE* out, bool terminal, const ProgressLineOptions& options)
    : out_(out), terminal_(terminal), options_(options) {}

bool ProgressLine::Due(bool force) {
  const auto now = std::chrono::steady_clock::now();
  const double interval = terminal_ ? options_.terminal_interval : options_.log_interval;
  if (!force && shown_ && std::chrono::duration<double>(now - last_).count() < interval)
    return false;
  last_ = now;
  shown_ = true;
  return true;
}

void ProgressLine::Show(const std::string& text) {
  if (terminal_) {
    std::fprintf(out_, "\r%s\033[K", text.c_str());
    drawn_ = true;
  } else {
    std::fprintf(out_, "%s\n", text.c_str());
  }
  std::fflush(out_);
}

void ProgressLine::Print(const std::string& text) {
  std::fprintf(out_, "%s%s\n", drawn_ ? "\r\033[K" : "", text.c_str());
  drawn_ = false;
}

void ProgressLine::End() {
  if (drawn_) std::fprintf(out_, "\n");
  drawn_ = false;
}

}  // namespace slope_monitor
