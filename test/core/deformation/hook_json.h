// Reading what a notification hook received (deformation/alert_hook.h): the
// test hooks append each alert's one-line JSON to a file. Shared by
// alert_hook_test, the estimator_hook rostest and the process_bag hook test.
#pragma once

#include <fstream>
#include <string>
#include <vector>

namespace slope_monitor {
namespace hook_json {

// The non-empty lines of a file (one hook run each).
inline std::vector<std::string> Lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);)
    if (!l.empty()) lines.push_back(l);
  return lines;
}

// The value of "key" in one line of flat JSON, as written: a string without
// its quotes, a number or literal as text; "<absent>" when the key is absent.
inline std::string Field(const std::string& json, const std::string& key) {
  const std::string k = "\"" + key + "\": ";
  const size_t a = json.find(k);
  if (a == std::string::npos) return "<absent>";
  const size_t b = a + k.size();
  if (json[b] == '"') return json.substr(b + 1, json.find('"', b + 1) - b - 1);
  return json.substr(b, json.find_first_of(",}", b) - b);
}

}  // namespace hook_json
}  // namespace slope_monitor
