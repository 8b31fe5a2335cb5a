// Every message and service of the package compiles into C++, and messages
// survive a round trip through a real bag file (rosbag, bz2 and lz4 chunks).
#include <cstdio>
#include <string>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/CameraEstimate.h"
#include "slope_monitor/DeformationPoint.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/ExportReport.h"
#include "slope_monitor/PointDisplacement.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/PointEstimate.h"
#include "slope_monitor/RadioPhaseObservation.h"
#include "slope_monitor/RadioPhaseObservationArray.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/RunAdjustment.h"
#include "slope_monitor/SetReferenceEpoch.h"
#include "slope_monitor/SlopeDeformation.h"
#include "slope_monitor/TargetObservation.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/TiePoint.h"
#include "slope_monitor/TiePointArray.h"

namespace {

std::string TempBagPath(const std::string& name) {
  return std::string(testing::TempDir()) + "/sm_messages_" + name + ".bag";
}

template <typename M>
M RoundTrip(const M& msg, const std::string& topic,
            rosbag::compression::CompressionType compression) {
  std::string name = topic.substr(1) + std::to_string(static_cast<int>(compression));
  for (char& ch : name) ch = ch == '/' ? '_' : ch;
  const std::string path = TempBagPath(name);
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    bag.setCompression(compression);
    bag.write(topic, ros::Time(1700000000, 5), msg);
  }
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  rosbag::View view(bag, rosbag::TopicQuery(topic));
  EXPECT_EQ(view.size(), 1u);
  M out;
  for (const rosbag::MessageInstance& m : view) {
    auto p = m.instantiate<M>();
    EXPECT_TRUE(p != nullptr) << "wrong type on " << topic;
    if (p) out = *p;
  }
  bag.close();
  std::remove(path.c_str());
  return out;
}

TEST(Messages, TargetObservationArrayRoundTrip) {
  slope_monitor::TargetObservationArray a;
  a.header.frame_id = "fixed_cam_1_optical";
  a.header.stamp = ros::Time(1700000000, 42);
  a.camera_name = "fixed_cam_1";
  a.epoch = 3;
  slope_monitor::TargetObservation o;
  o.id = 17;
  o.family = "tag36h11";
  o.role = slope_monitor::TargetObservation::ROLE_CONTROL;
  o.x = 123.456;
  o.y = 78.9;
  o.covariance = {1e-4, 0, 0, 2e-4};
  o.corners = {1, 2, 3, 4, 5, 6, 7, 8};
  a.observations.push_back(o);
  a.reject_reasons.push_back("saturated");
  a.rejected = 1;
  for (auto c :
       {rosbag::compression::Uncompressed, rosbag::compression::BZ2, rosbag::compression::LZ4}) {
    const auto b = RoundTrip(a, "/fixed_cam_1/targets", c);
    ASSERT_EQ(b.observations.size(), 1u);
    EXPECT_EQ(b.observations[0].id, 17);
    EXPECT_DOUBLE_EQ(b.observations[0].x, 123.456);
    EXPECT_DOUBLE_EQ(b.observations[0].covariance[3], 2e-4);
    EXPECT_DOUBLE_EQ(b.observations[0].corners[7], 8);
    EXPECT_EQ(b.header.stamp, a.header.stamp);
    EXPECT_EQ(b.reject_reasons.at(0), "saturated");
  }
}

TEST(Messages, RadioSampleBlockRoundTrip) {
  slope_monitor::RadioSampleBlock blk;
  blk.receiver_id = "rx2";
  blk.sequence = 99;
  blk.sample_rate = 48000.0;
  blk.center_frequency = 2.4e9;
  blk.full_scale = 1.0;
  for (int i = 0; i < 4096; ++i) {
    blk.i.push_back(0.001f * i);
    blk.q.push_back(-0.002f * i);
  }
  const auto b = RoundTrip(blk, "/radio/rx2/samples", rosbag::compression::LZ4);
  EXPECT_EQ(b.sequence, 99u);
  ASSERT_EQ(b.i.size(), 4096u);
  EXPECT_FLOAT_EQ(b.q[4095], -0.002f * 4095);
}

TEST(Messages, DeformationAndDisplacementRoundTrip) {
  slope_monitor::SlopeDeformation d;
  d.header.frame_id = "site";
  d.reference_epoch = 0;
  slope_monitor::DeformationPoint p;
  p.point_id = "tag36h11/5";
  p.displacement.x = 0.012;
  p.alert_level = slope_monitor::DeformationPoint::ALERT_WARNING;
  p.forecast_valid = true;
  p.forecast_failure_time = ros::Time(1700100000, 0);
  p.sources = {slope_monitor::PointDisplacement::SOURCE_TARGET,
               slope_monitor::PointDisplacement::SOURCE_RADIO};
  d.points.push_back(p);
  const auto b = RoundTrip(d, "/deformation", rosbag::compression::BZ2);
  ASSERT_EQ(b.points.size(), 1u);
  EXPECT_DOUBLE_EQ(b.points[0].displacement.x, 0.012);
  EXPECT_EQ(b.points[0].alert_level, slope_monitor::DeformationPoint::ALERT_WARNING);
  EXPECT_EQ(b.points[0].sources.size(), 2u);

  slope_monitor::PointDisplacementArray arr;
  slope_monitor::PointDisplacement pd;
  pd.point_id = "tx3";
  pd.source = slope_monitor::PointDisplacement::SOURCE_RADIO;
  pd.covariance[4] = 1e-6;
  arr.displacements.push_back(pd);
  const auto c = RoundTrip(arr, "/radio_displacements", rosbag::compression::Uncompressed);
  EXPECT_DOUBLE_EQ(c.displacements.at(0).covariance[4], 1e-6);
}

TEST(Messages, AdjustmentAndTiePointsRoundTrip) {
  slope_monitor::AdjustmentSolution s;
  s.usable = false;
  s.message = "too few control points: 2 < 3";
  slope_monitor::CameraEstimate c;
  c.camera_name = "uav";
  c.distortion = {1e-3, 0, 0, 0, 0, 0, 0};
  s.cameras.push_back(c);
  slope_monitor::PointEstimate p;
  p.id = "circle/4";
  p.covariance[8] = 4e-6;
  s.points.push_back(p);
  const auto b = RoundTrip(s, "/solution", rosbag::compression::LZ4);
  EXPECT_FALSE(b.usable);
  EXPECT_EQ(b.message, s.message);
  EXPECT_EQ(b.cameras.at(0).distortion.size(), 7u);
  EXPECT_DOUBLE_EQ(b.points.at(0).covariance[8], 4e-6);

  slope_monitor::TiePointArray t;
  slope_monitor::TiePoint tp;
  tp.xa = 1.25;
  tp.yb = 7.5;
  tp.method = slope_monitor::TiePoint::METHOD_LSC;
  t.points.push_back(tp);
  const auto u = RoundTrip(t, "/tie_points", rosbag::compression::Uncompressed);
  EXPECT_DOUBLE_EQ(u.points.at(0).yb, 7.5);
}

TEST(Messages, ServicesAndOtherMessagesCompile) {
  slope_monitor::RunAdjustment run;
  run.request.epoch = 2;
  run.response.solution.epoch = 2;
  slope_monitor::SetReferenceEpoch ref;
  ref.request.use_latest = true;
  ref.response.reference_epoch = 1;
  slope_monitor::ExportReport rep;
  rep.request.formats = {"csv", "geojson"};
  rep.response.files.push_back("/tmp/points.csv");
  slope_monitor::EpochMarker m;
  m.end = true;
  slope_monitor::RadioPhaseObservationArray ph;
  ph.observations.resize(3);
  EXPECT_EQ(run.response.solution.epoch, 2u);
  EXPECT_EQ(rep.request.formats.size(), 2u);
  EXPECT_EQ(ph.observations.size(), 3u);
  EXPECT_EQ(std::string(ros::service_traits::datatype<slope_monitor::RunAdjustment>()),
            "slope_monitor/RunAdjustment");
  EXPECT_EQ(std::string(ros::message_traits::datatype<slope_monitor::EpochMarker>()),
            "slope_monitor/EpochMarker");
  const auto back = RoundTrip(m, "/epoch", rosbag::compression::Uncompressed);
  EXPECT_TRUE(back.end);
}

}  // namespace
