// replay.launch's player (launch/include/replay_player.xml: replay_player,
// replay_start, replay_end) on a bag of full-size photos: every photo
// reaches a plain subscriber of the graph, the launch ends by itself, and
// the player burns no CPU once it has finished (issue 34, item 1).
//
// Before: rosbag play ended as soon as it had handed the last photo to its
// publishers and dropped what they had not sent yet (measured on 8 photos
// of 36 MB at rate 400: 0 of 8 reached a subscriber; rosbag play
// --keep-alive delivered them but then used 63-73 % of a core).
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <dirent.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Bool.h>

#include "run_command.h"

// A named namespace: ros_tests is a unity build (helpers of other files).
namespace replay_player_test {

namespace fs = std::filesystem;

// The photos: as many bytes as a 12 MP RGB photo (36 MB), each filled with
// its index, 4 s of bag time apart (a UAV's shutter interval).
constexpr int kPhotos = 3;
constexpr uint32_t kWidth = 4000, kHeight = 3000;  // [px], rgb8
constexpr double kInterval = 4.0;                  // [s] bag time
const char kTopic[] = "/replay_player_test/camera/image_raw";

// The process whose command line holds both `a` and `b`; -1 if none.
int FindProcess(const std::string& a, const std::string& b) {
  DIR* d = opendir("/proc");
  int found = -1;
  while (dirent* e = d ? readdir(d) : nullptr) {
    const int pid = std::atoi(e->d_name);
    if (pid <= 0) continue;
    std::ifstream in("/proc/" + std::to_string(pid) + "/cmdline");
    const std::string cmd((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (cmd.find(a) != std::string::npos && cmd.find(b) != std::string::npos) found = pid;
  }
  if (d) closedir(d);
  return found;
}

// User + system CPU time of a process [s]; -1 when it has ended.
double CpuSeconds(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return -1.0;
  std::istringstream fields(line.substr(line.rfind(')') + 2));
  std::string f;
  double ticks = 0.0;
  for (int i = 3; i <= 15 && fields >> f; ++i)
    if (i >= 14) ticks += std::stod(f);  // utime, stime (fields 14, 15)
  return ticks / static_cast<double>(sysconf(_SC_CLK_TCK));
}

TEST(ReplayPlayer, EveryFullSizePhotoReachesTheGraphAndTheLaunchEnds) {
  const fs::path dir =
      fs::temp_directory_path() / ("replay_player_test_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string bag_path = (dir / "photos.bag").string();
  {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Write);
    sensor_msgs::Image image;
    image.width = kWidth;
    image.height = kHeight;
    image.encoding = "rgb8";
    image.step = 3 * kWidth;
    for (int i = 0; i < kPhotos; ++i) {
      image.header.seq = static_cast<uint32_t>(i);
      image.header.stamp = ros::Time(1.8e9 + i * kInterval);
      image.data.assign(static_cast<size_t>(image.step) * kHeight, static_cast<uint8_t>(i + 1));
      bag.write(kTopic, image.header.stamp, image);
    }
  }
  // The launch: the player trio as replay.launch starts it, at its default
  // rate and delay, and this test as the graph (its graph_ready set false by
  // the launch, true once it has subscribed, as a node of the graph does).
  const std::string launch = (dir / "replay_player_test.launch").string();
  std::ofstream(launch) << "<launch>\n"
                        << "  <param name=\"image_counter/graph_ready\" value=\"false\"/>\n"
                        << "  <include file=\"" << SM_SOURCE_DIR
                        << "/launch/include/replay_player.xml\">\n"
                        << "    <arg name=\"bag\" value=\"" << bag_path << "\"/>\n"
                        << "    <arg name=\"rate\" value=\"400\"/>\n"
                        << "    <arg name=\"start_delay\" value=\"1\"/>\n"
                        << "  </include>\n"
                        << "</launch>\n";
  const int port = slope_monitor::run_command::FreePort();
  ASSERT_GT(port, 0);
  const std::string master = "http://127.0.0.1:" + std::to_string(port);
  slope_monitor::run_command::CommandRun run;
  const auto started = std::chrono::steady_clock::now();
  std::atomic<bool> launch_ended{false};
  std::thread roslaunch([&] {
    run = slope_monitor::run_command::Run(
        "ROS_MASTER_URI=" + master + " ROS_LOG_DIR=" + (dir / "log").string() +
        " ROS_HOME=" + (dir / "ros_home").string() + " timeout -s INT 120 roslaunch -p " +
        std::to_string(port) + " " + launch);
    launch_ended = true;
  });

  ros::M_string remappings = {
      {"__master", master}, {"__ip", "127.0.0.1"}, {"__log", (dir / "image_counter.log").string()}};
  ros::init(remappings, "image_counter", ros::init_options::NoSigintHandler);
  const auto waited = [&](double s) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count() > s;
  };
  while (!waited(60) && !launch_ended && !ros::master::check())
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::mutex mutex;
  std::vector<int> received;  // the photos' indices in arrival order (-1: damaged)
  std::atomic<bool> finished{false};
  bool declared = false;
  double player_cpu = -1.0;  // [s] of the finished player over 2 s
  if (!ros::master::check()) {
    roslaunch.join();  // no master: the launch failed (its output below)
  } else {
    ros::NodeHandle nh;
    ros::Subscriber images =
        nh.subscribe<sensor_msgs::Image>(kTopic, 100, [&](const sensor_msgs::ImageConstPtr& m) {
          const bool whole = m->data.size() == static_cast<size_t>(3 * kWidth) * kHeight &&
                             m->data.front() == m->header.seq + 1 &&
                             m->data.back() == m->header.seq + 1;
          std::lock_guard<std::mutex> lock(mutex);
          received.push_back(whole ? static_cast<int>(m->header.seq) : -1);
        });
    ros::Subscriber done = nh.subscribe<std_msgs::Bool>(
        "/player/finished", 1, [&](const std_msgs::BoolConstPtr& m) { finished = m->data; });
    ros::AsyncSpinner spinner(1);
    spinner.start();
    // Ready once the launch has declared this node (roslaunch sets the
    // parameters before it starts any node).
    while (!waited(60) && !launch_ended && !declared) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      declared = ros::param::has("/image_counter/graph_ready");
    }
    if (declared) ros::param::set("/image_counter/graph_ready", true);
    const auto all_received = [&] {
      std::lock_guard<std::mutex> lock(mutex);
      return received.size() >= static_cast<size_t>(kPhotos);
    };
    while (declared && !waited(90) && !launch_ended && !(finished && all_received()))
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    // The player has finished: its CPU over the next 2 s, while replay_end
    // waits for the graph (rosbag play --keep-alive: 63-73 % of a core).
    const int player = FindProcess("replay_player", bag_path);
    const double cpu0 = player > 0 ? CpuSeconds(player) : -1.0;
    std::this_thread::sleep_for(std::chrono::seconds(2));
    const double cpu1 = player > 0 ? CpuSeconds(player) : -1.0;
    if (finished && cpu0 >= 0.0 && cpu1 >= 0.0) player_cpu = cpu1 - cpu0;
    roslaunch.join();  // replay_end ends the launch
    spinner.stop();
  }
  ros::shutdown();
  std::cout << "roslaunch: exit " << run.status << " after "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()
            << " s\n";
  ASSERT_TRUE(declared) << "the launch did not start:\n" << run.output;
  EXPECT_TRUE(finished) << "the player never said it had finished (~finished)";
  std::cout << "finished player: " << player_cpu / 2.0 * 100.0 << " % of a core\n";
  EXPECT_GE(player_cpu, 0.0) << "no finished replay_player process to measure";
  EXPECT_LT(player_cpu, 0.2) << "the finished player used " << player_cpu / 2.0 * 100.0
                             << " % of a core";
  EXPECT_EQ(run.status, 0) << "the launch did not end by itself (124: stopped after 120 s):\n"
                           << run.output;
  EXPECT_NE(run.output.find("replay_end: the graph is idle"), std::string::npos) << run.output;
  std::vector<int> all;
  for (int i = 0; i < kPhotos; ++i) all.push_back(i);
  EXPECT_EQ(received, all) << "photos received (index, -1: damaged), of " << kPhotos;
  fs::remove_all(dir);
}

}  // namespace replay_player_test
