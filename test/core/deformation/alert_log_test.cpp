// Alert level changes name the point, both levels, the speed and the
// forecast, once per change.
#include "slope_monitor/core/deformation/alert_log.h"

#include <gtest/gtest.h>

namespace slope_monitor {
namespace deformation {
namespace {

PointState Point(const std::string& id, AlertLevel level, double speed_mm_per_day) {
  PointState p;
  p.id = id;
  p.alert = level;
  p.speed = speed_mm_per_day / 86400e3;
  p.speed_sigma = 0.5 / 86400e3;
  return p;
}

TEST(AlertLog, OneLinePerChangeWithPointLevelSpeedAndForecast) {
  AlertChangeTracker tracker;
  Snapshot s;
  s.points = {Point("rock", AlertLevel::kNone, 0.1), Point("tag36h11/3", AlertLevel::kWatch, 3.0)};
  std::vector<AlertChange> c = tracker.Update(s);
  ASSERT_EQ(c.size(), 1u);  // the standing watch is announced, the quiet rock is not
  EXPECT_EQ(c[0].point_id, "tag36h11/3");
  EXPECT_EQ(
      c[0].text.rfind(
          "point tag36h11/3: alert none -> watch, speed 3.00 +- 0.50 mm/day, no failure forecast",
          0),
      0u)
      << c[0].text;
  EXPECT_TRUE(tracker.Update(s).empty());  // no change, no line

  s.points[1] = Point("tag36h11/3", AlertLevel::kAlarm, 80.0);
  s.points[1].forecast.valid = true;
  s.points[1].forecast.failure_time = 1700000000.0 + 5400.0;  // 2023-11-14T23:43:20Z
  s.points[1].forecast.sigma = 1800.0;
  c = tracker.Update(s);
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].from, AlertLevel::kWatch);
  EXPECT_EQ(c[0].to, AlertLevel::kAlarm);
  EXPECT_EQ(c[0].text,
            "point tag36h11/3: alert watch -> alarm, speed 80.00 +- 0.50 mm/day, failure forecast "
            "2023-11-14T23:43:20Z +- 0.5 h");
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
