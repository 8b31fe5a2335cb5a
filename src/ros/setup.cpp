#include "slope_monitor/ros/setup.h"

#include "slope_monitor/core/common/error.h"

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

}  // namespace ros_adapters
}  // namespace slope_monitor
