// Areas of significant surface change as a measurement of the deformation
// estimator (source `surface`): the dense step's polygons of one epoch's DoD
// (dense/change_polygons.h) against the reference surface.
//
// Growth between epochs: each polygon of the new epoch is compared with the
// previous area epoch's polygons of the same sign that it intersects (OGR):
//   growth = its area - the sum of their areas
// (no intersecting polygon: its whole area, a new significant area). The
// first area epoch is the baseline (growth 0: change against the reference
// surface alone does not say that it grows). A polygon whose growth exceeds
// `growth_watch` raises watch, `growth_warning` warning; the areas' level is
// the highest of their polygons' and is held until the next area epoch.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "slope_monitor/core/deformation/estimator.h"

namespace slope_monitor {
namespace deformation {

// ChangeArea, AreaBatch, AreaState and AreaOptions are in estimator.h.

// Compares `current` with `previous`, the states of the last area epoch
// `previous_epoch` (none: `current` is the first, the baseline), and returns
// the states of the current polygons, largest first.
// Throws InvalidArgument for a polygon with fewer than 3 vertices or a
// non-finite value, naming the epoch and polygon.
std::vector<AreaState> AssessAreas(const std::vector<AreaState>& previous,
                                   std::optional<uint32_t> previous_epoch, const AreaBatch& current,
                                   const AreaOptions& options);

// The highest level of `areas`.
AlertLevel AreasAlert(const std::vector<AreaState>& areas);

}  // namespace deformation
}  // namespace slope_monitor
