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

struct AdjusterParameters {
  std::string target_list_path;  // or "<site file> (inline targets)"
  io::TargetList targets;        // the site file's when it lists them, else target_list's
  std::vector<std::string> target_topics, epoch_topics;
  // A site file that lists cameras decides them: its cameras with targets
  // (kind fixed or uav) are `cameras`, target_topics (/<camera>/targets) and
  // epoch_topics (/<camera>/camera/epoch), in the site's order; those three
  // parameters are then not read.
  bool cameras_from_site = false;
  std::vector<std::string> prior_topics;  // site: /<uav>/camera/position_prior each; else position_prior
  std::vector<std::string> tie_topics;    // site: /<uav>/tie_points each; else tie_points
  // Where camera `name`'s CameraInfo comes from: site: /<name>/camera/camera_info;
  // else <name>/camera_info (relative: remapped by the launch).
  std::string CameraInfoTopic(const std::string& name) const {
    return cameras_from_site ? "/" + name + "/camera/camera_info" : name + "/camera_info";
  }
  std::string frame_id;
  bool enable_run_adjustment = true, enable_set_reference_epoch = true;
  double pixel_size = 1.0;                            // [mm/px]
  std::map<std::string, double> pixel_size_by_camera;  // [mm/px] from the site file
  double PixelSizeOf(const std::string& camera) const {
    const auto it = pixel_size_by_camera.find(camera);
    return it == pixel_size_by_camera.end() ? pixel_size : it->second;
  }
  adjustment::EpochCollectorOptions collector;
  adjustment::BuildSceneOptions scene;
  adjustment::EpochAdjustmentOptions epoch;
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
  double stamp_tolerance = 0.0, max_wait = 0.0;  // [s] radio::EpochAssembler
  std::string frame_id;
};
RadioParameters ReadRadioParameters(ParamReader& p);

struct EstimatorParameters {
  deformation::EstimatorOptions options;
  std::vector<std::string> input_topics;
  std::vector<std::string> area_topics;  // ChangeAreaArray (areas of surface change)
  std::string frame_id, database, report_dir;
  bool report_on_shutdown = true;
  bool enable_export_report = true, enable_set_reference_epoch = true;
  std::vector<std::string> report_formats;
  deformation::ReportOptions report;
  MarkerOptions markers;
  double report_interval = 0.0;  // [s] live: reports on a wall-clock timer; 0 = off
  // [s] wall: how long a batch waits for the other inputs to pass its stamp
  // (core/common/input_order.h) before it is fused without them; 0 = arrival order
  double order_timeout = 0.0;  // (default: ReadEstimatorParameters)
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
