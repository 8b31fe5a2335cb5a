// The targetless fixed camera on real photos nobody here made (issue 19):
// ImGRAFT's Columbia Glacier camera AK10 (test/data/timelapse_columbia,
// provenance in test/data/README.md), through scripts/compare_columbia as a
// crew runs it: resect_camera on the four picked control points, track_camera
// from the 2009-08-03 photo to the 08-04 one on the stable-land polygons onto
// a plane at 100 m, and the field's usable glacier probes against the
// published 24-day velocity grid 20090803_20090827_100m.tab.
// Truths checked: the resection's RMS equals the one computed by hand from
// the same points and parameters (doc/targetless_camera.md: 3.710 px); the
// camera barely moved in a day (the re-orientation is a few thousandths of a
// degree, on > 100 stable points at sub-pixel rms); our one-day speeds
// correlate with the published ones (r >= 0.9; measured 0.93) and differ by
// a median < 2 m/day (one day against a 24-day mean, a plane for the DEM);
// the stable-ground check probes stand still (median < 0.2 m/day).
#include <unistd.h>

#include <cmath>
#include <regex>
#include <string>

#include <gtest/gtest.h>

#include "run_command.h"

namespace {

double ColumbiaNumber(const std::string& text, const std::string& pattern) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(pattern))) {
    ADD_FAILURE() << "no line matching '" << pattern << "' in:\n" << text;
    return NAN;
  }
  return std::stod(m[1].str());
}

TEST(ColumbiaComparison, FieldAgainstThePublishedVelocities) {
  const std::string out = "/tmp/sm_columbia_" + std::to_string(getpid());
  const auto r = slope_monitor::run_command::Run(std::string(SM_SOURCE_DIR) +
                                                 "/scripts/compare_columbia --bin " + SM_TOOL_DIR +
                                                 " --out " + out);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NEAR(ColumbiaNumber(r.output, R"(RMS ([0-9.]+) px over 4 points)"), 3.710, 0.0015);
  EXPECT_LT(ColumbiaNumber(r.output, R"(rotation ([0-9.]+) deg \()"), 0.02);
  EXPECT_LT(ColumbiaNumber(r.output, R"(rms ([0-9.]+) px over [0-9]+ stable points)"), 0.6);
  EXPECT_GT(ColumbiaNumber(r.output, R"(rms [0-9.]+ px over ([0-9]+) stable points)"), 100);
  EXPECT_GT(ColumbiaNumber(r.output, R"(inside a published cell: ([0-9]+))"), 1000);
  EXPECT_GE(ColumbiaNumber(r.output, R"(speed correlation: r = ([0-9.]+))"), 0.9);
  EXPECT_LT(ColumbiaNumber(r.output, R"(median / 90 %: ([0-9.]+) /)"), 2.0);
  EXPECT_LT(ColumbiaNumber(r.output, R"(check probes: median speed ([0-9.]+) m/day)"), 0.2);
  slope_monitor::run_command::Run("rm -rf " + out);
}

}  // namespace
