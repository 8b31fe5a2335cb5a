// replay_end: ends replay.launch when the graph has processed the whole bag.
//
//   <node pkg="slope_monitor" type="replay_end" name="replay_end" required="true"/>
//
// The player (replay_player) says when it has published the bag's last
// message (`<player>/finished`, std_msgs/Bool, latched) and stays up; on a
// fast replay or a busy machine the graph is then still epochs behind
// (images waiting for the centroiders, an adjustment being solved) and the
// player's publishers may still be sending photos: a launch that stopped
// then would drop what its nodes had not processed yet, and the reports
// would depend on the rate and on the CPU. replay_end waits for the player
// to finish (or to end: another player, such as rosbag play, that exits at
// the end of its bag), then until no thread of the graph's processes (every
// node of this master but rosout and itself, the player included, on this
// machine) is running or waiting for the CPU or the disk (state R or D in
// /proc/<pid>/task/*/stat) in every sample of `quiet` seconds, and exits:
// roslaunch then stops the nodes and the player, and the deformation
// estimator writes its reports. In a replay the graph has no time-outs
// (ros/setup.h LiveTimeouts), so before it exits replay_end announces the
// end of the input on /replay/end_of_input, stage by stage, waiting for the
// graph to be idle after each (ros/setup.h kEndOfMatching ...
// kEndOfSurfaces): what a live time-out would have released (a photo waiting
// for its prior, an epoch whose camera never sent its end marker) is
// processed as process_bag's end of input does, and the same bag gives the
// same numbers at any rate and load.
//
// Private parameters:
//   player  (string, "/player")  the player node (replay_player)
//   quiet   (double, 1.0 s)      how long the graph must stay idle (0.1..60)
//   timeout (double, 3600 s)     wall time after the player's end; then exit 1 naming the busy
//   nodes
#include <dirent.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <std_msgs/Bool.h>
#include <std_msgs/UInt8.h>
#include <xmlrpcpp/XmlRpcClient.h>

#include "slope_monitor/ros/setup.h"

namespace {

using Clock = std::chrono::steady_clock;

bool NodeRunning(const std::string& name) {
  std::vector<std::string> nodes;
  if (!ros::master::getNodes(nodes)) return true;  // master busy: ask again later
  for (const std::string& n : nodes)
    if (n == name) return true;
  return false;
}

// The process id of a node of this machine, -1 if it cannot be had.
int PidOf(const std::string& node) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  args[1] = node;
  if (!ros::master::execute("lookupNode", args, result, payload, false)) return -1;
  std::string host;
  uint32_t port = 0;
  if (!ros::network::splitURI(static_cast<std::string>(payload), host, port)) return -1;
  XmlRpc::XmlRpcClient client(host.c_str(), static_cast<int>(port), "/");
  XmlRpc::XmlRpcValue request, response;
  request[0] = ros::this_node::getName();
  if (!client.execute("getPid", request, response) ||
      response.getType() != XmlRpc::XmlRpcValue::TypeArray || response.size() < 3 ||
      static_cast<int>(response[0]) != 1)
    return -1;
  const int pid = static_cast<int>(response[2]);
  // Another machine's node (processing_machine): its pid means nothing here.
  std::ifstream cmdline("/proc/" + std::to_string(pid) + "/cmdline");
  std::string text((std::istreambuf_iterator<char>(cmdline)), std::istreambuf_iterator<char>());
  return text.find("__name:=" + node.substr(node.rfind('/') + 1)) != std::string::npos ? pid : -1;
}

// The graph's processes, the player's included: node name -> pid.
std::map<std::string, int> GraphProcesses() {
  std::vector<std::string> nodes;
  ros::master::getNodes(nodes);
  std::map<std::string, int> out;
  for (const std::string& n : nodes) {
    if (n == "/rosout" || n == ros::this_node::getName()) continue;
    const int pid = PidOf(n);
    if (pid > 0) out[n] = pid;
  }
  return out;
}

// True when a thread of `pid` runs or waits for the CPU or the disk.
bool Busy(int pid) {
  const std::string dir = "/proc/" + std::to_string(pid) + "/task";
  DIR* d = opendir(dir.c_str());
  if (!d) return false;  // ended
  bool busy = false;
  while (dirent* e = readdir(d)) {
    if (e->d_name[0] == '.') continue;
    std::ifstream in(dir + "/" + e->d_name + "/stat");
    std::string line;
    std::getline(in, line);
    const size_t paren = line.rfind(')');
    if (paren == std::string::npos || paren + 2 >= line.size()) continue;
    const char state = line[paren + 2];
    if (state == 'R' || state == 'D') busy = true;
  }
  closedir(d);
  return busy;
}

// Waits until no process of `graph` is busy in any sample of `needed` 0.1 s
// steps. False (logged, naming the busy nodes) after `timeout` s from `since`.
bool WaitIdle(const std::map<std::string, int>& graph, int needed, Clock::time_point since,
              double timeout) {
  int idle = 0;
  while (ros::ok() && idle < needed) {
    std::string busy;
    for (const auto& [node, pid] : graph)
      if (Busy(pid)) busy += (busy.empty() ? "" : ", ") + node;
    idle = busy.empty() ? idle + 1 : 0;
    if (std::chrono::duration<double>(Clock::now() - since).count() > timeout) {
      ROS_ERROR("replay_end: the graph is still busy %.0f s after the end of the bag (timeout): %s",
                timeout, busy.c_str());
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  // --help: the usage, before ros::init (no master contacted, nothing changed).
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "-h" || std::string(argv[i]) == "--help") {
      std::cout << "usage: replay_end [__name:=NAME] [_player:=/player] [_quiet:=1.0] "
                   "[_timeout:=3600]\n"
                   "Started by launch/replay.launch (required): waits for the player to finish\n"
                   "the bag (its ~finished, or its end), announces the end of input on\n"
                   "/replay/end_of_input stage by stage, waits until the graph's processes (the\n"
                   "player's included) have been idle for `quiet` s after each, and exits,\n"
                   "which ends the launch (the estimator then writes its reports). Exit\n"
                   "status 0 when the graph went idle, 1 on a bad parameter or when it was still\n"
                   "busy `timeout` s after the player's end (the busy nodes named).\n";
      return 0;
    }
  ros::init(argc, argv, "replay_end");
  ros::NodeHandle pnh("~");
  std::string player;
  double quiet = 1.0, timeout = 3600.0;
  pnh.param<std::string>("player", player, "/player");
  pnh.param("quiet", quiet, 1.0);
  pnh.param("timeout", timeout, 3600.0);
  if (!(quiet >= 0.1 && quiet <= 60.0) || !(timeout > 0.0)) {
    ROS_ERROR("replay_end: parameter '%s' must be in 0.1..60 s and '%s' > 0 s (got %g and %g)",
              pnh.resolveName("quiet").c_str(), pnh.resolveName("timeout").c_str(), quiet, timeout);
    return 1;
  }
  ros::AsyncSpinner spinner(1);
  spinner.start();
  ros::NodeHandle nh;
  ros::Publisher end_pub =
      nh.advertise<std_msgs::UInt8>(slope_monitor::ros_adapters::kEndOfInputTopic,
                                    slope_monitor::ros_adapters::kEndOfInputStages, true);
  const auto step = std::chrono::milliseconds(100);
  // The player: seen, then finished (its ~finished) or gone.
  std::atomic<bool> finished{false};
  ros::Subscriber finished_sub = nh.subscribe<std_msgs::Bool>(
      player + "/finished", 1, [&finished](const std_msgs::BoolConstPtr& m) {
        if (m->data) finished = true;
      });
  while (ros::ok() && !finished && !NodeRunning(player)) std::this_thread::sleep_for(step);
  while (ros::ok() && !finished && NodeRunning(player)) std::this_thread::sleep_for(step);
  if (!ros::ok()) return 0;
  const auto ended = Clock::now();
  const std::map<std::string, int> graph = GraphProcesses();
  ROS_INFO("replay_end: %s has %s the bag; waiting for %zu node process(es) to finish their work",
           player.c_str(), finished ? "finished" : "ended", graph.size());
  const int needed = static_cast<int>(std::lround(quiet / 0.1));
  if (!WaitIdle(graph, needed, ended, timeout)) return 1;
  for (int stage = 1; stage <= slope_monitor::ros_adapters::kEndOfInputStages && ros::ok();
       ++stage) {
    std_msgs::UInt8 m;
    m.data = static_cast<uint8_t>(stage);
    end_pub.publish(m);
    // Delivered and taken up (a node that starts work is busy from then on).
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    if (!WaitIdle(graph, needed, ended, timeout)) return 1;
  }
  ROS_INFO("replay_end: the graph is idle %.1f s after the end of the bag; ending the replay",
           std::chrono::duration<double>(Clock::now() - ended).count());
  return 0;
}
