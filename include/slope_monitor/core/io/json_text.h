// The text of every JSON file the package writes (nlohmann::json): indented
// by two spaces, UTF-8, a newline at the end. Numbers that are not finite
// (NaN, infinity) are written as null, as JSON has no other spelling for
// them; a reader takes null as "not available".
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace slope_monitor {
namespace io {

template <typename Json>
std::string JsonText(const Json& value) {
  return value.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

}  // namespace io
}  // namespace slope_monitor
