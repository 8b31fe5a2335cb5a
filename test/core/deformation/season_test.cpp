// A crew's season in the estimator: the first displacement after
// the reference already gives a speed (the reference's exact zero enters
// each filter), cumulative displacement raises alerts where speed does not
// (flights weeks apart), and recordings processed in any order give the
// state of processing them in time order, with or without a history.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <sqlite3.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/history.h"

namespace slope_monitor {
namespace deformation {
namespace {

constexpr double kSeasonT0 = 1700000000.0;
constexpr double kSeasonDay = 86400.0;

// One source's measurement of `ids` at t0 + dt: each moved `d` [m] south, sigma per axis.
Batch Epoch(uint32_t epoch, double dt, const std::vector<std::string>& ids, double d, double sigma,
            Source source = Source::kTarget) {
  Batch b;
  b.epoch = epoch;
  b.stamp = kSeasonT0 + dt;
  for (const std::string& id : ids) {
    Measurement m;
    m.point_id = id;
    m.source = source;
    m.source_name = "/bundle_adjuster";
    m.epoch = epoch;
    m.stamp = b.stamp;
    m.reference_stamp = kSeasonT0;
    m.displacement = Eigen::Vector3d(0.0, -d, 0.0);
    m.covariance = Eigen::Matrix3d::Identity() * sigma * sigma;
    b.measurements.push_back(m);
  }
  return b;
}

const PointState& Point(const Snapshot& s, const std::string& id) {
  for (const PointState& p : s.points)
    if (p.id == id) return p;
  throw InvalidArgument("no point " + id);
}

// The demo's circle/10 at epoch 1: 57 mm in 6 h, sigma 4 mm. From the
// reference's zero: speed d / dt = 228 mm/day (the diffuse velocity prior
// leaves it as the data give it), sigma at least sigma_d / dt = 16 mm/day.
// Two such points confirm each other: alarm (50 mm/day) at the first movement.
TEST(Season, FirstDisplacementGivesSpeedAndAlert) {
  EstimatorOptions o;
  o.filter.jerk_spectral_density = 1e-25;  // the monitoring graph's (ros/node_parameters.h)
  Estimator e(o);
  e.AddBatch(Epoch(1, 0.25 * kSeasonDay, {"a", "b"}, 0.057, 0.004));
  const Snapshot s = e.GetSnapshot();
  const double mm_per_day = 1e3 * kSeasonDay;
  for (const char* id : {"a", "b"}) {
    const PointState& p = Point(s, id);
    EXPECT_NEAR(p.speed * mm_per_day, 228.0, 2.0) << id;
    EXPECT_GE(p.speed_sigma * mm_per_day, 16.0) << id;
    EXPECT_LT(p.speed_sigma * mm_per_day, 60.0) << id;
    EXPECT_EQ(p.alert, AlertLevel::kAlarm) << id << ": " << p.alert_reason;
    EXPECT_NEAR(p.displacement.y(), -0.057, 0.0005) << id;  // the measurement, not pulled to zero
  }
}

// A UAV-only site flown every 30 days, 20 mm between flights (0.67 mm/day:
// under the 2 mm/day watch speed): the displacement threshold (10 mm by
// 3 sigma) raises watch at the second flight, and the reason says so.
TEST(Season, DisplacementThresholdAlertsSlowMovementBetweenFlights) {
  Estimator e{EstimatorOptions()};
  e.AddBatch(Epoch(1, 30 * kSeasonDay, {"a", "b"}, 0.020, 0.002));
  const Snapshot s = e.GetSnapshot();
  for (const char* id : {"a", "b"}) {
    const PointState& p = Point(s, id);
    EXPECT_LT(p.speed * 1e3 * kSeasonDay, 2.0) << id;
    EXPECT_EQ(p.alert, AlertLevel::kWatch) << id << ": " << p.alert_reason;
    EXPECT_NE(p.alert_reason.find("displacement 20.0"), std::string::npos) << p.alert_reason;
  }
  // Below the threshold by 3 sigma: nothing.
  Estimator quiet{EstimatorOptions()};
  quiet.AddBatch(Epoch(1, 30 * kSeasonDay, {"a", "b"}, 0.012, 0.002));
  EXPECT_EQ(quiet.GetSnapshot().alert, AlertLevel::kNone);
  Thresholds bad;
  bad.displacement_warning = bad.displacement_watch;
  EXPECT_THROW(bad.Check("t"), ConfigError);
}

// Recordings weeks apart (beyond the 3-day reorder window) processed as
// 1, 3, 2 give, bit for bit, the state of 1, 2, 3.
TEST(Season, RecordingsInAnyOrderGiveTheInOrderState) {
  const std::vector<std::string> ids = {"a", "b", "c"};
  std::vector<Batch> rec = {Epoch(1, 20 * kSeasonDay, ids, 0.010, 0.002),
                            Epoch(2, 40 * kSeasonDay, ids, 0.024, 0.002),
                            Epoch(3, 60 * kSeasonDay, ids, 0.050, 0.002)};
  Estimator in_order{EstimatorOptions()}, shuffled{EstimatorOptions()};
  for (const Batch& b : rec) in_order.AddBatch(b);
  shuffled.AddBatch(rec[0]);
  shuffled.AddBatch(rec[2]);
  const BatchSummary late = shuffled.AddBatch(rec[1]);
  EXPECT_EQ(late.accepted, 3);
  EXPECT_EQ(late.refused, 0);
  EXPECT_GE(shuffled.reruns(), 1u);
  const Snapshot a = in_order.GetSnapshot(), b = shuffled.GetSnapshot();
  for (const std::string& id : ids) {
    EXPECT_EQ(Point(a, id).displacement, Point(b, id).displacement) << id;
    EXPECT_EQ(Point(a, id).velocity, Point(b, id).velocity) << id;
    EXPECT_EQ(Point(a, id).alert, Point(b, id).alert) << id;
    EXPECT_EQ(Point(a, id).num_measurements, 3u) << id;
  }
  // Again: nothing added, each measurement named as already received.
  const BatchSummary again = shuffled.AddBatch(rec[1]);
  EXPECT_EQ(again.accepted, 0);
  EXPECT_EQ(again.already_held, 3);
  EXPECT_TRUE(again.messages.empty());
}

// A revised measurement (the radio's epochs tracked again) replaces the one
// held, in the history too: the state is that of the revised values.
TEST(Season, RevisedMeasurementsReplaceTheHeldOnes) {
  const std::vector<std::string> ids = {"a"};
  Estimator direct{EstimatorOptions()};
  direct.AddBatch(Epoch(1, 1 * kSeasonDay, ids, 0.010, 0.002, Source::kRadio));
  direct.AddBatch(Epoch(2, 2 * kSeasonDay, ids, 0.021, 0.002, Source::kRadio));
  const std::string path = "/tmp/season_revise_" + std::to_string(::getpid()) + ".db";
  std::remove(path.c_str());
  {
    History h(path);
    Estimator e(EstimatorOptions(), &h);
    e.AddBatch(Epoch(1, 1 * kSeasonDay, ids, 0.010, 0.002, Source::kRadio));
    e.AddBatch(Epoch(2, 2 * kSeasonDay, ids, 0.025, 0.002, Source::kRadio));
    const BatchSummary r =
        e.ReviseBatch(Epoch(2, 2 * kSeasonDay, ids, 0.021, 0.002, Source::kRadio));
    EXPECT_EQ(r.revised, 1);
    EXPECT_EQ(h.CountRows("observations"), 2);
    EXPECT_EQ(Point(e.GetSnapshot(), "a").displacement,
              Point(direct.GetSnapshot(), "a").displacement);
  }
  {
    History h(path);  // the revision was stored
    Estimator e(EstimatorOptions(), &h);
    EXPECT_EQ(Point(e.GetSnapshot(), "a").displacement,
              Point(direct.GetSnapshot(), "a").displacement);
  }
  for (const char* suffix : {"", "-wal", "-shm", ".lock"}) std::remove((path + suffix).c_str());
}

// The history belongs to one site and keeps its reference: another site is
// refused naming both; a history whose reference is missing is refused and
// left as it was; a new reference on request keeps the observations and
// measures from the next recording's reference.
TEST(Season, HistoryOfOneSiteWithItsReference) {
  const std::string path = "/tmp/season_site_" + std::to_string(::getpid()) + ".db";
  std::remove(path.c_str());
  {
    History h(path);
    h.CheckSite("north_slope");
    h.CheckSite("north_slope");
    try {
      h.CheckSite("south_slope");
      ADD_FAILURE() << "another site's recording was taken";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("'south_slope'"), std::string::npos) << what;
      EXPECT_NE(what.find("'north_slope'"), std::string::npos) << what;
    }
    Estimator e(EstimatorOptions(), &h);
    e.AddBatch(Epoch(1, 1 * kSeasonDay, {"a"}, 0.010, 0.002));
    EXPECT_EQ(*h.Meta("datum_stamp"), "1700000000.000000");
    h.CheckReference();
  }
  {
    History h(path);
    h.StartNewReference();
    Estimator e(EstimatorOptions(), &h);
    EXPECT_TRUE(e.GetSnapshot().points.empty());  // the old reference's observations wait out
    Batch later = Epoch(2, 10 * kSeasonDay, {"a"}, 0.004, 0.002);
    for (Measurement& m : later.measurements) m.reference_stamp = kSeasonT0 + 5 * kSeasonDay;
    EXPECT_EQ(e.AddBatch(later).accepted, 1);
    EXPECT_EQ(*h.Meta("datum_stamp"), "1700432000.000000");
    EXPECT_NEAR(Point(e.GetSnapshot(), "a").displacement.y(), -0.004, 1e-4);
    EXPECT_EQ(h.CountRows("observations"), 2);
  }
  {
    // Its reference removed (an edited file): refused, naming the file.
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(
        sqlite3_exec(db, "DELETE FROM meta WHERE key = 'datum_stamp'", nullptr, nullptr, nullptr),
        SQLITE_OK);
    sqlite3_close(db);
    History h(path);
    try {
      h.CheckReference();
      ADD_FAILURE() << "a history without its reference was taken";
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("no reference epoch"), std::string::npos) << e.what();
    }
    EXPECT_EQ(h.CountRows("observations"), 2);
  }
  for (const char* suffix : {"", "-wal", "-shm", ".lock"}) std::remove((path + suffix).c_str());
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
