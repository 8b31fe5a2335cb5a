// ProgressLine (issue 38): a log file gets plain lines (no '\r', no ESC),
// a terminal the redrawn line; written to a temporary file and read back.
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/progress_line.h"

namespace slope_monitor {
namespace {

// What `write` printed through a ProgressLine on a temporary file.
template <typename F>
std::string Written(bool terminal, F write) {
  FILE* f = std::tmpfile();
  EXPECT_NE(f, nullptr);
  {
    ProgressLine line(f, terminal);
    write(line);
  }
  std::fflush(f);
  std::rewind(f);
  std::string out;
  for (int c; (c = std::fgetc(f)) != EOF;) out += static_cast<char>(c);
  std::fclose(f);
  return out;
}

void Session(ProgressLine& line) {
  if (line.Due()) line.Show("tool: 0 %");
  if (line.Due()) line.Show("tool: 50 %");  // within the interval: not shown
  line.Print("tool: a log line");
  if (line.Due(true)) line.Show("tool: 100 %");
  line.End();
}

TEST(ProgressLine, AFileGetsPlainLines) {
  // A file is no terminal: the constructor that asks isatty() takes it as a log.
  FILE* f = std::tmpfile();
  ASSERT_NE(f, nullptr);
  EXPECT_FALSE(ProgressLine(f).terminal());
  std::fclose(f);
  EXPECT_EQ(Written(false, Session), "tool: 0 %\ntool: a log line\ntool: 100 %\n");
}

TEST(ProgressLine, ATerminalGetsTheLineRedrawn) {
  EXPECT_EQ(Written(true, Session),
            "\rtool: 0 %\033[K\r\033[Ktool: a log line\n\rtool: 100 %\033[K\n");
}

}  // namespace
}  // namespace slope_monitor
