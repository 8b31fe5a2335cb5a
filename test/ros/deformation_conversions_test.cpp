// Deformation message conversions: a displacement message becomes a batch
// with the right numbers, and the outputs carry the estimate back.
#include <gtest/gtest.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/deformation_conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

slope_monitor::PointDisplacementArray Message(double t, double dy) {
  slope_monitor::PointDisplacementArray msg;
  msg.header.stamp = ros::Time(t);
  msg.header.frame_id = "site";
  msg.epoch = 2;
  slope_monitor::PointDisplacement d;
  d.point_id = "tag36h11/4";
  d.source = slope_monitor::PointDisplacement::SOURCE_TARGET;
  d.source_name = "bundle_adjuster";
  d.reference_stamp = ros::Time(1700000000.0);
  d.reference_position.x = 100;
  d.reference_position.y = 80;
  d.reference_position.z = 30;
  d.displacement.y = dy;
  d.covariance = {1e-6, 0, 0, 0, 1e-6, 0, 0, 0, 4e-6};
  msg.displacements.push_back(d);
  return msg;
}

TEST(DeformationConversions, DisplacementsToBatch) {
  const deformation::Batch b =
      FromMsg(Message(1700003600.0, -0.01), "/bundle_adjuster/displacements");
  ASSERT_EQ(b.measurements.size(), 1u);
  const deformation::Measurement& m = b.measurements[0];
  EXPECT_EQ(m.point_id, "tag36h11/4");
  EXPECT_EQ(m.source, deformation::Source::kTarget);
  EXPECT_DOUBLE_EQ(m.stamp, 1700003600.0);  // zero stamp takes the header's
  EXPECT_DOUBLE_EQ(m.reference_stamp, 1700000000.0);
  EXPECT_DOUBLE_EQ(m.displacement.y(), -0.01);
  EXPECT_DOUBLE_EQ(m.covariance(2, 2), 4e-6);
  EXPECT_EQ(b.epoch, 2u);
  slope_monitor::PointDisplacementArray bad = Message(1700003600.0, 0.0);
  bad.displacements[0].source = 7;
  try {
    FromMsg(bad, "/x/displacements");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("/x/displacements"), std::string::npos);
  }
}

TEST(DeformationConversions, EstimateToMessagesMarkersCloudAlerts) {
  deformation::Estimator est{deformation::EstimatorOptions()};
  for (int i = 1; i <= 10; ++i)
    est.AddBatch(FromMsg(Message(1700000000.0 + 3600.0 * i, -0.001 * i), "t"));
  const deformation::Snapshot s = est.GetSnapshot();
  std_msgs::Header h;
  h.frame_id = "site";
  h.stamp = ros::Time(1700036000.0);
  const slope_monitor::SlopeDeformation msg = ToMsg(s, h);
  ASSERT_EQ(msg.points.size(), 1u);
  EXPECT_EQ(msg.header.stamp, h.stamp);
  EXPECT_NEAR(msg.points[0].displacement.y, -0.010, 0.001);  // noise-free input: 1 mm/h for 10 h
  EXPECT_NEAR(msg.points[0].velocity.y, -0.001 / 3600.0, 0.2 * 0.001 / 3600.0);
  EXPECT_EQ(msg.points[0].sources.size(), 1u);
  EXPECT_EQ(msg.points[0].sources[0], slope_monitor::PointDisplacement::SOURCE_TARGET);

  MarkerOptions mo;
  mo.arrow_scale = 100.0;
  const visualization_msgs::MarkerArray markers = ToMarkers(s, h, mo);
  ASSERT_EQ(markers.markers.size(), 4u);  // DELETEALL + sphere, arrow, label
  const visualization_msgs::Marker& arrow = markers.markers[2];
  EXPECT_EQ(arrow.type, visualization_msgs::Marker::ARROW);
  EXPECT_EQ(arrow.header.frame_id, "site");
  ASSERT_EQ(arrow.points.size(), 2u);
  EXPECT_NEAR(arrow.points[1].y - arrow.points[0].y, 100.0 * msg.points[0].displacement.y, 1e-9);
  EXPECT_NE(markers.markers[3].text.find("tag36h11/4"), std::string::npos);

  const sensor_msgs::PointCloud2 cloud = ToCloud(s, h);
  EXPECT_EQ(cloud.width * cloud.height, 1u);
  sensor_msgs::PointCloud2ConstIterator<float> x(cloud, "x"), d(cloud, "displacement");
  EXPECT_FLOAT_EQ(*x, 100.0f);
  EXPECT_NEAR(*d, std::abs(msg.points[0].displacement.y), 1e-3);

  const diagnostic_msgs::DiagnosticArray alerts = ToAlerts(s, h);
  ASSERT_EQ(alerts.status.size(), 2u);
  EXPECT_EQ(alerts.status[1].name, "deformation/tag36h11/4");
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
