// launch/record.launch for real (test/rostest/camera_capture_record.test):
// the test node starts `roslaunch slope_monitor record.launch` (lz4, split at
// 1 MB) into a temporary directory, loads a camera_capture nodelet on a photo
// folder it wrote (two epochs of three 640x480 photos), publishes radio
// sample blocks (recorded) and an unrelated topic (not), stops the recorder
// with SIGINT once the last epoch has ended, and checks the bags: their names
// (site, date, start time, split index), lz4 chunks, and what the bag_check
// tool reports per file and for the files as one session (--session) —
// topics, counts and epoch boundaries.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <regex>
#include <sstream>

#include <XmlRpcValue.h>
#include <gtest/gtest.h>
#include <nodelet/NodeletLoad.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>

#include "../core/capture/test_images.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/ros/capture_conversions.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

using rostest_node::WaitFor;

// Nodes subscribed to `topic` (from the master's system state).
std::vector<std::string> Subscribers(const std::string& topic) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  std::vector<std::string> out;
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return out;
  XmlRpc::XmlRpcValue& subs = payload[1];
  for (int i = 0; i < subs.size(); ++i) {
    if (static_cast<std::string>(subs[i][0]) != topic) continue;
    for (int j = 0; j < subs[i][1].size(); ++j)
      out.push_back(static_cast<std::string>(subs[i][1][j]));
  }
  return out;
}

// Runs a command, returns its standard output (and error) and exit status.
std::string RunCommand(const std::string& command, int* status) {
  std::string out;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) {
    *status = -1;
    return out;
  }
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof(buf), pipe)) > 0) out.append(buf, n);
  const int s = pclose(pipe);
  *status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
  return out;
}

TEST(CameraCaptureRecord, RecordLaunchSplitsCompressesAndBagCheckReports) {
  capture_test::TempDir photos("record_photos"), out("record_bags");
  constexpr int kW = 640, kH = 480;
  const std::vector<std::string> times = {"10:00:00", "10:00:01", "10:00:02",
                                          "11:00:00", "11:00:01", "11:00:02"};
  for (size_t i = 0; i < times.size(); ++i) {
    capture_test::ExifTags t;
    t.date_time = "2024:05:01 " + times[i];
    t.gps = true;
    t.lat_deg = 35.1 + 1e-4 * i;
    t.lon_deg = 139.2;
    t.alt_m = 1200.0;
    capture_test::WriteJpeg(photos.File("p" + std::to_string(i) + ".jpg"),
                            capture_test::TexturedImage(kW, kH, 3, static_cast<int>(i)), t);
  }

  // Our own count of what was published.
  ros::NodeHandle nh("/rec/camera");
  std::mutex mutex;
  int published = 0;
  bool last_epoch_ended = false;
  ros::Subscriber image_sub =
      nh.subscribe<sensor_msgs::Image>("image_raw", 10, [&](const sensor_msgs::ImageConstPtr&) {
        std::lock_guard<std::mutex> l(mutex);
        ++published;
      });
  ros::Subscriber epoch_sub = nh.subscribe<slope_monitor::EpochMarker>(
      "epoch", 10, [&](const slope_monitor::EpochMarkerConstPtr& m) {
        std::lock_guard<std::mutex> l(mutex);
        if (m->end && m->epoch == 1) last_epoch_ended = true;
      });

  // The recorder, as a crew starts it.
  const std::string site = "smtest", date = "2024-05-01";
  const pid_t launch = fork();
  ASSERT_GE(launch, 0) << "fork failed";
  if (launch == 0) {
    const std::string dir_arg = "dir:=" + out.path();
    execlp("roslaunch", "roslaunch", "slope_monitor", "record.launch", ("site:=" + site).c_str(),
           ("date:=" + date).c_str(), dir_arg.c_str(), "compression:=lz4", "split_size:=1",
           "split_duration:=1h", static_cast<char*>(nullptr));
    _exit(127);
  }
  struct Stopper {
    pid_t pid;
    bool stopped = false;
    // SIGINT (what Ctrl-C sends): rosbag closes its bags. True when it exited.
    bool Stop(double timeout) {
      if (stopped) return true;
      kill(pid, SIGINT);
      const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
      while (ros::WallTime::now() < end) {
        int status = 0;
        if (waitpid(pid, &status, WNOHANG) == pid) return stopped = true;
        ros::WallDuration(0.1).sleep();
      }
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
      stopped = true;
      return false;
    }
    ~Stopper() { Stop(20.0); }
  } stopper{launch};

  // A radio receiver's samples (recorded) and an unrelated topic (not).
  ros::NodeHandle root;
  ros::Publisher radio_pub =
      root.advertise<slope_monitor::RadioSampleBlock>("/radio/rx_test/samples", 10);
  ros::Publisher other_pub = root.advertise<std_msgs::String>("/field_notes/chatter", 10);

  const std::string recorder = "/record_" + site;
  ASSERT_TRUE(WaitFor(
      [&] {
        std::vector<std::string> nodes;
        return ros::master::getNodes(nodes) &&
               std::find(nodes.begin(), nodes.end(), recorder) != nodes.end();
      },
      40.0))
      << recorder << " did not start";

  // The capture nodelet: publishing starts start_delay after loading, by
  // when the recorder (which polls the master every second) has subscribed.
  const std::string name = "/rec/camera/camera_capture";
  const std::map<std::string, XmlRpc::XmlRpcValue> params = {{"source", "folder"},
                                                             {"folder", photos.path()},
                                                             {"rate", 5.0},
                                                             {"start_delay", 4.0},
                                                             {"epoch_gap", 600.0}};
  for (const auto& [key, value] : params) ros::param::set(name + "/" + key, value);
  ASSERT_TRUE(ros::service::waitForService("/capture_manager/load_nodelet", ros::Duration(30.0)));
  nodelet::NodeletLoad load;
  load.request.name = name;
  load.request.type = "slope_monitor/CameraCapture";
  const ros::WallTime loaded = ros::WallTime::now();
  ASSERT_TRUE(ros::service::call("/capture_manager/load_nodelet", load) && load.response.success);
  ASSERT_TRUE(WaitFor(
      [&] {
        const auto s = Subscribers("/rec/camera/image_raw");
        return std::find(s.begin(), s.end(), recorder) != s.end();
      },
      10.0))
      << recorder << " did not subscribe to /rec/camera/image_raw";
  EXPECT_LT((ros::WallTime::now() - loaded).toSec(), 4.0)
      << "the recorder subscribed after publishing started; counts below would be short";
  ASSERT_TRUE(WaitFor(
      [&] {
        const auto s = Subscribers("/radio/rx_test/samples");
        return std::find(s.begin(), s.end(), recorder) != s.end() &&
               radio_pub.getNumSubscribers() > 0;
      },
      10.0))
      << recorder << " did not subscribe to /radio/rx_test/samples";
  for (uint32_t k = 0; k < 5; ++k) {
    slope_monitor::RadioSampleBlock block;
    block.header.stamp = ros::Time::now();
    block.receiver_id = "rx_test";
    block.sequence = k;
    block.i.assign(64, 0.5f);
    radio_pub.publish(block);
    std_msgs::String note;
    note.data = "not for the bag";
    other_pub.publish(note);
    ros::WallDuration(0.05).sleep();
  }
  ASSERT_TRUE(WaitFor(
      [&] {
        std::lock_guard<std::mutex> l(mutex);
        return last_epoch_ended;
      },
      30.0))
      << "the capture did not finish";
  // The end marker travels on its own connection and can overtake the last
  // (0.9 MB) image on a loaded machine: give the images a moment to arrive.
  WaitFor(
      [&] {
        std::lock_guard<std::mutex> l(mutex);
        return published >= 6;
      },
      10.0);
  EXPECT_EQ(published, 6);
  ros::WallDuration(1.5).sleep();  // the recorder writes its queue
  ASSERT_TRUE(stopper.Stop(20.0)) << "roslaunch did not stop on SIGINT";

  // Bag files: <dir>/<site>_<date>_YYYY-MM-DD-HH-MM-SS_<n>.bag, all closed.
  const std::regex pattern(site + "_" + date + R"(_\d{4}-\d\d-\d\d-\d\d-\d\d-\d\d_(\d+)\.bag)");
  std::map<int, std::string> bags;
  for (const auto& e : std::filesystem::directory_iterator(out.path())) {
    const std::string file = e.path().filename().string();
    std::smatch m;
    EXPECT_TRUE(std::regex_match(file, m, pattern)) << "unexpected file " << file;
    if (std::regex_match(file, m, pattern)) bags[std::stoi(m[1])] = e.path().string();
  }
  ASSERT_GE(bags.size(), 2u) << "6 images of 0.9 MB split at 1 MB give several bags";
  EXPECT_EQ(bags.begin()->first, 0);
  std::string files;
  for (const auto& [index, path] : bags) {
    files += " '" + path + "'";
    std::ifstream in(path, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(bytes.find("compression=lz4"), std::string::npos) << path << " has no lz4 chunk";
    EXPECT_EQ(bytes.find("compression=none"), std::string::npos)
        << path << " has an uncompressed chunk";
  }

  // The bag_check tool: each split file on its own (all readable, counts add
  // up), then the files as one session (epoch boundaries across the splits).
  const std::regex topic_line(R"(^  (/\S+)  (\S+)  (\d+) msgs .*)");
  const std::regex epoch_line(R"(^  (start|end)\s+epoch (\d+) at [0-9.]+(  count (\d+))?.*)");
  auto parse = [&](const std::string& report, std::map<std::string, int>* counts,
                   std::vector<std::string>* boundaries) {
    std::istringstream lines(report);
    std::string line;
    while (std::getline(lines, line)) {
      std::smatch m;
      if (std::regex_match(line, m, topic_line)) (*counts)[m[1]] += std::stoi(m[3]);
      if (std::regex_match(line, m, epoch_line)) {
        boundaries->push_back(m[1].str() + " " + m[2].str() +
                              (m[4].matched ? " " + m[4].str() : ""));
      }
    }
  };
  int status = -1;
  const std::string per_file = RunCommand("rosrun slope_monitor bag_check" + files, &status);
  EXPECT_EQ(status, 0) << per_file;
  std::map<std::string, int> file_counts;
  std::vector<std::string> file_boundaries;
  parse(per_file, &file_counts, &file_boundaries);
  const std::string report =
      RunCommand("rosrun slope_monitor bag_check --session" + files, &status);
  EXPECT_EQ(status, 0) << report;
  std::map<std::string, int> counts;
  std::vector<std::string> boundaries;
  parse(report, &counts, &boundaries);
  for (const char* topic :
       {"/rec/camera/image_raw", "/rec/camera/camera_info", "/rec/camera/gnss/fix"}) {
    EXPECT_EQ(counts[topic], 6) << topic << "\n" << report;
    EXPECT_EQ(file_counts[topic], 6) << topic << "\n" << per_file;
  }
  EXPECT_EQ(counts["/rec/camera/epoch"], 4) << report;
  EXPECT_EQ(counts["/radio/rx_test/samples"], 5) << report;
  EXPECT_EQ(counts.count("/field_notes/chatter"), 0u) << "recorded a topic outside topics_regex\n"
                                                      << report;
  EXPECT_EQ(file_counts["/rec/camera/epoch"], 4) << per_file;
  EXPECT_EQ(boundaries, (std::vector<std::string>{"start 0", "end 0 3", "start 1", "end 1 3"}))
      << report;

  // The same through the library, and the images in the bags are the photos.
  int images = 0;
  for (const auto& [index, path] : bags) {
    const ros_adapters::BagReport r = ros_adapters::CheckBag(path, ros_adapters::BagCheckOptions());
    for (const auto& t : r.topics) {
      if (t.topic == "/rec/camera/image_raw") {
        EXPECT_EQ(t.datatype, "sensor_msgs/Image");
        images += static_cast<int>(t.count);
      }
    }
  }
  EXPECT_EQ(images, 6);
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "camera_capture_record_test");
}
