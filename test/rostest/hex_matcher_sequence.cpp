// hex_matcher in mode sequence through its topics
// (test/rostest/hex_matcher_sequence.test): images in on /hs_test/image,
// position priors on /hs_test/position_prior, tie points out on
// /hs_test/tie_points.
//
// Truth: image i is the crop of the Cones left image (test/data) at
// (x0 - s_i.x, y0 - s_i.y), so that a scene point at column X is at X - x0 +
// s_i.x in image i and every correct tie point of the pair (a, b) has
// xb - xa = s_b - s_a exactly (each image with its own Gaussian noise of 1.5
// grey levels, fixed seeds). Shifts of 50-120 px: far beyond the matcher's
// 24 px search radius, found by the global shift. Position priors (0.1 m per
// pixel of shift) decide the pairs: every earlier image within 30 m, nearest
// first. The sequence:
//   1 s (0, 0):      first of the epoch: one empty message, camera_a "", pairs_b 1;
//   2 s (50, 10):    pairs with 1;                    pairs_b 1
//   3 s (100, 20):   pairs with 2, 1 (nearest first); pairs_b 2
//   4 wrong size:    pairs with 3, 2, 1, all failing (empty), pairs_b 3; the node goes on
//   5 s (120, -15):  pairs with 3, 2, 1;              pairs_b 3
//   6 s (0, 0) 200 s later: a new epoch: one empty message, pairs_b 1
//   7 s (60, 0), no prior: the previous image (sequence_depth 2, only 6 there): pairs_b 1
// Track IDs: image 1's interest points matched into 2, 3 and 5 carry the same
// id ((1 << 32) | row * width + col of xa) in the three pairs.
#include <cmath>
#include <cstdio>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/Image.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/TiePointArray.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

constexpr int kW = 240, kH = 180, kX0 = 200, kY0 = 100;

using slope_monitor::rostest_node::WaitFor;

class HexMatcherSequenceRos : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle nh;
    pub_image_ = nh.advertise<sensor_msgs::Image>("/hs_test/image", 20);
    pub_prior_ =
        nh.advertise<geometry_msgs::PoseWithCovarianceStamped>("/hs_test/position_prior", 20);
    sub_ = nh.subscribe<slope_monitor::TiePointArray>(
        "/hs_test/tie_points", 100, [this](const slope_monitor::TiePointArrayConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          ties_.push_back(*m);
        });
    diag_ = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 100, [this](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          for (const auto& s : m->status)
            if (s.hardware_id == "hex_matcher") diags_.push_back(s);
        });
    spinner_.start();
    ASSERT_TRUE(WaitFor(
        [&] {
          return pub_image_.getNumSubscribers() > 0 && pub_prior_.getNumSubscribers() > 0 &&
                 sub_.getNumPublishers() > 0;
        },
        60.0))
        << "hex_matcher did not subscribe to /hs_test/image, /hs_test/position_prior or advertise "
           "/hs_test/tie_points";
    const std::string path = std::string(SM_TEST_DATA_DIR) + "/stereo_middlebury_cones/left.tif";
    scene_ = cv::imread(path, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(scene_.empty()) << "cannot read " << path;
  }

  // Image with shift s: the crop at (x0 - s.x, y0 - s.y) with noise; mono8.
  cv::Mat Crop(cv::Point s, unsigned seed, int w = kW) const {
    cv::Mat f;
    scene_(cv::Rect(kX0 - s.x, kY0 - s.y, w, kH)).convertTo(f, CV_32F);
    cv::Mat noise(f.size(), CV_32F);
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.5);
    cv::Mat out;
    cv::Mat(f + noise).convertTo(out, CV_8U);
    return out;
  }

  // Publishes the prior (unless !with_prior) and the image with stamp t and
  // waits for the `expected` messages of image b.
  void Send(const cv::Mat& image, double t, bool with_prior, cv::Point s, size_t expected) {
    std_msgs::Header h;
    h.stamp = ros::Time(t);
    h.frame_id = "uav_optical";
    if (with_prior) {
      geometry_msgs::PoseWithCovarianceStamped p;
      p.header.stamp = h.stamp;
      p.header.frame_id = "site";
      p.pose.pose.position.x = 0.1 * s.x;
      p.pose.pose.position.y = 0.1 * s.y;
      p.pose.pose.position.z = 60.0;
      p.pose.pose.orientation.w = 1.0;
      pub_prior_.publish(p);
    }
    shifts_[t] = s;
    pub_image_.publish(cv_bridge::CvImage(h, "mono8", image).toImageMsg());
    ASSERT_TRUE(WaitFor([&] { return ForB(t).size() >= expected; }, 30.0))
        << "image at " << t << ": " << ForB(t).size() << " of " << expected
        << " tie-point messages";
    ros::Duration(0.3).sleep();  // no extra message may follow
    EXPECT_EQ(ForB(t).size(), expected) << "image at " << t;
  }

  std::vector<slope_monitor::TiePointArray> ForB(double t) {
    std::lock_guard<std::mutex> l(mutex_);
    std::vector<slope_monitor::TiePointArray> out;
    for (const auto& m : ties_)
      if (std::fabs(m.header.stamp.toSec() - t) < 1e-6) out.push_back(m);
    return out;
  }

  bool DiagnosticSays(const std::string& part) {
    std::lock_guard<std::mutex> l(mutex_);
    for (const auto& s : diags_)
      if (s.message.find(part) != std::string::npos) return true;
    return false;
  }

  // Checks a good pair message against the known shift; returns the ids of its normal-quality
  // points.
  std::map<std::uint64_t, std::pair<double, double>> CheckPair(
      const slope_monitor::TiePointArray& m) {
    const cv::Point sa = shifts_.at(m.header_a.stamp.toSec()),
                    sb = shifts_.at(m.header.stamp.toSec());
    const double ex = sb.x - sa.x, ey = sb.y - sa.y;
    std::map<std::uint64_t, std::pair<double, double>> ids;
    int normal = 0, correct = 0;
    std::vector<double> dx, dy;
    for (const auto& p : m.points) {
      EXPECT_NE(p.id, 0u);
      EXPECT_EQ(p.method, slope_monitor::TiePoint::METHOD_LSC);
      if (p.quality <= 0.25) continue;
      ++normal;
      dx.push_back(p.xb - p.xa);
      dy.push_back(p.yb - p.ya);
      if (std::hypot(p.xb - p.xa - ex, p.yb - p.ya - ey) <= 0.2) ++correct;
      ids[p.id] = {p.xa, p.ya};
      // id = (serial of a) << 32 | row * width + col of round(xa)
      EXPECT_EQ(p.id & 0xffffffffu, std::uint64_t(std::lround(p.ya) * kW + std::lround(p.xa)));
    }
    std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
    std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
    std::printf(
        "pair %.0f -> %.0f: pairs_b %u, %zu tie points, %d normal, %d within 0.2 px of the shift "
        "(%.0f, %.0f), "
        "median shift (%.2f, %.2f)\n",
        m.header_a.stamp.toSec(), m.header.stamp.toSec(), m.pairs_b, m.points.size(), normal,
        correct, ex, ey, dx.empty() ? NAN : dx[dx.size() / 2],
        dy.empty() ? NAN : dy[dy.size() / 2]);
    EXPECT_GT(normal, 50);
    EXPECT_GE(correct, 0.97 * normal);
    if (!dx.empty()) {
      EXPECT_NEAR(dx[dx.size() / 2], ex, 0.1);
      EXPECT_NEAR(dy[dy.size() / 2], ey, 0.1);
    }
    return ids;
  }

  ros::AsyncSpinner spinner_{2};
  ros::Publisher pub_image_, pub_prior_;
  ros::Subscriber sub_, diag_;
  std::mutex mutex_;
  std::vector<slope_monitor::TiePointArray> ties_;
  std::vector<diagnostic_msgs::DiagnosticStatus> diags_;
  std::map<double, cv::Point> shifts_;
  cv::Mat scene_;
};

TEST_F(HexMatcherSequenceRos, PairsCountsTrackIdsAndBadImage) {
  const cv::Point s1(0, 0), s2(50, 10), s3(100, 20), s5(120, -15), s6(0, 0), s7(60, 0);
  // 1: first of the epoch.
  Send(Crop(s1, 1), 10.0, true, s1, 1);
  {
    const auto m = ForB(10.0);
    ASSERT_EQ(m.size(), 1u);
    EXPECT_EQ(m[0].pairs_b, 1u);
    EXPECT_EQ(m[0].camera_a, "");
    EXPECT_EQ(m[0].camera_b, "uav");
    EXPECT_TRUE(m[0].points.empty());
  }
  // 2: one pair (with 1).
  Send(Crop(s2, 2), 12.0, true, s2, 1);
  std::map<std::uint64_t, std::pair<double, double>> ids_12, ids_13, ids_15;
  {
    const auto m = ForB(12.0);
    ASSERT_EQ(m.size(), 1u);
    EXPECT_EQ(m[0].pairs_b, 1u);
    EXPECT_EQ(m[0].camera_a, "uav");
    EXPECT_DOUBLE_EQ(m[0].header_a.stamp.toSec(), 10.0);
    ids_12 = CheckPair(m[0]);
  }
  // 3: pairs with 2 (5.1 m) then 1 (10.2 m).
  Send(Crop(s3, 3), 14.0, true, s3, 2);
  {
    const auto m = ForB(14.0);
    ASSERT_EQ(m.size(), 2u);
    EXPECT_DOUBLE_EQ(m[0].header_a.stamp.toSec(), 12.0);
    EXPECT_DOUBLE_EQ(m[1].header_a.stamp.toSec(), 10.0);
    for (const auto& x : m) EXPECT_EQ(x.pairs_b, 2u);
    CheckPair(m[0]);
    ids_13 = CheckPair(m[1]);
  }
  // 4: wrong size: three failing pairs, empty messages, the count still holds.
  Send(Crop(cv::Point(100, 0), 4, kW - 40), 16.0, true, cv::Point(100, 0), 3);
  {
    const auto m = ForB(16.0);
    ASSERT_EQ(m.size(), 3u);
    for (const auto& x : m) {
      EXPECT_EQ(x.pairs_b, 3u);
      EXPECT_TRUE(x.points.empty());
      EXPECT_EQ(x.camera_a, "uav");
    }
  }
  EXPECT_TRUE(WaitFor([&] { return DiagnosticSays("differ in size"); }, 20.0))
      << "no diagnostics naming the size mismatch";
  // 5: the node goes on; the wrong-size image is no partner: pairs with 3, 2, 1.
  Send(Crop(s5, 5), 18.0, true, s5, 3);
  {
    const auto m = ForB(18.0);
    ASSERT_EQ(m.size(), 3u);
    const double expected_a[3] = {14.0, 12.0, 10.0};  // 3.6 m, 7.7 m, 12.1 m
    for (size_t k = 0; k < 3; ++k) {
      EXPECT_EQ(m[k].pairs_b, 3u);
      EXPECT_DOUBLE_EQ(m[k].header_a.stamp.toSec(), expected_a[k]);
      const auto ids = CheckPair(m[k]);
      if (k == 2) ids_15 = ids;
    }
  }
  // Tracks: image 1's points matched into 2, 3 and 5 share their ids (same xa).
  int three = 0, four = 0;
  for (const auto& kv : ids_12) {
    EXPECT_EQ(kv.first >> 32, 1u) << "image 1 is the node's first image";
    const auto i3 = ids_13.find(kv.first);
    if (i3 == ids_13.end()) continue;
    ++three;
    EXPECT_EQ(i3->second, kv.second);
    const auto i5 = ids_15.find(kv.first);
    if (i5 == ids_15.end()) continue;
    ++four;
    EXPECT_EQ(i5->second, kv.second);
  }
  std::printf("tracks of image 1: %zu in image 2, %d also in image 3, %d also in image 5\n",
              ids_12.size(), three, four);
  EXPECT_GT(three, 30);
  EXPECT_GT(four, 10);
  // 6: 200 s later: a new epoch, no partner.
  Send(Crop(s6, 6), 218.0, true, s6, 1);
  {
    const auto m = ForB(218.0);
    ASSERT_EQ(m.size(), 1u);
    EXPECT_EQ(m[0].pairs_b, 1u);
    EXPECT_EQ(m[0].camera_a, "");
  }
  // 7: no prior: the previous image of the epoch only.
  Send(Crop(s7, 7), 220.0, false, s7, 1);
  {
    const auto m = ForB(220.0);
    ASSERT_EQ(m.size(), 1u);
    EXPECT_EQ(m[0].pairs_b, 1u);
    EXPECT_DOUBLE_EQ(m[0].header_a.stamp.toSec(), 218.0);
    const auto ids = CheckPair(m[0]);
    for (const auto& kv : ids) EXPECT_EQ(kv.first >> 32, 6u);
  }
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hex_matcher_sequence_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
