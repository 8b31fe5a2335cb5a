// What the rostest test nodes share (header only): waiting for a condition
// in wall time, and the test node's main().
#pragma once

#include <functional>
#include <string>

#include <gtest/gtest.h>
#include <ros/ros.h>

namespace slope_monitor {
namespace rostest_node {

// Waits (wall time, polling every 50 ms) until pred() holds; false on timeout.
inline bool WaitFor(const std::function<bool()>& pred, double timeout) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && ros::WallTime::now() < end) {
    if (pred()) return true;
    ros::WallDuration(0.05).sleep();
  }
  return pred();
}

// The test node's main(): gtest, then the ROS node `node_name` with two
// spinner threads (callbacks run while a test waits), then every test.
inline int RunTests(int argc, char** argv, const std::string& node_name) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}

}  // namespace rostest_node
}  // namespace slope_monitor
