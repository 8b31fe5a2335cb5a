#include "slope_monitor/ros/replay_defaults.h"

namespace slope_monitor {
namespace ros_adapters {

std::string DefaultHistoryOfBag(const std::string& bag, const std::string& home) {
  // As replay.launch's $(eval arg('bag').split('/')[-1][:-4]).
  const size_t slash = bag.rfind('/');
  const std::string name = slash == std::string::npos ? bag : bag.substr(slash + 1);
  const std::string stem = name.size() > 4 ? name.substr(0, name.size() - 4) : "";
  return home + "/.ros/slope_monitor/" + stem + ".db";
}

}  // namespace ros_adapters
}  // namespace slope_monitor
