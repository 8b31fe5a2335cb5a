// Reading what a notification hook received (deformation/alert_hook.h): the
// test hooks append each alert's one-line JSON to a file. Shared by
// alert_hook_test, the estimator_hook rostest and the process_bag hook test.
#pragma once

#include <cmath>
#include <cstdint>
#include <fstream>
#include <map>
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

// One point's alert-level change as the estimator published it.
struct LevelChange {
  std::string point, from, to;
  double speed_mm_per_day = 0.0;
};

// The level changes in a sequence of slope_monitor/SlopeDeformation
// messages (a template: this header has no ROS), the hook's expected runs.
class LevelChanges {
 public:
  template <typename Deformation>
  void Add(const Deformation& m) {
    static const char* const kLevels[] = {"none", "watch", "warning", "alarm"};
    for (const auto& p : m.points) {
      const uint8_t from = level_.count(p.point_id) ? level_[p.point_id] : 0;
      if (p.alert_level != from) {
        const double speed = std::sqrt(p.velocity.x * p.velocity.x + p.velocity.y * p.velocity.y +
                                       p.velocity.z * p.velocity.z);
        changes_.push_back({p.point_id, kLevels[from], kLevels[p.alert_level], speed * 86400e3});
      }
      level_[p.point_id] = p.alert_level;
    }
  }
  const std::vector<LevelChange>& changes() const { return changes_; }

 private:
  std::map<std::string, uint8_t> level_;
  std::vector<LevelChange> changes_;
};

}  // namespace hook_json
}  // namespace slope_monitor
