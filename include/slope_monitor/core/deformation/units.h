// The unit the deformation reports and alerts state speeds in.
#pragma once

namespace slope_monitor {
namespace deformation {

// m/s -> mm/day (speeds are m/s inside, mm/day wherever a person reads them).
constexpr double kMmPerDay = 86400e3;

}  // namespace deformation
}  // namespace slope_monitor
