// Node shim: runs the radio_phase_solver nodelet in-process (nodelet::Loader),
// so `rosrun slope_monitor radio_phase_solver_node` works without a manager.
#include <nodelet/loader.h>
#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "radio_phase_solver");
  nodelet::Loader loader(false);
  nodelet::M_string remappings(ros::names::getRemappings());
  nodelet::V_string my_argv(argv + 1, argv + argc);
  if (!loader.load(ros::this_node::getName(), "slope_monitor/RadioPhaseSolver", remappings, my_argv)) {
    ROS_FATAL("radio_phase_solver_node: cannot load the nodelet slope_monitor/RadioPhaseSolver");
    return 1;
  }
  ros::spin();
  return 0;
}
