// Node shim: runs the camera_capture nodelet in-process (nodelet::Loader), so
// `rosrun slope_monitor camera_capture_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "camera_capture");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/CameraCapture", remappings, my_argv)) {
    ROS_FATAL("camera_capture_node: cannot load the nodelet slope_monitor/CameraCapture");
    return 1;
  }
  ros::spin();
  return 0;
}
