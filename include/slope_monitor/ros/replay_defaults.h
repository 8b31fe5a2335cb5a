// Where a replay of a survey bag keeps its history when not told: one rule
// for process_bag (--database) and launch/replay.launch (database:=), which
// writes the same rule as an $(eval) (roslaunch cannot call this code;
// test/ros/safe_defaults_test.cpp checks that the launch file gives what
// this function gives). Issue 38: both used to share ~/.ros/slope_monitor/replay.db,
// so a second bag continued the first bag's history.
#pragma once

#include <string>

namespace slope_monitor {
namespace ros_adapters {

// The history of `bag` (a path) when none is named:
// <home>/.ros/slope_monitor/<the bag's file name less its 4-character ".bag">.db,
// e.g. /data/site_a.bag -> ~/.ros/slope_monitor/site_a.db. Two bags of other
// names never share one; the same bag processed again continues its own.
std::string DefaultHistoryOfBag(const std::string& bag, const std::string& home);

}  // namespace ros_adapters
}  // namespace slope_monitor
