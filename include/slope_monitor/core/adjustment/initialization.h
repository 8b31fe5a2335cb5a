// Initial values for the bundle adjustment from the geometry module: images
// whose exterior orientation is unknown are resected from the points already
// known (control points start at their survey), then unknown points are
// intersected from the oriented images, repeated until nothing changes.
#pragma once

#include <string>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/geometry/intersection.h"
#include "slope_monitor/core/geometry/resection.h"

namespace slope_monitor {
namespace adjustment {

struct InitializationOptions {
  geometry::ResectionOptions resection;
  geometry::IntersectionOptions intersection;
  int max_passes = 4;
};

// Returns "" when every image and every point observed by >= 2 images has an
// initial value, else the reason (naming the image or points left unknown).
// Points that cannot be intersected are left with position_known = false.
std::string InitializeScene(Scene* scene, const InitializationOptions& options = {});

}  // namespace adjustment
}  // namespace slope_monitor
