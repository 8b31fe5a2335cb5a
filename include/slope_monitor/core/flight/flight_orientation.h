// Orientation of a flight's photos without targets (doc/design.md: collinearity
// bundle adjustment with self-calibration), from what the flight gives:
//
//  1. a relative start: the pair with the most tie points and enough
//     parallax is oriented by the five-point relative orientation
//     (geometry::RelativeOrientation); its points are intersected;
//  2. incremental growth: the photo that sees most known points is resected
//     (geometry::Resect, RANSAC), new points are intersected; each time the
//     oriented photos grow by a quarter, a bundle adjustment of all oriented
//     photos (self-calibrating c and k1; the start pair held) refines the
//     block and observations off by more than max_reprojection_px are
//     dropped (COLMAP's incremental mapper works the same way). Start and
//     growth run on FlightTies::growth_tracks when there are any; then the
//     ties' own tracks are intersected from the oriented photos and carry
//     the adjustments below;
//  3. georeferencing: a similarity from the model to the site, fitted to the
//     control points intersected from their picks (>= 3), else to the
//     photos' GNSS positions (>= 3, not on one line); else the block stays in
//     its model frame (no scale, said in FlightSummary::datum);
//  4. the final adjustment in the site frame: GNSS positions as priors with
//     their sigma, control points with their survey sigma, interior
//     c, x0, y0, k1, k2, k3 free (c, k1, k2 below min_photos_full_calibration
//     photos), covariance of every pose and point;
//  5. check points (never in the adjustment) intersected from their picks
//     with the adjusted orientation; their residual per point in metres;
//     with leave_one_out, each control point in turn left out (the
//     adjustment repeated without it) and its residual reported the same way.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/flight/flight_matching.h"
#include "slope_monitor/core/geometry/intersection.h"
#include "slope_monitor/core/geometry/relative_orientation.h"
#include "slope_monitor/core/geometry/resection.h"
#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace flight {

struct FlightOrientationOptions {
  geometry::RelativeOrientationOptions relative = [] {
    geometry::RelativeOrientationOptions o;
    o.inlier_threshold_px = 2.0;  // the nominal camera has no distortion yet
    return o;
  }();
  double min_start_parallax_deg = 3.0;  // start pair's median ray angle at least this, > 0
  geometry::ResectionOptions resection = [] {
    geometry::ResectionOptions o;
    o.inlier_threshold_px = 8.0;  // the nominal camera has no distortion yet
    o.max_iterations = 500;
    return o;
  }();
  geometry::IntersectionOptions intersection = [] {
    geometry::IntersectionOptions o;
    o.min_angle_deg = 1.5;
    return o;
  }();
  int min_resection_points = 15;        // known points a photo must see to be resected, >= 6
  double growth_for_adjustment = 1.25;  // adjust when the oriented photos grow by this factor, > 1
  double max_reprojection_px = 4.0;     // observations farther after an adjustment are dropped, > 0
  double tie_sigma_px = 0.5;            // [px] a tie point's standard deviation, > 0
  double pick_sigma_px = io::kGcpPickSigmaPx;  // [px] a control point picked by hand, > 0
  double gnss_sigma_horizontal_m = capture::kExifGnssSigmaHorizontal;  // [m] > 0
  double gnss_sigma_vertical_m = capture::kExifGnssSigmaVertical;      // [m] > 0
  int min_photos_full_calibration = 12;  // fewer oriented photos: only c, k1, k2 free, >= 3
  bool leave_one_out = true;             // re-adjust once per control point without it
  adjustment::Options bundle = [] {
    adjustment::Options o;
    o.loss = "cauchy";
    o.loss_scale = 3.0;
    o.max_iterations = 200;
    o.function_tolerance = 1e-7;
    o.min_control_points = 3;
    o.max_outlier_fraction = 0.3;
    o.max_sigma0 = 20.0;
    o.num_threads = 1;  // bit-identical numbers on any machine load
    return o;
  }();
  int intermediate_iterations = 50;  // Ceres iterations of the adjustments while growing, > 0
  void Check() const;                // throws ConfigError naming the field
};

// A control or check point with its picks.
struct FlightControlPoint {
  std::string name;
  Eigen::Vector3d site = Eigen::Vector3d::Zero();  // [m] survey in the site frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity() * 0.05 * 0.05;  // [m^2]
  bool check = false;  // true: never in the adjustment
  // false: the height is not known (a gcp list with every height 0): give
  // covariance(2, 2) loose; the residuals' dz is reported as 0.
  bool has_height = true;
  std::vector<std::pair<int, Eigen::Vector2d>> picks;  // (photo index, pixel)
};

struct FlightInput {
  const FlightPhotos* photos = nullptr;
  const FlightTies* ties = nullptr;
  std::vector<std::optional<Eigen::Vector3d>> gnss_in_site;  // per photo (empty: none)
  std::vector<FlightControlPoint> control;
};

struct PointResidual {
  std::string name;
  bool check = false;
  int picks = 0;          // picks in oriented photos
  bool measured = false;  // false: too few picks in oriented photos (message)
  std::string message;
  Eigen::Vector3d residual = Eigen::Vector3d::Zero();  // [m] photogrammetric - survey
  // [px] control points: RMS of the picks' reprojection errors (a pick far
  // off, or a survey that disagrees with the block, shows here).
  double pick_rms_px = 0.0;
};

struct FlightSummary {
  bool success = false;  // an adjusted block of >= 2 photos
  std::string message;   // why not, or the notes in one line
  int photos = 0, oriented = 0;
  int points = 0, observations = 0;
  double rms_px = 0.0, mean_px = 0.0;  // reprojection error of the kept observations
  double sigma0 = 0.0;
  std::string covariance_note;  // "" or why the final adjustment has no covariance (sigmas then 0)
  std::string
      datum;  // "7 control points", "GNSS of 8 photos", "model frame (no datum: arbitrary scale)"
  bool georeferenced = false;
  std::vector<std::string> not_oriented;  // "<photo>: <reason>"
  std::vector<PointResidual> control, check, leave_one_out;
  double control_rms = 0.0, check_rms = 0.0, leave_one_out_rms = 0.0;  // [m] 3-D
  std::map<std::string, double>
      seconds;  // "start", "growth", "georeference", "adjustment", "leave_one_out"
  std::array<double, camera::kNumInterior> interior_sigma{};
};

struct FlightResult {
  adjustment::Scene
      scene;  // oriented photos and their tie points ("tie/<k>"; control points are in the summary)
  std::vector<int> photo_of_image;           // scene image -> photo index
  std::vector<std::uint8_t> point_grey;      // per scene point
  std::vector<double> point_error_px;        // per scene point: mean reprojection error
  std::vector<double> observation_error_px;  // per scene observation
  adjustment::Summary bundle;
  FlightSummary summary;
};

// progress: ("oriented", photos oriented, photos) after each photo added.
FlightResult OrientFlight(const FlightInput& input, const FlightOrientationOptions& options = {},
                          const StageProgress& progress = {});

// The reprojection error of result->scene (one camera) per observation and
// point (observation_error_px, point_error_px) and the summary's
// observations, points, mean_px and rms_px.
void MeasureReprojection(FlightResult* result);

}  // namespace flight
}  // namespace slope_monitor
