#include "slope_monitor/ros/setup.h"

#include <atomic>
#include <memory>

#include <std_msgs/UInt8.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/parameters.h"

namespace slope_monitor {
namespace ros_adapters {

std::optional<std::string> SetUpError(const std::function<void()>& set_up) {
  try {
    set_up();
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

SetUpFailureDiagnostics::SetUpFailureDiagnostics(
    const ros::NodeHandle& nh, const ros::NodeHandle& pnh, const std::string& name,
    const std::string& cause, std::vector<std::pair<std::string, std::string>> values)
    : cause_(cause), values_(std::move(values)), updater_(nh, pnh) {
  updater_.setHardwareID(name);
  updater_.add(name, [this](diagnostic_updater::DiagnosticStatusWrapper& stat) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "not running: " + cause_);
    for (const auto& [key, value] : values_) stat.add(key, value);
  });
  timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                              [this](const ros::WallTimerEvent&) { updater_.force_update(); });
  updater_.force_update();
}

GraphReady::~GraphReady() { pnh_.setParam(kGraphReadyParam, true); }

namespace {
std::atomic<int> g_exit_status{0};
}  // namespace

void EndProcess(int status) {
  int seen = g_exit_status.load();
  while (status > seen && !g_exit_status.compare_exchange_weak(seen, status)) {
  }
  ros::requestShutdown();
}

int ProcessExitStatus() { return g_exit_status.load(); }

bool LiveTimeouts() { return !ros::Time::isSimTime(); }

ros::Subscriber SubscribeEndOfInput(ros::NodeHandle& nh, EndOfInputStage stage,
                                    std::function<void()> finish) {
  if (LiveTimeouts()) return ros::Subscriber();
  auto done = std::make_shared<bool>(false);
  return nh.subscribe<std_msgs::UInt8>(
      kEndOfInputTopic, kEndOfInputStages,
      [stage, finish = std::move(finish), done](const std_msgs::UInt8ConstPtr& m) {
        if (m->data != stage || *done) return;
        *done = true;
        finish();
      });
}

}  // namespace ros_adapters
}  // namespace slope_monitor
