// The message validation layer (issue 22): each hostile value the issue
// found accepted is refused, counted by reason and named, and the rest of
// its array is kept.
#include <gtest/gtest.h>

#include "slope_monitor/ros/validation.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

constexpr double kNow = 1.7e9;  // [s] the node's clock, 2023-11

slope_monitor::PointDisplacement Good(const std::string& id) {
  slope_monitor::PointDisplacement d;
  d.point_id = id;
  d.source = slope_monitor::PointDisplacement::SOURCE_RADIO;
  d.source_name = "radio_phase_solver";
  d.stamp = ros::Time(kNow - 60.0);
  d.reference_stamp = ros::Time(kNow - 86400.0);
  d.reference_position.x = 120.0;
  d.reference_position.y = -35.0;
  d.reference_position.z = 410.0;
  d.displacement.x = 0.004;
  for (int k = 0; k < 3; ++k) d.covariance[4 * k] = 1e-6;  // sigma 1 mm
  return d;
}

slope_monitor::PointDisplacementArray Array(uint32_t epoch,
                                            std::vector<slope_monitor::PointDisplacement> d) {
  slope_monitor::PointDisplacementArray a;
  a.header.stamp = ros::Time(kNow - 60.0);
  a.header.frame_id = "site";
  a.epoch = epoch;
  a.displacements = std::move(d);
  return a;
}

TEST(Validation, GoodMessagePassesWhole) {
  MessageValidator v;
  const auto out = v.Filter(Array(3, {Good("tag36h11/1"), Good("rock")}), "displacements", kNow);
  EXPECT_EQ(out.displacements.size(), 2u);
  EXPECT_EQ(v.total_rejected(), 0u);
  EXPECT_TRUE(v.last_problems().empty());
}

TEST(Validation, EachBadElementIsDroppedAndCountedTheRestKept) {
  std::vector<slope_monitor::PointDisplacement> d;
  d.push_back(Good("keep_1"));
  d.push_back(Good(std::string(250, 'x')));  // long id
  d.push_back(Good("far"));
  d.back().reference_position.x = 1e300;
  d.push_back(Good("nan"));
  d.back().displacement.y = std::nan("");
  d.push_back(Good("huge_cov"));
  for (int k = 0; k < 3; ++k) d.back().covariance[4 * k] = 1e300;
  d.push_back(Good("tiny_cov"));
  for (int k = 0; k < 3; ++k) d.back().covariance[4 * k] = 1e-300;
  d.push_back(Good("asym_cov"));
  d.back().covariance[1] = 5e-7;  // (0,1) without (1,0)
  d.push_back(Good("indefinite"));
  d.back().covariance[1] = d.back().covariance[3] = 2e-6;  // |rho| > 1
  d.push_back(Good("in_2106"));
  d.back().stamp = ros::Time(4291747200.0);  // 2106-01-01
  d.push_back(Good("bad\nid"));
  d.push_back(Good("keep_2"));
  MessageValidator v;
  const auto out = v.Filter(Array(1, d), "displacements", kNow);
  ASSERT_EQ(out.displacements.size(), 2u);
  EXPECT_EQ(out.displacements[0].point_id, "keep_1");
  EXPECT_EQ(out.displacements[1].point_id, "keep_2");
  EXPECT_EQ(v.total_rejected(), 9u);
  EXPECT_EQ(v.rejected().at("bad identifier"), 2u);
  EXPECT_EQ(v.rejected().at("out of range"), 1u);
  EXPECT_EQ(v.rejected().at("non-finite value"), 1u);
  EXPECT_EQ(v.rejected().at("bad covariance"), 4u);
  EXPECT_EQ(v.rejected().at("bad stamp"), 1u);
  ASSERT_EQ(v.last_problems().size(), 9u);
  EXPECT_NE(v.last_problems()[0].find("has 250 characters (at most 64)"), std::string::npos)
      << v.last_problems()[0];
  EXPECT_NE(v.last_problems()[1].find("point 'far'"), std::string::npos) << v.last_problems()[1];
  for (const std::string& p : v.last_problems()) {
    EXPECT_NE(p.find("topic 'displacements'"), std::string::npos) << p;
    EXPECT_EQ(p.find('\n'), std::string::npos) << p;
  }
}

TEST(Validation, EpochsMonotonicPerSourceAndNoWildFirstEpoch) {
  MessageValidator v;
  EXPECT_TRUE(
      v.Filter(Array(4294967295u, {Good("a")}), "displacements", kNow).displacements.empty());
  EXPECT_EQ(v.rejected().at("epoch not monotonic"), 1u);
  EXPECT_EQ(v.Filter(Array(5, {Good("a")}), "displacements", kNow).displacements.size(), 1u);
  EXPECT_EQ(v.Filter(Array(5, {Good("a")}), "displacements", kNow).displacements.size(),
            1u);  // repeat: fine
  EXPECT_TRUE(
      v.Filter(Array(4, {Good("a")}), "displacements", kNow).displacements.empty());  // backwards
  EXPECT_TRUE(v.Filter(Array(4294967295u, {Good("a")}), "displacements", kNow)
                  .displacements.empty());  // jump
  EXPECT_EQ(v.rejected().at("epoch not monotonic"), 3u);
  // Another source on the same topic keeps its own count.
  auto other = Good("b");
  other.source_name = "bundle_adjuster";
  EXPECT_EQ(v.Filter(Array(1, {other}), "displacements", kNow).displacements.size(), 1u);
}

TEST(Validation, SiteExtentAndSigmaBounds) {
  ValidationOptions o;
  o.site_extent =
      Eigen::AlignedBox3d(Eigen::Vector3d(0, -100, 300), Eigen::Vector3d(200, 100, 500));
  o.extent_margin = 50.0;
  MessageValidator v(o);
  auto inside = Good("in");
  auto edge = Good("edge");
  edge.reference_position.x = 249.0;  // within the margin
  auto outside = Good("out");
  outside.reference_position.x = 251.0;
  EXPECT_EQ(v.Filter(Array(1, {inside, edge, outside}), "d", kNow).displacements.size(), 2u);
  EXPECT_EQ(v.CovarianceProblem(Eigen::Matrix3d::Identity() * 1e-12),
            "");  // sigma 1e-6 m: the bound
  EXPECT_NE(v.CovarianceProblem(Eigen::Matrix3d::Identity() * 1e-13), "");  // below
  EXPECT_EQ(v.CovarianceProblem(Eigen::Matrix3d::Identity() * 1e6), "");    // sigma 1e3 m
  EXPECT_NE(v.CovarianceProblem(Eigen::Matrix3d::Identity() * 1.1e6), "");  // above
}

TEST(Validation, RadioBlockMustCarryItsTopicsReceiver) {
  slope_monitor::RadioSampleBlock b;
  b.header.stamp = ros::Time(kNow);
  b.receiver_id = "rx2";
  b.sample_rate = 20000.0;
  b.center_frequency = 433e6;
  b.full_scale = 1.0;
  b.i = {0.1f, 0.2f};
  b.q = {0.0f, 0.1f};
  MessageValidator v;
  EXPECT_FALSE(v.Accept(b, "rx1", kNow));
  EXPECT_EQ(v.rejected().at("receiver id does not match topic"), 1u);
  EXPECT_NE(v.last_problems().front().find("labelled 'rx2'"), std::string::npos)
      << v.last_problems().front();
  EXPECT_TRUE(v.Accept(b, "rx2", kNow));
  b.q[1] = std::numeric_limits<float>::infinity();
  EXPECT_FALSE(v.Accept(b, "rx2", kNow));
  EXPECT_EQ(v.rejected().at("non-finite value"), 1u);
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
