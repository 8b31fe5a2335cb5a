// Node shim: runs the targetless_camera nodelet (fixed_targetless cameras) in-process
// (nodelet::Loader), so `rosrun slope_monitor targetless_camera_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "targetless_camera");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/TargetlessCamera", remappings,
                   my_argv)) {
    ROS_FATAL("targetless_camera_node: cannot load the nodelet slope_monitor/TargetlessCamera");
    return 1;
  }
  ros::spin();
  return 0;
}
