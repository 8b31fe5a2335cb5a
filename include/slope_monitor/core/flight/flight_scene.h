// The flight orientation (flight_orientation.h) for an epoch the graph has
// collected: the bundle adjuster's scene of one UAV camera's photos, their
// tie points (hex_matcher, mode sequence), GNSS position priors and any
// control points they see. InitializeScene (adjustment/initialization.h)
// starts only from >= 4 known points or the flight log's attitude; a UAV
// flight without targets has neither, so its photos are started here, with
// the same code process_flight runs on a photo folder.
#pragma once

#include <string>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/flight/flight_orientation.h"

namespace slope_monitor {
namespace flight {

// Orients the images of camera `camera` in *scene: relative start,
// resection/intersection growth and self-calibrating adjustments on the
// scene's tie points, georeferenced by the images' GNSS position priors (their
// covariance gives the sigma) or the control points they see. Writes the
// exterior orientations (exterior_known = true), the tie points' positions
// (position_known = true) and the camera's interior (distortion model radial
// for a camera without distortion terms, else its own)
// into *scene; leaves *scene as it was when the summary says no success.
// Throws InvalidArgument naming the camera when the scene has none of that name.
FlightSummary OrientSceneFromTiePoints(adjustment::Scene* scene, const std::string& camera,
                                       const FlightOrientationOptions& options = {});

// The block of camera `camera` in an adjusted scene, as the flight writers
// (flight_export.h) take it: its images, the points they see (any role) and
// those observations, the precision of both, points grey 128 (the graph
// keeps no colour), the reprojection errors (MeasureReprojection).
FlightResult BlockOfCamera(const adjustment::Scene& scene, const adjustment::Summary& summary,
                           const std::string& camera);

}  // namespace flight
}  // namespace slope_monitor
