// Alert level changes as log lines a crew reads: which point, from which
// level to which, its speed with sigma, and the failure-time forecast.
//
//   AlertChangeTracker tracker;
//   for (const AlertChange& c : tracker.Update(snapshot)) log(c.level, c.text);
//
// The first snapshot reports every point already above `none` (a restart
// re-announces standing alerts); later snapshots report changes only. A
// change of the areas of surface change's level (Snapshot::area_alert) is
// reported as point "surface" with the area's reason.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "slope_monitor/core/deformation/estimator.h"

namespace slope_monitor {
namespace deformation {

// AlertChange::point_id of a change of the areas' level (Snapshot::area_alert).
constexpr const char* kSurfaceAreas = "surface";

struct AlertChange {
  std::string point_id;  // or kSurfaceAreas
  AlertLevel from = AlertLevel::kNone;
  AlertLevel to = AlertLevel::kNone;
  // "point tag36h11/3: alert watch -> warning, speed 12.40 +- 0.80 mm/day,
  //  failure forecast 2026-11-25T06:00:00Z +- 1.5 h" (or "no failure forecast (reason)").
  std::string text;
};

class AlertChangeTracker {
 public:
  std::vector<AlertChange> Update(const Snapshot& snapshot);

 private:
  std::map<std::string, AlertLevel> levels_;
  AlertLevel area_level_ = AlertLevel::kNone;
};

}  // namespace deformation
}  // namespace slope_monitor
