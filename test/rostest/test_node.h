// What the rostest test nodes share (header only): waiting for a condition
// in wall time or for the bag's clock, reading a parameter, a service call
// with a time-out, and the test node's main().
#pragma once

#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <string>
#include <thread>

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

// Waits (wall time, polling every 0.5 s) until the ROS clock (the bag's
// simulated time under rosbag play --clock) reaches `until`, or until done()
// holds if given; false after `timeout` seconds of wall time.
inline bool WaitForClock(const ros::Time& until, double timeout,
                         const std::function<bool()>& done = {}) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout);
  while (ros::ok() && ros::Time::now() < until && !(done && done())) {
    if (ros::WallTime::now() >= end) return false;
    ros::WallDuration(0.5).sleep();
  }
  return true;
}

// A private double parameter with its fallback.
inline double Param(const ros::NodeHandle& nh, const std::string& key, double fallback) {
  double v = fallback;
  nh.param(key, v, fallback);
  return v;
}

// The test node's main(): gtest, then the ROS node `node_name` with two
// spinner threads (callbacks run while a test waits), then every test.
// ros::service::call that cannot hang a test: false when the call fails
// or has not returned after `timeout` seconds (the call goes on in a
// thread of its own; its answer is then dropped). A hung call would leave
// rostest to kill the test at its time-limit without any result.
template <class Service>
bool CallWithin(const std::string& name, Service* srv, double timeout) {
  auto request = std::make_shared<Service>(*srv);
  auto answered = std::make_shared<std::promise<bool>>();
  std::future<bool> done = answered->get_future();
  std::thread([name, request, answered] {
    answered->set_value(ros::service::call(name, *request));
  }).detach();
  if (done.wait_for(std::chrono::duration<double>(timeout)) != std::future_status::ready) {
    ADD_FAILURE() << name << " did not answer within " << timeout << " s";
    return false;
  }
  if (!done.get()) return false;
  *srv = *request;
  return true;
}

inline int RunTests(int argc, char** argv, const std::string& node_name) {
  ::testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, node_name);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  return RUN_ALL_TESTS();
}

}  // namespace rostest_node
}  // namespace slope_monitor
