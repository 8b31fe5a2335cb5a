// Areas of significant surface change in the estimator: growth between
// epochs by hand (squares in site metres, default thresholds 25 / 100 m^2).
#include "slope_monitor/core/deformation/change_areas.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/alert_log.h"
#include "slope_monitor/core/deformation/estimator.h"

namespace slope_monitor {
namespace deformation {
namespace {

// A square of side `side` [m] with its south-west corner at (x, y).
ChangeArea Square(double x, double y, double side, int sign) {
  ChangeArea a;
  a.sign = sign;
  a.area = side * side;
  a.volume = sign * 0.5 * a.area;
  a.mean_change = sign * 0.5;
  a.outline = {{x, y}, {x + side, y}, {x + side, y + side}, {x, y + side}};
  return a;
}

AreaBatch Epoch(uint32_t epoch, std::vector<ChangeArea> areas) {
  AreaBatch b;
  b.epoch = epoch;
  b.stamp = 1.7e9 + epoch * 21600.0;
  b.source_name = "dense_matcher";
  b.areas = std::move(areas);
  return b;
}

TEST(ChangeAreas, GrowthBetweenEpochsRaisesWatchThenWarning) {
  Estimator estimator{EstimatorOptions()};
  // Epoch 1: a 5 m x 5 m loss (25 m^2): the baseline, no alert.
  ASSERT_TRUE(estimator.AddAreas(Epoch(1, {Square(0, 0, 5, -1)})));
  Snapshot s = estimator.GetSnapshot();
  ASSERT_EQ(s.areas.size(), 1u);
  EXPECT_EQ(s.areas[0].id, "e01/1");
  EXPECT_EQ(s.area_alert, AlertLevel::kNone);
  EXPECT_EQ(s.alert, AlertLevel::kNone);

  // Epoch 2: it grew to 8 m x 8 m (64 m^2, +39 m^2 > 25): watch.
  ASSERT_TRUE(estimator.AddAreas(Epoch(2, {Square(0, 0, 8, -1)})));
  s = estimator.GetSnapshot();
  ASSERT_EQ(s.areas.size(), 1u);
  EXPECT_DOUBLE_EQ(s.areas[0].growth, 64.0 - 25.0);
  EXPECT_EQ(s.areas[0].alert, AlertLevel::kWatch);
  EXPECT_EQ(s.area_alert, AlertLevel::kWatch);
  EXPECT_EQ(s.alert, AlertLevel::kWatch);  // the slope's level includes the areas

  // Epoch 3: 14 m x 14 m (196 m^2, +132 m^2 > 100): warning.
  ASSERT_TRUE(estimator.AddAreas(Epoch(3, {Square(0, 0, 14, -1)})));
  EXPECT_EQ(estimator.GetSnapshot().area_alert, AlertLevel::kWarning);

  // Epoch 4: the same area (no growth): the alert falls back.
  ASSERT_TRUE(estimator.AddAreas(Epoch(4, {Square(0, 0, 14, -1)})));
  s = estimator.GetSnapshot();
  EXPECT_DOUBLE_EQ(s.areas[0].growth, 0.0);
  EXPECT_EQ(s.area_alert, AlertLevel::kNone);

  // A late or re-delivered epoch is refused and changes nothing.
  EXPECT_FALSE(estimator.AddAreas(Epoch(4, {Square(50, 50, 20, 1)})));
  EXPECT_FALSE(estimator.AddAreas(Epoch(2, {})));
  EXPECT_EQ(estimator.GetSnapshot().areas.size(), 1u);
}

TEST(ChangeAreas, NewAreaCountsWholeAndSignsAreApart) {
  std::vector<AreaState> before =
      AssessAreas({}, std::nullopt, Epoch(1, {Square(0, 0, 5, -1)}), AreaOptions());
  // Epoch 2: the loss is unchanged; a gain of 6 x 6 m (36 m^2) appears on top
  // of it (other sign: not the same area) and a 3 x 3 m loss far away (9 m^2).
  const std::vector<AreaState> after = AssessAreas(
      before, 1u, Epoch(2, {Square(0, 0, 5, -1), Square(1, 1, 6, 1), Square(40, 40, 3, -1)}),
      AreaOptions());
  ASSERT_EQ(after.size(), 3u);  // largest first
  EXPECT_EQ(after[0].area.sign, 1);
  EXPECT_DOUBLE_EQ(after[0].growth, 36.0);
  EXPECT_EQ(after[0].alert, AlertLevel::kWatch);
  EXPECT_DOUBLE_EQ(after[1].growth, 0.0);
  EXPECT_DOUBLE_EQ(after[2].growth, 9.0);
  EXPECT_EQ(after[2].alert, AlertLevel::kNone);
  EXPECT_EQ(AreasAlert(after), AlertLevel::kWatch);
  EXPECT_NE(after[0].reason.find("grown by 36"), std::string::npos) << after[0].reason;
}

TEST(ChangeAreas, AreaAlertChangeIsLogged) {
  Estimator estimator{EstimatorOptions()};
  AlertChangeTracker tracker;
  estimator.AddAreas(Epoch(1, {Square(0, 0, 5, -1)}));
  EXPECT_TRUE(tracker.Update(estimator.GetSnapshot()).empty());
  estimator.AddAreas(Epoch(2, {Square(0, 0, 8, -1)}));
  const std::vector<AlertChange> changes = tracker.Update(estimator.GetSnapshot());
  ASSERT_EQ(changes.size(), 1u);
  EXPECT_EQ(changes[0].point_id, "surface");
  EXPECT_EQ(changes[0].to, AlertLevel::kWatch);
  EXPECT_NE(changes[0].text.find("area e02/1"), std::string::npos) << changes[0].text;
}

TEST(ChangeAreas, BadPolygonsAndThresholdsAreNamed) {
  ChangeArea line = Square(0, 0, 5, 1);
  line.outline.resize(2);
  try {
    AssessAreas({}, std::nullopt, Epoch(7, {Square(0, 0, 5, 1), line}), AreaOptions());
    FAIL() << "a 2-vertex outline was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("area epoch 7 polygon 2"), std::string::npos) << e.what();
  }
  EstimatorOptions o;
  o.areas.growth_warning = 10.0;  // below watch (25)
  EXPECT_THROW(Estimator{o}, ConfigError);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
