// bag_check's core (CheckBag) on the real turtlesim bags (uncompressed, bz2,
// lz4; counts from `rosbag info`), on a truncated copy, an empty and a non-bag
// file, and on a bag written by the test with EpochMarker messages.
#include <fstream>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <std_msgs/String.h>

#include "../core/capture/test_images.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/capture_conversions.h"

namespace slope_monitor {
namespace {

const std::string kDir = std::string(SM_TEST_DATA_DIR) + "/rosbag_turtlesim/";

void ExpectTurtlesim(const ros_adapters::BagReport& r) {
  // Reference: `rosbag info` of the same files.
  EXPECT_EQ(r.messages, 8647u);
  EXPECT_NEAR(r.start, 1396293887.84, 0.01);
  EXPECT_NEAR(r.end, 1396293909.54, 0.01);
  const std::map<std::string, std::pair<uint64_t, std::string>> expected = {
      {"/rosout", {10, "rosgraph_msgs/Log"}},
      {"/tf", {2688, "tf/tfMessage"}},
      {"/tf_static", {1, "tf2_msgs/TFMessage"}},
      {"/turtle1/cmd_vel", {357, "geometry_msgs/Twist"}},
      {"/turtle1/color_sensor", {1351, "turtlesim/Color"}},
      {"/turtle1/pose", {1344, "turtlesim/Pose"}},
      {"/turtle2/cmd_vel", {208, "geometry_msgs/Twist"}},
      {"/turtle2/color_sensor", {1344, "turtlesim/Color"}},
      {"/turtle2/pose", {1344, "turtlesim/Pose"}}};
  ASSERT_EQ(r.topics.size(), expected.size());
  for (const auto& t : r.topics) {
    ASSERT_TRUE(expected.count(t.topic)) << t.topic;
    EXPECT_EQ(t.count, expected.at(t.topic).first) << t.topic;
    EXPECT_EQ(t.datatype, expected.at(t.topic).second) << t.topic;
  }
  // One epoch by time gaps (the bag lasts 21.7 s, epoch_gap 600 s) holding every message.
  EXPECT_FALSE(r.epochs_from_markers);
  ASSERT_EQ(r.epochs.size(), 2u);
  EXPECT_FALSE(r.epochs[0].end);
  EXPECT_TRUE(r.epochs[1].end);
  EXPECT_EQ(r.epochs[1].count, 8647u);
}

TEST(BagCheck, TurtlesimUncompressedBz2Lz4) {
  ros_adapters::BagCheckOptions o;
  for (const char* name : {"example.bag", "example-bz2.bag", "example-lz4.bag"}) {
    SCOPED_TRACE(name);
    const ros_adapters::BagReport r = ros_adapters::CheckBag(kDir + name, o);
    ExpectTurtlesim(r);
    const std::string text = ros_adapters::FormatBagReport(r);
    EXPECT_NE(text.find("/turtle1/pose  turtlesim/Pose  1344 msgs"), std::string::npos) << text;
  }
}

TEST(BagCheck, GapsAndTimeGapEpochs) {
  ros_adapters::BagCheckOptions o;
  o.gap = 0.5;
  o.epoch_gap = 0.01;
  const ros_adapters::BagReport r = ros_adapters::CheckBag(kDir + "example.bag", o);
  // Only /turtle1/cmd_vel pauses longer than 0.5 s (its longest pause is
  // 0.976 s; every other topic's is under 0.2 s, see `rqt_bag`/bag_check).
  ASSERT_FALSE(r.gaps.empty());
  for (const auto& g : r.gaps) {
    EXPECT_EQ(g.topic, "/turtle1/cmd_vel");
    EXPECT_GT(g.to - g.from, 0.5);
  }
  for (const auto& t : r.topics) {
    if (t.topic == "/turtle1/cmd_vel") {
      EXPECT_NEAR(t.max_gap, 0.976, 0.001);
    } else {
      EXPECT_LT(t.max_gap, 0.2) << t.topic;
    }
  }
  // Epoch boundaries alternate start/end and the counts add up to every message.
  uint64_t total = 0;
  for (size_t i = 0; i < r.epochs.size(); ++i) {
    EXPECT_EQ(r.epochs[i].end, i % 2 == 1);
    if (r.epochs[i].end) total += r.epochs[i].count;
  }
  EXPECT_EQ(total, 8647u);
}

TEST(BagCheck, TruncatedEmptyAndNonBagFilesNameTheFile) {
  capture_test::TempDir dir("bagcheck");
  const std::string truncated = dir.File("truncated.bag");
  capture_test::WriteTruncatedCopy(kDir + "example.bag", truncated, 0.5);
  const std::string empty = dir.File("empty.bag");
  capture_test::WriteText(empty, "");
  const std::string text = dir.File("notes.bag");
  capture_test::WriteText(text, "these are field notes, not a bag\n");
  for (const std::string& path : {truncated, empty, text, dir.File("missing.bag")}) {
    try {
      ros_adapters::CheckBag(path, ros_adapters::BagCheckOptions{});
      ADD_FAILURE() << "no exception for " << path;
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
  }
}

TEST(BagCheck, EpochMarkersWrittenByTheTest) {
  capture_test::TempDir dir("bagcheck2");
  const std::string path = dir.File("epochs.bag");
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::LZ4);
    const double t0 = 1700000000.0;
    for (uint32_t e = 0; e < 2; ++e) {
      const double start = t0 + e * 21600.0;  // 6 h apart
      slope_monitor::EpochMarker m;
      m.epoch = e;
      m.end = false;
      m.source = "/uav/camera";
      bag.write("/uav/camera/epoch", ros::Time(start), m);
      for (int i = 0; i < 3; ++i) {
        std_msgs::String s;
        s.data = "image";
        bag.write("/uav/camera/image_stub", ros::Time(start + 1.0 + 2.0 * i), s);
      }
      m.end = true;
      m.count = 3;
      bag.write("/uav/camera/epoch", ros::Time(start + 6.0), m);
    }
  }
  const ros_adapters::BagReport r = ros_adapters::CheckBag(path, ros_adapters::BagCheckOptions{});
  EXPECT_EQ(r.messages, 10u);
  EXPECT_TRUE(r.epochs_from_markers);
  ASSERT_EQ(r.epochs.size(), 4u);
  EXPECT_FALSE(r.epochs[0].end);
  EXPECT_TRUE(r.epochs[1].end);
  EXPECT_EQ(r.epochs[1].count, 3u);
  EXPECT_EQ(r.epochs[2].epoch, 1u);
  EXPECT_DOUBLE_EQ(r.epochs[2].time, 1700021600.0);
  EXPECT_EQ(r.epochs[3].topic, "/uav/camera/epoch");
  // The 6 h pause is a gap on both topics.
  EXPECT_EQ(r.gaps.size(), 2u);
}

// A recording split in three files (as rosbag record --split writes it): the
// middle file holds no marker. Per file it falls back to time-gap epochs;
// as one session (CheckBags) the epochs span the splits, counts add up.
TEST(BagCheck, SplitSessionAsOneRecording) {
  capture_test::TempDir dir("bagcheck_split");
  const double t0 = 1700000000.0;
  const std::vector<std::string> paths = {dir.File("s_0.bag"), dir.File("s_1.bag"),
                                          dir.File("s_2.bag")};
  slope_monitor::EpochMarker m;
  m.epoch = 4;
  m.source = "/uav/camera";
  std_msgs::String s;
  s.data = "image";
  {
    rosbag::Bag bag(paths[0], rosbag::bagmode::Write);
    bag.write("/uav/camera/epoch", ros::Time(t0), m);
    bag.write("/uav/camera/image_stub", ros::Time(t0 + 1.0), s);
  }
  {
    rosbag::Bag bag(paths[1], rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::LZ4);
    bag.write("/uav/camera/image_stub", ros::Time(t0 + 3.0), s);
    bag.write("/uav/camera/image_stub", ros::Time(t0 + 5.0), s);
  }
  {
    rosbag::Bag bag(paths[2], rosbag::bagmode::Write);
    bag.write("/uav/camera/image_stub", ros::Time(t0 + 7.0), s);
    m.end = true;
    m.count = 4;
    bag.write("/uav/camera/epoch", ros::Time(t0 + 7.5), m);
  }
  const ros_adapters::BagReport middle =
      ros_adapters::CheckBag(paths[1], ros_adapters::BagCheckOptions{});
  EXPECT_FALSE(middle.epochs_from_markers);
  const ros_adapters::BagReport r = ros_adapters::CheckBags(paths, ros_adapters::BagCheckOptions{});
  EXPECT_EQ(r.messages, 6u);
  EXPECT_DOUBLE_EQ(r.start, t0);
  EXPECT_DOUBLE_EQ(r.end, t0 + 7.5);
  ASSERT_EQ(r.topics.size(), 2u);
  EXPECT_EQ(r.topics[1].topic, "/uav/camera/image_stub");
  EXPECT_EQ(r.topics[1].count, 4u);
  EXPECT_DOUBLE_EQ(r.topics[1].max_gap, 2.0);
  EXPECT_TRUE(r.epochs_from_markers);
  ASSERT_EQ(r.epochs.size(), 2u);
  EXPECT_FALSE(r.epochs[0].end);
  EXPECT_TRUE(r.epochs[1].end);
  EXPECT_EQ(r.epochs[1].epoch, 4u);
  EXPECT_EQ(r.epochs[1].count, 4u);
  EXPECT_TRUE(r.gaps.empty());
  // A bad part is named.
  capture_test::WriteText(dir.File("notes.bag"), "not a bag\n");
  try {
    ros_adapters::CheckBags({paths[0], dir.File("notes.bag")}, ros_adapters::BagCheckOptions{});
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("notes.bag"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace slope_monitor
