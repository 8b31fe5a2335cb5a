// Every node shim <name>_node: runs the nodelet slope_monitor/<Name> in-process
// (nodelet::Loader), so `rosrun slope_monitor <name>_node` works without a
// manager. One source compiled once for all of them (CMakeLists.txt): the
// executable's own name says which nodelet it loads (hex_matcher_node ->
// node hex_matcher, nodelet slope_monitor/HexMatcher). Its exit status is
// the nodelet's (ros/setup.h: EndProcess), 0 unless it recorded a failure.
#include <cctype>
#include <cstdio>
#include <string>

#include <nodelet/loader.h>
#include <ros/ros.h>

#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/ros/setup.h"

namespace {

// "radio_phase_solver" -> "RadioPhaseSolver".
std::string CamelCase(const std::string& snake) {
  std::string out;
  bool up = true;
  for (char c : snake) {
    if (c == '_') {
      up = true;
    } else {
      out += up ? static_cast<char>(std::toupper(static_cast<unsigned char>(c))) : c;
      up = false;
    }
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  std::string exe = argv[0];
  exe = exe.substr(exe.find_last_of('/') + 1);
  const std::string suffix = "_node";
  if (exe.size() <= suffix.size() ||
      exe.compare(exe.size() - suffix.size(), suffix.size(), suffix) != 0) {
    std::fprintf(stderr, "%s: a node shim must be called <name>_node (e.g. hex_matcher_node)\n",
                 exe.c_str());
    return 2;
  }
  const std::string name = exe.substr(0, exe.size() - suffix.size());
  const std::string nodelet = "slope_monitor/" + CamelCase(name);
  ros::init(argc, argv, name);
  nodelet::Loader loader(false);
  const nodelet::M_string& remappings = ros::names::getRemappings();
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), nodelet, remappings, my_argv)) {
    ROS_FATAL("%s: cannot load the nodelet %s", exe.c_str(), nodelet.c_str());
    return 1;
  }
  ros::spin();
  // A one-shot nodelet that could not do its job (ros/setup.h: EndProcess).
  return slope_monitor::ros_adapters::ProcessExitStatus();
}
