// Node shim: runs the hex_matcher nodelet in-process (nodelet::Loader),
// so `rosrun slope_monitor hex_matcher_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "hex_matcher");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/HexMatcher", remappings, my_argv)) {
    ROS_FATAL("hex_matcher_node: cannot load the nodelet slope_monitor/HexMatcher");
    return 1;
  }
  ros::spin();
  return 0;
}
