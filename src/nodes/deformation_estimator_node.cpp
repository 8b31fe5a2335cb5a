// Node shim: runs the deformation_estimator nodelet in-process (nodelet::Loader),
// so `rosrun slope_monitor deformation_estimator_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "deformation_estimator");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/DeformationEstimator", remappings, my_argv)) {
    ROS_FATAL("deformation_estimator_node: cannot load the nodelet slope_monitor/DeformationEstimator");
    return 1;
  }
  ros::spin();
  return 0;
}
