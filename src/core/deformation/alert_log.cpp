#include "slope_monitor/core/deformation/alert_log.h"

#include <cmath>
#include <cstdio>
#include <ctime>

namespace slope_monitor {
namespace deformation {
namespace {

std::string Text(const PointState& p, AlertLevel from) {
  char speed[96];
  std::snprintf(speed, sizeof(speed), "speed %.2f +- %.2f mm/day", p.speed * 86400e3,
                p.speed_sigma * 86400e3);
  std::string forecast;
  if (p.forecast.valid) {
    const std::time_t t = static_cast<std::time_t>(std::floor(p.forecast.failure_time));
    std::tm tm{};
    gmtime_r(&t, &tm);
    char when[32], sigma[32];
    std::strftime(when, sizeof(when), "%Y-%m-%dT%H:%M:%SZ", &tm);
    std::snprintf(sigma, sizeof(sigma), "%.1f", p.forecast.sigma / 3600.0);
    forecast = std::string("failure forecast ") + when + " +- " + sigma + " h";
  } else {
    forecast =
        "no failure forecast" + (p.forecast.reason.empty() ? "" : " (" + p.forecast.reason + ")");
  }
  return "point " + p.id + ": alert " + AlertName(from) + " -> " + AlertName(p.alert) + ", " +
         speed + ", " + forecast + (p.alert_reason.empty() ? "" : "; " + p.alert_reason);
}

}  // namespace

std::vector<AlertChange> AlertChangeTracker::Update(const Snapshot& snapshot) {
  std::vector<AlertChange> changes;
  for (const PointState& p : snapshot.points) {
    auto it = levels_.find(p.id);
    const AlertLevel from = it == levels_.end() ? AlertLevel::kNone : it->second;
    if (p.alert != from) changes.push_back({p.id, from, p.alert, Text(p, from)});
    levels_[p.id] = p.alert;
  }
  if (snapshot.area_alert != area_level_) {
    std::string why;  // the reason of the (first) area at the new level
    for (const AreaState& a : snapshot.areas)
      if (a.alert == snapshot.area_alert && why.empty()) why = "; " + a.reason;
    changes.push_back({kSurfaceAreas, area_level_, snapshot.area_alert,
                       "areas of significant surface change: alert " + AlertName(area_level_) +
                           " -> " + AlertName(snapshot.area_alert) + why});
    area_level_ = snapshot.area_alert;
  }
  return changes;
}

}  // namespace deformation
}  // namespace slope_monitor
