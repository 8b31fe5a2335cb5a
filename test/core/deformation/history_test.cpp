// SQLite history: kill-and-restart equivalence, commit before use, a corrupt
// file refused untouched, schema migration from version 1.
#include <cstdio>
#include <fstream>
#include <iterator>

#include <gtest/gtest.h>
#include <sqlite3.h>
#include <unistd.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/history.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

using testing::kDay;
using testing::kT0;

std::string TempPath(const std::string& name) {
  const std::string p = "/tmp/sm_deformation_" + std::to_string(getpid()) + "_" + name;
  for (const char* suffix : {"", "-wal", "-shm"}) std::remove((p + suffix).c_str());
  return p;
}

std::vector<Batch> HistoryScenario() {
  testing::Motion m1, m2;
  m1.v0 = 10e-3 / kDay;
  m1.accelerating = true;
  m1.failure_time = kT0 + 6 * kDay;
  m2.v0 = 0.0;
  testing::SourceSpec radio;
  radio.interval = 3 * 3600.0;  // few batches: each is two fsync'ed transactions
  testing::SourceSpec target;
  target.source = Source::kTarget;
  target.interval = 6 * 3600.0;
  target.sigma = Eigen::Vector3d(0.002, 0.002, 0.003);
  target.seed = 3;
  const double t_end = kT0 + 3 * kDay;
  return testing::Merge({testing::MakeBatches(radio, {"a", "b"}, {m1, m2}, t_end),
                         testing::MakeBatches(target, {"a", "b"}, {m1, m2}, t_end)});
}

void ExpectSameSnapshot(const Snapshot& x, const Snapshot& y) {
  ASSERT_EQ(x.points.size(), y.points.size());
  EXPECT_EQ(x.reference_epoch, y.reference_epoch);
  EXPECT_EQ(x.reference_stamp, y.reference_stamp);
  EXPECT_EQ(x.alert, y.alert);
  for (size_t i = 0; i < x.points.size(); ++i) {
    const PointState &a = x.points[i], &b = y.points[i];
    EXPECT_EQ(a.id, b.id);
    EXPECT_EQ(a.stamp, b.stamp);
    EXPECT_EQ(a.num_measurements, b.num_measurements);
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(a.displacement(k), b.displacement(k)) << a.id;  // bit-identical
      EXPECT_EQ(a.velocity(k), b.velocity(k)) << a.id;
      EXPECT_EQ(a.acceleration(k), b.acceleration(k)) << a.id;
    }
    EXPECT_EQ(a.displacement_covariance, b.displacement_covariance);
    EXPECT_EQ(a.alert, b.alert);
    EXPECT_EQ(a.forecast.valid, b.forecast.valid);
    EXPECT_EQ(a.forecast.failure_time, b.forecast.failure_time);
  }
}

TEST(History, KillAndRestartGivesTheUninterruptedResult) {
  const std::vector<Batch> batches = HistoryScenario();
  EstimatorOptions o;
  const std::string path_a = TempPath("a.db"), path_b = TempPath("b.db");
  Snapshot uninterrupted;
  {
    History h(path_a);
    Estimator e(o, &h);
    for (const Batch& b : batches) e.AddBatch(b);
    uninterrupted = e.GetSnapshot();
  }
  const size_t half = batches.size() / 2;
  {
    History h(path_b);
    Estimator e(o, &h);
    for (size_t i = 0; i < half; ++i) e.AddBatch(batches[i]);
  }  // "killed": everything is gone but the file
  Snapshot resumed;
  {
    History h(path_b);
    Estimator e(o, &h);
    EXPECT_TRUE(e.GetSnapshot().has_reference);
    EXPECT_EQ(e.GetSnapshot().reference_stamp, kT0);
    for (size_t i = half; i < batches.size(); ++i) e.AddBatch(batches[i]);
    resumed = e.GetSnapshot();
    EXPECT_EQ(h.CountRows("batches"), static_cast<int64_t>(batches.size()));
    EXPECT_EQ(h.CountRows("observations"), static_cast<int64_t>(2 * batches.size()));
    EXPECT_GT(h.CountRows("estimates"), 0);
  }
  ExpectSameSnapshot(uninterrupted, resumed);
  // The estimates tables hold the same final rows.
  History ha(path_a), hb(path_b);
  EXPECT_EQ(ha.CountRows("estimates"), hb.CountRows("estimates"));
}

TEST(History, AMeasurementCommittedButNotProcessedIsUsedOnRestart) {
  // Killed between the commit of a batch and its use: the restart uses it.
  const std::vector<Batch> batches = HistoryScenario();
  const std::string path = TempPath("c.db");
  Snapshot expected;
  {
    Estimator e{EstimatorOptions()};
    for (const Batch& b : batches) e.AddBatch(b);
    expected = e.GetSnapshot();
  }
  {
    History h(path);
    Estimator e(EstimatorOptions(), &h);
    for (size_t i = 0; i + 1 < batches.size(); ++i) e.AddBatch(batches[i]);
    h.AppendBatch(batches.back());  // committed, then the process died
  }
  History h(path);
  Estimator e(EstimatorOptions(), &h);
  ExpectSameSnapshot(expected, e.GetSnapshot());
}

TEST(History, ReferenceEpochSurvivesARestart) {
  const std::vector<Batch> batches = HistoryScenario();
  const std::string path = TempPath("r.db");
  Snapshot before;
  {
    History h(path);
    Estimator e(EstimatorOptions(), &h);
    for (const Batch& b : batches) e.AddBatch(b);
    EXPECT_EQ(e.SetReferenceEpoch(4, false), 4u);
    before = e.GetSnapshot();
    EXPECT_EQ(before.reference_epoch, 4u);
    // Relative to epoch 4, the moving point's displacement is smaller than from the datum.
    EXPECT_THROW(e.SetReferenceEpoch(999, false), InvalidArgument);
  }
  History h(path);
  Estimator e(EstimatorOptions(), &h);
  ExpectSameSnapshot(before, e.GetSnapshot());
}

TEST(History, CorruptFileIsRefusedAndLeftUntouched) {
  const std::string path = TempPath("corrupt.db");
  const std::string junk =
      "this is not a database, it is a crew's note about the typhoon\n" + std::string(5000, 'x');
  {
    std::ofstream out(path, std::ios::binary);
    out << junk;
  }
  try {
    History h(path);
    FAIL() << "a non-SQLite file was opened";
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find("not a SQLite database"), std::string::npos) << what;
  }
  std::ifstream in(path, std::ios::binary);
  const std::string after((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(after, junk);
}

TEST(History, TruncatedDatabaseIsRefused) {
  const std::string path = TempPath("trunc.db");
  {
    History h(path);
    Estimator e(EstimatorOptions(), &h);
    for (const Batch& b : HistoryScenario()) e.AddBatch(b);
  }
  // Keep the header page only: the SQLite header is valid, the rest is gone.
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  ASSERT_GT(bytes.size(), 8192u);
  bytes.resize(bytes.size() / 2 + 100);
  {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  bool refused = false;
  try {
    History h(path);
    Estimator e(EstimatorOptions(), &h);
  } catch (const IoError& e) {
    refused = std::string(e.what()).find(path) != std::string::npos;
  }
  EXPECT_TRUE(refused);
}

TEST(History, MigratesAVersion1Database) {
  const std::string path = TempPath("v1.db");
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    const char* v1 =
        "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);"
        "CREATE TABLE batches(id INTEGER PRIMARY KEY, received TEXT, epoch INTEGER, stamp REAL);"
        "CREATE TABLE observations(id INTEGER PRIMARY KEY, batch_id INTEGER REFERENCES batches(id),"
        " point_id TEXT NOT NULL, source INTEGER, source_name TEXT, epoch INTEGER, stamp REAL, "
        "reference_stamp REAL,"
        " rx REAL, ry REAL, rz REAL, dx REAL, dy REAL, dz REAL, covariance BLOB);"
        "CREATE TABLE estimates(point_id TEXT NOT NULL, stamp REAL NOT NULL, epoch INTEGER, "
        "batch_id INTEGER,"
        " dx REAL, dy REAL, dz REAL, vx REAL, vy REAL, vz REAL, ax REAL, ay REAL, az REAL,"
        " displacement_covariance BLOB, velocity_covariance BLOB, PRIMARY KEY(point_id, stamp));"
        "INSERT INTO batches VALUES(1, '2026-01-01T00:00:00Z', 3, 1700010000.0);"
        "INSERT INTO observations VALUES(1, 1, 'p1', 1, 'bundle_adjuster', 3, 1700010000.0, "
        "1700000000.0,"
        " 1, 2, 3, 0.004, -0.012, -0.002, NULL);"
        "INSERT INTO estimates(point_id, stamp, epoch, batch_id, dx) VALUES('p1', 1700010000.0, 3, "
        "1, 0.004);"
        "PRAGMA user_version = 1;";
    ASSERT_EQ(sqlite3_exec(db, v1, nullptr, nullptr, nullptr), SQLITE_OK);
    sqlite3_close(db);
  }
  History h(path);
  EXPECT_EQ(h.schema_version(), 2);
  EXPECT_EQ(h.CountRows("estimates"), 1);
  EXPECT_EQ(h.CountRows("reference_offsets"), 0);
  // The v1 rows are kept (a NULL covariance reads back as zero; the
  // estimator's replay refuses such a row without deleting it).
  const auto batches = h.LoadBatches();
  ASSERT_EQ(batches.size(), 1u);
  ASSERT_EQ(batches[0].batch.measurements.size(), 1u);
  EXPECT_EQ(batches[0].batch.measurements[0].point_id, "p1");
  EXPECT_DOUBLE_EQ(batches[0].batch.measurements[0].displacement.y(), -0.012);
  EXPECT_EQ(batches[0].batch.epoch, 3u);
}

TEST(History, NewerSchemaIsRefused) {
  const std::string path = TempPath("v9.db");
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  ASSERT_EQ(
      sqlite3_exec(db, "CREATE TABLE x(a); PRAGMA user_version = 9;", nullptr, nullptr, nullptr),
      SQLITE_OK);
  sqlite3_close(db);
  try {
    History h(path);
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("newer"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
