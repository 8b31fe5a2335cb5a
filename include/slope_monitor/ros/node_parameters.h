// The parameters of the processing nodes, read once into typed options: one
// reader per node, used by its nodelet (from the parameter server) and by the
// process_bag tool (from the same config/defaults/*.yaml, ros/param_files.h),
// so both run the core with the same settings. Keys, units, defaults and
// ranges: config/defaults/<node>.yaml. Every reader throws ConfigError naming
// the key (and CheckNoUnknownKeys is called on the reader).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/plot_report.h"
#include "slope_monitor/core/deformation/report.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/core/radio/phase_solver.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {
namespace ros_adapters {

// The monitoring graph's adjustment, where it differs from the library's
// adjustment::Options: displacements compared datum-free (their covariance
// without the datum's), and a sigma0 below 1 does not shrink the
// covariances (min_variance_factor 1: image noise better than assumed is
// not taken as a smaller displacement uncertainty).
inline adjustment::EpochAdjustmentOptions MonitoringEpochOptions() {
  adjustment::EpochAdjustmentOptions e;
  e.adjustment.compute_datum_free_covariance = true;
  e.adjustment.min_variance_factor = 1.0;
  return e;
}

// Every field's in-class value is the default a node gets when neither
// config/defaults/<node>.yaml nor the launch sets the key (the readers take
// them from here; test/ros/config_files_test.cpp checks the yaml files
// against them).
struct AdjusterParameters {
  // The site's history (deformation/history.h, the estimator's database):
  // the reference epoch is kept there (SavedStates "adjuster") and a later
  // run measures from it; "" = the reference lives in this run only.
  std::string database;
  std::string site_file;                   // "" = none: target_list and the parameters decide
  std::optional<SiteCrsOptions> site_crs;  // the site file's frame (when there is one)
  // "" = off; else each accepted epoch's UAV blocks (with a site file) go to
  // <block_dir>/epoch_<n>/<camera>/ as process_flight writes a flight.
  std::string block_dir;
  // Each accepted epoch with control points: every control point left out in
  // turn and its residual logged (adjustment::LeaveOneOut).
  bool leave_one_out = true;
  std::string target_list_path;  // or "<site file> (inline targets)"
  io::TargetList targets;        // the site file's when it lists them, else target_list's
  std::vector<std::string> target_topics = {"targets"}, epoch_topics = {"epoch"};
  // A site file that lists cameras decides them: its cameras with targets
  // (kind fixed or uav) are `cameras`, target_topics (/<camera>/targets) and
  // epoch_topics (/<camera>/camera/epoch), in the site's order; those three
  // parameters are then not read. Without one, graph_cameras (set by
  // launch/include/processing_graph.xml) does the same with the graph's
  // default cameras (io::DefaultCameras()).
  bool graph_cameras = false;
  bool cameras_from_site = false;  // the site's cameras or, with graph_cameras, the default ones
  std::vector<std::string>
      prior_topics;  // site: /<uav>/camera/position_prior each; else position_prior
  std::vector<std::string> tie_topics;  // site: /<uav>/tie_points each; else tie_points
  // Where camera `name`'s CameraInfo comes from: site: /<name>/camera/camera_info;
  // else <name>/camera_info (relative: remapped by the launch).
  std::string CameraInfoTopic(const std::string& name) const {
    return cameras_from_site ? "/" + name + "/camera/camera_info" : name + "/camera_info";
  }
  std::string frame_id = "site";
  bool enable_run_adjustment = true, enable_set_reference_epoch = true;
  bool uav_tie_points = false;  // the UAV cameras' photos wait for their tie points
  // io::SiteWithoutDetectableTargets: no target list, or points picked in
  // the photos only; the UAV photos are tied by their tie points.
  bool site_without_targets = false;
  // Interior parameters (camera::InteriorNames) free for the UAV cameras in
  // every flight; empty: free_interior's (and the UAV start's c, k1, k2)
  std::vector<std::string> uav_free_interior;
  double pixel_size = 1.0;                             // [mm/px]
  std::map<std::string, double> pixel_size_by_camera;  // [mm/px] from the site file
  double PixelSizeOf(const std::string& camera) const {
    const auto it = pixel_size_by_camera.find(camera);
    return it == pixel_size_by_camera.end() ? pixel_size : it->second;
  }
  adjustment::EpochCollectorOptions collector;
  adjustment::BuildSceneOptions scene;
  adjustment::EpochAdjustmentOptions epoch = MonitoringEpochOptions();
  adjustment::DisplacementOptions displacement;
  FrustumOptions frustums;  // the `frustums` markers (rviz)
};
AdjusterParameters ReadAdjusterParameters(ParamReader& p);

struct RadioParameters {
  // False when no radio network is configured anywhere (network_file,
  // truth_file and the site file's radio_network all empty): radio is
  // optional, the solver stays idle.
  bool has_network = false;
  radio::NetworkConfig network;
  radio::RadioSolverOptions options;
  double stamp_tolerance = 1e-3, max_wait = 2.5;  // [s] radio::EpochAssembler
  std::string frame_id = "site";
  // Where the network comes from: the site file's radio_network, else exactly
  // one of network_file and truth_file (the simulator's truth, its
  // transmitters started at truth_initial_sigma; the truth does not hold the
  // sample rate).
  std::string site_file, network_file, truth_file;
  // The site's history: the reference solution and tracking state are kept
  // there (SavedStates "radio/<run>"), a run goes on from the state saved
  // before its first block; "" = a run solves its own reference.
  std::string database;
  double truth_initial_sigma = 0.005;  // [m]
  double truth_sample_rate = 20000.0;  // [Hz]
};
RadioParameters ReadRadioParameters(ParamReader& p);

// The monitoring graph's estimator, where it differs from the library's
// deformation::EstimatorOptions: a white-jerk density of 1e-25 m^2/s^5
// (~ (700 mm/day^2)^2 per day; the library's 2e-29 suits slow creep).
// Measured on the rostest slide near failure (config/defaults/
// deformation_estimator.yaml): 2e-29 lagged 4-7 sigma, 1e-26 up to 3.0
// sigma, 1e-25 up to 2.3 sigma.
inline deformation::EstimatorOptions MonitoringEstimatorOptions() {
  deformation::EstimatorOptions o;
  o.filter.jerk_spectral_density = 1e-25;
  return o;
}

struct EstimatorParameters {
  deformation::EstimatorOptions options = MonitoringEstimatorOptions();
  std::vector<std::string> input_topics = {"displacements"};
  std::vector<std::string> area_topics;  // ChangeAreaArray (areas of surface change)
  std::string frame_id = "site", database, report_dir;
  // The site the history belongs to (the site file's name, else the
  // parameter site_name): a history of another site is refused. "" = not checked.
  std::string site_name;
  std::string recording;  // the input's name (bag files), kept with the reference epoch
  std::string velocity_unit =
      "mm/day";  // of the thresholds and forecast_min_velocity: mm/day or mm/h
  // As written in the file: "point_id: watch, warning, alarm" and
  // "measured_id = monitoring_point_id" (parsed into `options`).
  std::vector<std::string> point_thresholds, aliases;
  std::vector<double> geodetic_origin;  // [] or [lat_deg, lon_deg, height_m] (into report)
  std::string site_file;
  bool report_on_shutdown = true;
  bool enable_export_report = true, enable_set_reference_epoch = true;
  std::vector<std::string> report_formats;
  deformation::ReportOptions report;
  MarkerOptions markers;
  double report_interval = 0.0;  // [s] live: reports on a wall-clock timer; 0 = off
  // [s] wall: how long a batch waits for the other inputs to pass its stamp
  // (core/common/input_order.h) before it is fused without them; 0 = arrival order
  double order_timeout = 300.0;
  bool report_on_alert_change = false;
  deformation::PlotReportOptions plot;  // plot.script "" = the OpenCV pictures
  // The site file's contents when `site_file` is set (thresholds, aliases and
  // origin already applied to `options` and `report`; its notification is
  // for the caller to run).
  std::optional<io::SiteFile> site;
};
EstimatorParameters ReadEstimatorParameters(ParamReader& p);

}  // namespace ros_adapters
}  // namespace slope_monitor
