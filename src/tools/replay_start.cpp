// replay_start: starts replay.launch's player when every node of the graph is
// ready, so that no node misses the first photos of a bag.
//
//   <node pkg="slope_monitor" type="replay_player" name="player" args="--pause ..."/>
//   <node pkg="slope_monitor" type="replay_start" name="replay_start"/>
//
// roslaunch starts the player and the graph together; a node that is still
// loading (a slow disk, a busy machine) when the player begins would miss
// the first messages and measure a different survey. The launch sets
// `<node>/graph_ready: false` for every node of the graph before any process
// starts, and each node sets it true when its onInit has returned
// (ros_adapters::GraphReady). replay_start waits until every `graph_ready`
// parameter on the server is true, then for `settle` seconds (the
// subscriptions connect to the player), and resumes the player through its
// `pause_playback` service. Past `timeout` it names the nodes that are not
// ready and starts the player anyway (their inputs are then incomplete).
//
// Private parameters:
//   player  (string, "/player")  the player node (replay_player, started with --pause)
//   settle  (double, 1.0 s)      wall time between ready and play (0..60)
//   timeout (double, 120 s)      wall time to wait for the nodes (> 0)
#include <chrono>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include <ros/ros.h>
#include <std_srvs/SetBool.h>

#include "slope_monitor/ros/parameters.h"

namespace {

// The nodes whose graph_ready parameter is not true yet; `total` counts all.
std::vector<std::string> NotReady(size_t* total) {
  std::vector<std::string> names, waiting;
  ros::param::getParamNames(names);
  const std::string suffix = std::string("/") + slope_monitor::ros_adapters::kGraphReadyParam;
  *total = 0;
  for (const std::string& n : names) {
    if (n.size() <= suffix.size() ||
        n.compare(n.size() - suffix.size(), suffix.size(), suffix) != 0)
      continue;
    ++*total;
    bool ready = false;
    if (!ros::param::get(n, ready) || !ready)
      waiting.push_back(n.substr(0, n.size() - suffix.size()));
  }
  return waiting;
}

std::string Join(const std::vector<std::string>& v) {
  std::string out;
  for (const std::string& s : v) out += (out.empty() ? "" : ", ") + s;
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  // --help: the usage, before ros::init (no master contacted, nothing changed).
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "-h" || std::string(argv[i]) == "--help") {
      std::cout
          << "usage: replay_start [__name:=NAME] [_player:=/player] [_settle:=1.0] "
             "[_timeout:=120]\n"
             "Started by launch/replay.launch: resumes the paused player (replay_player,\n"
             "its pause_playback service) once every node's ~graph_ready parameter is\n"
             "true, then `settle` s later; past `timeout` s it names the nodes not ready\n"
             "and starts the player anyway. Exit status 0 when the player was started, 1 on a\n"
             "bad parameter or when the player could not be resumed.\n";
      return 0;
    }
  ros::init(argc, argv, "replay_start");
  ros::NodeHandle pnh("~");
  std::string player;
  double settle = 1.0, timeout = 120.0;
  pnh.param<std::string>("player", player, "/player");
  pnh.param("settle", settle, 1.0);
  pnh.param("timeout", timeout, 120.0);
  if (!(settle >= 0.0 && settle <= 60.0) || !(timeout > 0.0)) {
    ROS_ERROR("replay_start: parameter '%s' must be in 0..60 s and '%s' > 0 s (got %g and %g)",
              pnh.resolveName("settle").c_str(), pnh.resolveName("timeout").c_str(), settle,
              timeout);
    return 1;
  }
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };
  size_t total = 0;
  std::vector<std::string> waiting = NotReady(&total);
  while (ros::ok() && !waiting.empty() && elapsed() < timeout) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    waiting = NotReady(&total);
  }
  if (!ros::ok()) return 0;
  if (waiting.empty()) {
    ROS_INFO("replay_start: %zu nodes ready after %.1f s; playing the bag", total, elapsed());
  } else {
    ROS_WARN(
        "replay_start: not ready after %.0f s: %s; playing the bag anyway (their inputs will be "
        "incomplete)",
        timeout, Join(waiting).c_str());
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(settle));
  const std::string service = player + "/pause_playback";
  if (!ros::service::waitForService(service, ros::Duration(timeout))) {
    ROS_ERROR("replay_start: the player's service '%s' did not come within %.0f s", service.c_str(),
              timeout);
    return 1;
  }
  std_srvs::SetBool resume;
  resume.request.data = false;  // false: play
  if (!ros::service::call(service, resume) || !resume.response.success) {
    ROS_ERROR("replay_start: '%s' refused to resume the player: %s", service.c_str(),
              resume.response.message.c_str());
    return 1;
  }
  return 0;
}
