// hex_matcher run as a node (test/rostest/hex_matcher.test): image pairs in on
// /hm_test/image_a and /hm_test/image_b, tie points out on /tie_points.
//
// Truth: image b is a crop of the Cones left image (test/data) displaced by
// a known integer shift from image a's crop, so every correct tie point has
// xb - xa = kShift exactly (both crops carry independent Gaussian noise of
// 1.5 grey levels, fixed seeds). Bad input: a pair of different sizes, a pair
// of different encodings (mono8 / mono16) and a textureless pair; the node
// must name the problem (log, diagnostics), publish no fake matches and keep
// matching the next good pair.
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include <cv_bridge/cv_bridge.h>
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/TiePointArray.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

const cv::Point kShift(9, -5);  // [px] xb - xa
constexpr int kW = 360, kH = 300;

using slope_monitor::rostest_node::WaitFor;

class HexMatcherRos : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle nh;
    pub_a_ = nh.advertise<sensor_msgs::Image>("/hm_test/image_a", 5);
    pub_b_ = nh.advertise<sensor_msgs::Image>("/hm_test/image_b", 5);
    sub_ = nh.subscribe<slope_monitor::TiePointArray>(
        "/tie_points", 20, [this](const slope_monitor::TiePointArrayConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          ties_.push_back(*m);
        });
    diag_ = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 100, [this](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          for (const auto& s : m->status)
            if (s.hardware_id == "hex_matcher") diags_.push_back(s);
        });
    log_ = nh.subscribe<rosgraph_msgs::Log>("/rosout", 1000,
                                            [this](const rosgraph_msgs::LogConstPtr& m) {
                                              std::lock_guard<std::mutex> l(mutex_);
                                              logs_.push_back(*m);
                                            });
    spinner_.start();
    ASSERT_TRUE(WaitFor(
        [&] {
          return pub_a_.getNumSubscribers() > 0 && pub_b_.getNumSubscribers() > 0 &&
                 sub_.getNumPublishers() > 0;
        },
        60.0))
        << "hex_matcher did not subscribe to /hm_test/image_a, image_b or advertise /tie_points";
    const std::string path = std::string(SM_TEST_DATA_DIR) + "/stereo_middlebury_cones/left.tif";
    cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(grey.empty()) << "cannot read " << path;
    scene_ = grey;
  }

  // Crop of the scene at (x0, y0) with noise; mono8.
  cv::Mat Crop(int x0, int y0, unsigned seed) const {
    cv::Mat f;
    scene_(cv::Rect(x0, y0, kW, kH)).convertTo(f, CV_32F);
    cv::Mat noise(f.size(), CV_32F);
    cv::RNG rng(seed);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.5);
    cv::Mat out;
    cv::Mat(f + noise).convertTo(out, CV_8U);
    return out;
  }

  void Publish(const cv::Mat& a, const std::string& enc_a, const cv::Mat& b,
               const std::string& enc_b, double stamp) {
    std_msgs::Header h;
    h.stamp = ros::Time(stamp);
    h.frame_id = "cam_a";
    pub_a_.publish(cv_bridge::CvImage(h, enc_a, a).toImageMsg());
    h.frame_id = "cam_b";
    pub_b_.publish(cv_bridge::CvImage(h, enc_b, b).toImageMsg());
  }

  size_t TieCount() {
    std::lock_guard<std::mutex> l(mutex_);
    return ties_.size();
  }
  slope_monitor::TiePointArray LastTies() {
    std::lock_guard<std::mutex> l(mutex_);
    return ties_.back();
  }
  bool DiagnosticSays(const std::string& part) {
    std::lock_guard<std::mutex> l(mutex_);
    for (const auto& s : diags_)
      if (s.message.find(part) != std::string::npos) return true;
    return false;
  }
  bool LogSays(const std::string& part) {
    std::lock_guard<std::mutex> l(mutex_);
    for (const auto& m : logs_)
      if (m.level >= rosgraph_msgs::Log::ERROR && m.msg.find(part) != std::string::npos)
        return true;
    return false;
  }

  // A good pair: publishes it and checks the tie points against kShift.
  void GoodPair(double stamp, unsigned seed) {
    const size_t before = TieCount();
    const int x0 = 40, y0 = 40;
    // b at xb sees the scene point at xb + (x0 - kShift.x, ...) = xa + x0 => xb = xa + kShift.
    Publish(Crop(x0, y0, seed), "mono8", Crop(x0 - kShift.x, y0 - kShift.y, seed + 1), "mono8",
            stamp);
    ASSERT_TRUE(WaitFor([&] { return TieCount() > before; }, 30.0))
        << "no tie points for the good pair at " << stamp;
    const slope_monitor::TiePointArray t = LastTies();
    EXPECT_DOUBLE_EQ(t.header.stamp.toSec(), stamp);
    EXPECT_EQ(t.header_a.frame_id, "cam_a");
    int normal = 0, correct = 0;
    double sum2 = 0;
    for (const auto& p : t.points) {
      EXPECT_EQ(p.method, slope_monitor::TiePoint::METHOD_LSC);
      EXPECT_GT(p.covariance[0], 0.0);
      EXPECT_GT(p.covariance[3], 0.0);
      if (p.quality <= 0.25) continue;  // flagged low quality (doc/nodes/hex_matcher.md)
      ++normal;
      const double ex = (p.xb - p.xa) - kShift.x, ey = (p.yb - p.ya) - kShift.y;
      const double e = std::hypot(ex, ey);
      if (e <= 0.2) ++correct;
      sum2 += e * e;
    }
    const double rms = std::sqrt(sum2 / std::max(1, normal));
    std::printf(
        "good pair at %.0f: %zu tie points, %d normal quality, %d within 0.2 px of the shift, RMS "
        "%.3f px\n",
        stamp, t.points.size(), normal, correct, rms);
    EXPECT_GT(normal, 100);
    EXPECT_GE(correct, 0.98 * normal);
    EXPECT_LT(rms, 0.1);
  }

  ros::AsyncSpinner spinner_{2};
  ros::Publisher pub_a_, pub_b_;
  ros::Subscriber sub_, diag_, log_;
  std::mutex mutex_;
  std::vector<slope_monitor::TiePointArray> ties_;
  std::vector<diagnostic_msgs::DiagnosticStatus> diags_;
  std::vector<rosgraph_msgs::Log> logs_;
  cv::Mat scene_;
};

TEST_F(HexMatcherRos, KnownShiftBadInputAndRecovery) {
  GoodPair(100.0, 1);

  // Different sizes: dropped, named in the log and in diagnostics, nothing published.
  size_t before = TieCount();
  Publish(Crop(40, 40, 3), "mono8", Crop(40, 40, 4)(cv::Rect(0, 0, kW - 20, kH)).clone(), "mono8",
          200.0);
  EXPECT_TRUE(WaitFor([&] { return LogSays("differ in size"); }, 20.0))
      << "no error naming the size mismatch";
  EXPECT_TRUE(WaitFor([&] { return DiagnosticSays("differ in size"); }, 20.0));
  EXPECT_EQ(TieCount(), before);

  // Different encodings (mono8 / mono16): dropped, named in diagnostics (the
  // log is throttled to one error per 5 s).
  cv::Mat b16;
  Crop(40 - kShift.x, 40 - kShift.y, 6).convertTo(b16, CV_16U, 256.0);
  Publish(Crop(40, 40, 5), "mono8", b16, "mono16", 300.0);
  EXPECT_TRUE(WaitFor([&] { return DiagnosticSays("differ in encoding"); }, 20.0))
      << "no diagnostics naming the encoding mismatch";
  EXPECT_EQ(TieCount(), before);

  // Textureless pair: a clear outcome (an empty tie-point set), no fake matches.
  Publish(cv::Mat(kH, kW, CV_8U, cv::Scalar(120)), "mono8", cv::Mat(kH, kW, CV_8U, cv::Scalar(121)),
          "mono8", 400.0);
  ASSERT_TRUE(WaitFor([&] { return TieCount() > before; }, 30.0))
      << "no answer to the textureless pair";
  EXPECT_EQ(LastTies().points.size(), 0u);

  // Still running: the next good pair is matched as before.
  GoodPair(500.0, 7);
}

// The operator's outline of an obstacle (exclude_boxes [100, 80, 200, 160]
// on the second node): the matches with xa inside it are published with
// quality <= 0.25, the others with normal quality and the known shift.
TEST_F(HexMatcherRos, ExcludeBoxesMarkTheOutlinedMatches) {
  ros::NodeHandle nh;
  ros::Publisher pa = nh.advertise<sensor_msgs::Image>("/hm_boxes/image_a", 2);
  ros::Publisher pb = nh.advertise<sensor_msgs::Image>("/hm_boxes/image_b", 2);
  std::mutex m;
  std::vector<slope_monitor::TiePointArray> got;
  ros::Subscriber sub = nh.subscribe<slope_monitor::TiePointArray>(
      "/hm_boxes/tie_points", 5, [&](const slope_monitor::TiePointArrayConstPtr& t) {
        std::lock_guard<std::mutex> l(m);
        got.push_back(*t);
      });
  ASSERT_TRUE(WaitFor(
      [&] {
        return pa.getNumSubscribers() > 0 && pb.getNumSubscribers() > 0 &&
               sub.getNumPublishers() > 0;
      },
      60.0));
  std_msgs::Header h;
  h.stamp = ros::Time(1000.0);
  pa.publish(cv_bridge::CvImage(h, "mono8", Crop(40, 40, 11)).toImageMsg());
  pb.publish(cv_bridge::CvImage(h, "mono8", Crop(40 - kShift.x, 40 - kShift.y, 12)).toImageMsg());
  ASSERT_TRUE(WaitFor(
      [&] {
        std::lock_guard<std::mutex> l(m);
        return !got.empty();
      },
      30.0));
  std::lock_guard<std::mutex> l(m);
  int inside = 0, outside_normal = 0, outside = 0;
  for (const auto& p : got.back().points) {
    if (p.xa >= 100 && p.xa <= 200 && p.ya >= 80 && p.ya <= 160) {
      ++inside;
      EXPECT_LE(p.quality, 0.25) << "(" << p.xa << ", " << p.ya << ") inside the box";
    } else {
      ++outside;
      if (p.quality > 0.25 && std::hypot(p.xb - p.xa - kShift.x, p.yb - p.ya - kShift.y) <= 0.2)
        ++outside_normal;
    }
  }
  std::printf(
      "exclude_boxes: %d tie points inside the box (all low quality), %d outside, %d of them "
      "normal and "
      "within 0.2 px\n",
      inside, outside, outside_normal);
  EXPECT_GT(inside, 10);
  EXPECT_GE(outside_normal, 0.97 * outside);
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "hex_matcher_test");
  ros::NodeHandle nh;
  return RUN_ALL_TESTS();
}
