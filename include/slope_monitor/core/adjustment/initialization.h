// Initial values for the bundle adjustment from the geometry module: images
// whose exterior orientation is unknown are resected from the points already
// known (control points start at their survey), then unknown points are
// intersected from the oriented images, repeated until nothing changes.
#pragma once

#include <string>
#include <vector>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/geometry/intersection.h"
#include "slope_monitor/core/geometry/resection.h"

namespace slope_monitor {
namespace adjustment {

struct InitializationOptions {
  geometry::ResectionOptions resection;
  geometry::IntersectionOptions intersection;
  int max_passes = 20;  // resection / intersection rounds (a strip of photos tied by tie points
                        // orients one more photo a round)
  // Images with a GNSS position prior that cannot be resected (fewer than four
  // known points, as a UAV photo seeing two or three targets): the attitude is
  // fitted to the known points seen (>= 2) with the prior as projection centre,
  // and kept when every one reprojects within this [px] (0 = off).
  double prior_attitude_max_px = 25.0;
};

// Returns "" when every image and every point observed by >= 2 images has an
// initial value, else the reason (naming the image or points left unknown).
// Points that cannot be intersected are left with position_known = false.
std::string InitializeScene(Scene* scene, const InitializationOptions& options = {});

// What PruneScene removed, each with the reason ("image 'uav@17.0': 3
// observations of initialised points (min 4)").
struct PruneReport {
  std::vector<std::string> dropped_images;
  std::vector<std::string> dropped_points;
  std::vector<std::string> dropped_cameras;
  bool Empty() const {
    return dropped_images.empty() && dropped_points.empty() && dropped_cameras.empty();
  }
  std::string Summary() const;  // one line: counts and the first few reasons
};

// The part of an initialised scene that can be adjusted: drops points without
// an initial position, then repeatedly images without an orientation or with
// fewer than `min_observations_per_image` observations, points no image sees
// any more, and cameras with no image left; re-indexes what stays. One weak
// image (a UAV photo with three targets) no longer sinks the whole epoch.
// Images with a position prior need min_observations_with_prior instead
// (-1: the same as min_observations_per_image).
Scene PruneScene(const Scene& scene, int min_observations_per_image, PruneReport* report = nullptr,
                 int min_observations_with_prior = -1);

}  // namespace adjustment
}  // namespace slope_monitor
