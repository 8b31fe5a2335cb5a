// Node shim: runs the bundle_adjuster nodelet in-process (nodelet::Loader),
// so `rosrun slope_monitor bundle_adjuster_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "bundle_adjuster");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/BundleAdjuster", remappings, my_argv)) {
    ROS_FATAL("bundle_adjuster_node: cannot load the nodelet slope_monitor/BundleAdjuster");
    return 1;
  }
  ros::spin();
  return 0;
}
