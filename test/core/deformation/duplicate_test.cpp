// A measurement delivered twice (a latched topic re-delivers its last message
// when a restarted estimator subscribes again) is refused: not stored, not
// fused a second time, before and after a restart from the history.
#include <unistd.h>

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/history.h"

namespace slope_monitor {
namespace deformation {
namespace {

constexpr double kDuplicateT0 = 1700000000.0;

Batch MakeBatch(uint32_t epoch, double dt, double dy) {
  Batch b;
  b.epoch = epoch;
  b.stamp = kDuplicateT0 + dt;
  Measurement m;
  m.point_id = "p1";
  m.source = Source::kRadio;
  m.source_name = "/radio/radio_displacements";
  m.epoch = epoch;
  m.stamp = b.stamp;
  m.reference_stamp = kDuplicateT0;
  m.reference_position = Eigen::Vector3d(100, 80, 20);
  m.displacement = Eigen::Vector3d(0.0, dy, 0.0);
  m.covariance = Eigen::Matrix3d::Identity() * 1e-6;  // 1 mm
  b.measurements.push_back(m);
  return b;
}

TEST(Duplicate, IdenticalMeasurementIsRefusedAndNotStored) {
  const std::string path = "/tmp/sm_deformation_duplicate_" + std::to_string(getpid()) + ".db";
  std::remove(path.c_str());
  EstimatorOptions options;
  Eigen::Vector3d after_two;
  {
    History h(path);
    Estimator e(options, &h);
    EXPECT_EQ(e.AddBatch(MakeBatch(0, 0.0, 0.0)).accepted, 1);
    EXPECT_EQ(e.AddBatch(MakeBatch(1, 3600.0, -0.002)).accepted, 1);
    after_two = e.GetSnapshot().points.at(0).displacement;
    const BatchSummary again = e.AddBatch(MakeBatch(1, 3600.0, -0.002));
    EXPECT_EQ(again.accepted, 0);
    EXPECT_EQ(again.refused, 1);
    EXPECT_EQ(again.already_held, 1);
    EXPECT_TRUE(again.messages.empty());  // counted; the caller says it once
    EXPECT_EQ(h.CountRows("observations"), 2);
    EXPECT_EQ(e.GetSnapshot().points.at(0).displacement,
              after_two);  // bit for bit: not fused again
    EXPECT_EQ(e.GetSnapshot().points.at(0).num_measurements, 2u);
    // The same point, source and stamp with another value is the same
    // measurement (a recording processed again with other settings): refused.
    const BatchSummary revised = e.AddBatch(MakeBatch(1, 3600.0, -0.0021));
    EXPECT_EQ(revised.accepted, 0);
    EXPECT_EQ(revised.already_held, 1);
    EXPECT_EQ(e.AddBatch(MakeBatch(2, 7200.0, -0.0041)).accepted, 1);
  }
  {
    // Restarted: the history's measurements count as received.
    History h(path);
    Estimator e(options, &h);
    EXPECT_EQ(e.GetSnapshot().points.at(0).num_measurements, 3u);
    EXPECT_EQ(e.AddBatch(MakeBatch(1, 3600.0, -0.002)).refused, 1);
    EXPECT_EQ(e.AddBatch(MakeBatch(2, 7200.0, -0.0041)).refused, 1);
    EXPECT_EQ(h.CountRows("observations"), 3);
    EXPECT_EQ(e.AddBatch(MakeBatch(3, 10800.0, -0.006)).accepted, 1);
  }
  std::remove(path.c_str());
  std::remove((path + "-wal").c_str());
  std::remove((path + "-shm").c_str());
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
