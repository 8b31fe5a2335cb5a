// Node shim: runs the dense_epoch nodelet (one surface per adjusted epoch) in-process
// (nodelet::Loader), so `rosrun slope_monitor dense_epoch_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "dense_epoch");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/DenseEpoch", remappings, my_argv)) {
    ROS_FATAL("dense_epoch_node: cannot load the nodelet slope_monitor/DenseEpoch");
    return 1;
  }
  ros::spin();
  return 0;
}
