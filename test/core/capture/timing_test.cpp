#include "slope_monitor/core/capture/timing.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

constexpr double kDay = 86400.0;
constexpr double kMay1st0h = 1714521600.0;  // 2024-05-01 00:00:00 UTC

TEST(CaptureSchedule, IntervalAlignedToTheClock) {
  ScheduleOptions o;
  o.interval = 300.0;
  CaptureSchedule s(o);
  EXPECT_DOUBLE_EQ(*s.NextCapture(kMay1st0h), kMay1st0h + 300.0);  // strictly after
  EXPECT_DOUBLE_EQ(*s.NextCapture(kMay1st0h + 1.0), kMay1st0h + 300.0);
  EXPECT_DOUBLE_EQ(*s.NextCapture(kMay1st0h + 299.9), kMay1st0h + 300.0);
  ScheduleOptions trigger_only;
  EXPECT_FALSE(CaptureSchedule(trigger_only).NextCapture(kMay1st0h).has_value());
}

TEST(CaptureSchedule, DailyWindowsInLocalTime) {
  ScheduleOptions o;
  o.interval = 3600.0;
  o.windows = {"06:00-08:30", "22:00-02:00"};  // the second wraps midnight
  o.utc_offset_hours = 9.0;                    // local = UTC + 9 h
  CaptureSchedule s(o);
  // 06:00 local = 21:00 UTC the day before.
  EXPECT_TRUE(s.InWindow(kMay1st0h - 3 * 3600.0));
  EXPECT_FALSE(s.InWindow(kMay1st0h - 3 * 3600.0 - 1.0));
  EXPECT_TRUE(s.InWindow(kMay1st0h - 3600.0 + 1799.0));       // 08:29:59 local
  EXPECT_FALSE(s.InWindow(kMay1st0h - 3600.0 + 1800.0));      // 08:30 local: end excluded
  EXPECT_TRUE(s.InWindow(kMay1st0h + 13 * 3600.0));           // 22:00 local
  EXPECT_TRUE(s.InWindow(kMay1st0h + 16 * 3600.0 + 3599.0));  // 01:59:59 local
  EXPECT_FALSE(s.InWindow(kMay1st0h + 17 * 3600.0));          // 02:00 local
  // From 09:00 local (00:00 UTC), the next hourly capture in a window is 22:00 local = 13:00 UTC.
  EXPECT_DOUBLE_EQ(*s.NextCapture(kMay1st0h), kMay1st0h + 13 * 3600.0);
  // From 01:00 local (16:00 UTC): 02:00 local is outside, so 06:00 local = 21:00 UTC.
  EXPECT_DOUBLE_EQ(*s.NextCapture(kMay1st0h + 16 * 3600.0), kMay1st0h + 21 * 3600.0);
}

TEST(CaptureSchedule, BadOptionsNameTheKey) {
  ScheduleOptions o;
  o.interval = 0.5;
  try {
    CaptureSchedule s(o);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("schedule/interval"), std::string::npos);
  }
  o.interval = 60.0;
  o.windows = {"6-8"};
  try {
    CaptureSchedule s(o);
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'6-8'"), std::string::npos);
  }
  o.windows = {"25:00-26:00"};
  EXPECT_THROW(CaptureSchedule s(o), ConfigError);
  o.windows = {};
  o.frames_per_epoch = 0;
  EXPECT_THROW(CaptureSchedule s(o), ConfigError);
  EXPECT_THROW(CaptureSchedule(ScheduleOptions{kDay * 30, {}, 0.0, 1}), ConfigError);
}

TEST(EpochTracker, GapsWithoutLookAhead) {
  EpochOptions o;
  o.gap = 10.0;
  o.first_epoch = 5;
  EpochTracker t(o);
  auto ev = t.BeforeFrame(0.0);
  ASSERT_EQ(ev.size(), 1u);
  EXPECT_FALSE(ev[0].end);
  EXPECT_EQ(ev[0].epoch, 5u);
  EXPECT_TRUE(t.AfterFrame(std::nullopt, false).empty());  // next unknown: stays open
  EXPECT_TRUE(t.BeforeFrame(10.0).empty());                // gap == threshold: same epoch
  ev = t.BeforeFrame(20.5);                                // gap 10.5 > 10: new epoch
  ASSERT_EQ(ev.size(), 2u);
  EXPECT_TRUE(ev[0].end);
  EXPECT_EQ(ev[0].epoch, 5u);
  EXPECT_EQ(ev[0].count, 2u);
  EXPECT_DOUBLE_EQ(ev[0].stamp, 10.0);
  EXPECT_FALSE(ev[1].end);
  EXPECT_EQ(ev[1].epoch, 6u);
  const auto end = t.Close();
  ASSERT_TRUE(end.has_value());
  EXPECT_EQ(end->epoch, 6u);
  EXPECT_EQ(end->count, 1u);
  EXPECT_FALSE(t.Close().has_value());
  EXPECT_THROW(EpochTracker(EpochOptions{0.0, 0.0, 0}), ConfigError);
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
