#include "slope_monitor/core/deformation/change_areas.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <ogr_geometry.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace deformation {
namespace {

void CheckArea(const ChangeArea& a, uint32_t epoch, size_t index) {
  const auto where = [&] { return Message("area epoch ", epoch, " polygon ", index + 1, ": "); };
  if (a.outline.size() < 3)
    throw InvalidArgument(Message(where(), "outline has ", a.outline.size(), " vertices (< 3)"));
  if (a.sign != 1 && a.sign != -1)
    throw InvalidArgument(Message(where(), "sign ", a.sign, " is not +1 or -1"));
  if (!(std::isfinite(a.area) && a.area >= 0.0 && std::isfinite(a.volume)))
    throw InvalidArgument(Message(where(), "area ", a.area, " m^2 / volume ", a.volume, " m^3"));
  for (const Eigen::Vector2d& v : a.outline)
    if (!v.allFinite()) throw InvalidArgument(Message(where(), "a vertex is not finite"));
}

std::unique_ptr<OGRPolygon> ToOgr(const ChangeArea& a) {
  auto poly = std::make_unique<OGRPolygon>();
  const auto ring = [](const std::vector<Eigen::Vector2d>& pts) {
    auto r = std::make_unique<OGRLinearRing>();
    for (const Eigen::Vector2d& v : pts) r->addPoint(v.x(), v.y());
    r->closeRings();
    return r;
  };
  poly->addRingDirectly(ring(a.outline).release());
  for (const auto& h : a.holes) poly->addRingDirectly(ring(h).release());
  return poly;
}

}  // namespace

void AreaOptions::Check() const {
  if (!(growth_watch > 0.0))
    throw ConfigError(Message("areas: growth_watch ", growth_watch, " m^2 must be > 0"));
  if (!(growth_warning > growth_watch))
    throw ConfigError(Message("areas: growth_warning ", growth_warning,
                              " m^2 must be > growth_watch ", growth_watch, " m^2"));
}

std::vector<AreaState> AssessAreas(const std::vector<AreaState>& previous,
                                   std::optional<uint32_t> previous_epoch, const AreaBatch& current,
                                   const AreaOptions& options) {
  for (size_t k = 0; k < current.areas.size(); ++k) CheckArea(current.areas[k], current.epoch, k);
  std::vector<std::unique_ptr<OGRPolygon>> before;
  before.reserve(previous.size());
  for (const AreaState& p : previous) before.push_back(ToOgr(p.area));
  std::vector<ChangeArea> sorted = current.areas;
  std::stable_sort(sorted.begin(), sorted.end(),
                   [](const ChangeArea& a, const ChangeArea& b) { return a.area > b.area; });
  std::vector<AreaState> out;
  for (size_t k = 0; k < sorted.size(); ++k) {
    AreaState s;
    char id[32];
    std::snprintf(id, sizeof(id), "e%02u/%zu", current.epoch, k + 1);
    s.id = id;
    s.area = sorted[k];
    s.epoch = current.epoch;
    s.stamp = current.stamp;
    const char* kind = s.area.sign > 0 ? "gain" : "loss";
    if (!previous_epoch) {
      s.reason = Message("area ", s.id, " (", kind, ") ", s.area.area,
                         " m^2: the first area epoch, the baseline of growth");
      out.push_back(std::move(s));
      continue;
    }
    const std::unique_ptr<OGRPolygon> poly = ToOgr(s.area);
    double earlier = 0.0;
    int overlapping = 0;
    for (size_t j = 0; j < previous.size(); ++j) {
      if (previous[j].area.sign != s.area.sign || !poly->Intersects(before[j].get())) continue;
      earlier += previous[j].area.area;
      ++overlapping;
    }
    s.growth = s.area.area - earlier;
    if (s.growth > options.growth_warning) {
      s.alert = AlertLevel::kWarning;
    } else if (s.growth > options.growth_watch) {
      s.alert = AlertLevel::kWatch;
    }
    s.reason = Message("area ", s.id, " (", kind, ") ", s.area.area, " m^2, grown by ", s.growth,
                       " m^2 since epoch ", *previous_epoch, " (", overlapping,
                       " earlier polygon(s) of ", earlier, " m^2); thresholds watch ",
                       options.growth_watch, " / warning ", options.growth_warning, " m^2");
    out.push_back(std::move(s));
  }
  return out;
}

AlertLevel AreasAlert(const std::vector<AreaState>& areas) {
  AlertLevel level = AlertLevel::kNone;
  for (const AreaState& a : areas) level = std::max(level, a.alert);
  return level;
}

}  // namespace deformation
}  // namespace slope_monitor
