// Node shim: runs the slope_monitor/TargetCentroider nodelet in-process.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "target_centroider");
  nodelet::Loader loader;
  nodelet::M_string remap(ros::names::getRemappings());
  nodelet::V_string nargv;
  if (!loader.load(ros::this_node::getName(), "slope_monitor/TargetCentroider", remap, nargv)) {
    ROS_ERROR("target_centroider: could not load the nodelet slope_monitor/TargetCentroider");
    return 1;
  }
  ros::spin();
  return 0;
}
