// One site file, config/sites/<name>.yaml: everything that is particular to
// a site, read by every node and tool that needs a part of it (doc/sites.md
// lists every key). Errors throw ConfigError naming the file and the key
// ("config/sites/demo.yaml: cameras[1].kind: ...").
//
//   name: demo                      # site name (used in reports and alerts)
//   crs: EPSG:4979                  # site CRS: "EPSG:NNNN" or a PROJ string (required)
//   origin: [8.0, 46.5, 1200.0]     # `site` origin in the CRS: x easting/lon, y northing/lat, z
//   (required) frame: local_enu                # local_enu | shifted_crs (local_enu;
//   common/site_crs.h) cameras:                        # any number, each {name, kind,
//   calibration_url, pixel_size}
//     - {name: north_ridge, kind: fixed, pixel_size: 0.0048}
//   radio_network: radio.yaml       # radio network file (radio::NetworkConfig); absent: no radio
//   targets: {file: targets.csv}    # a target list file (.yaml: io::TargetList, .csv:
//   target_csv.h), or targets: {crs: site, size: 1.0, list: [{id: tag36h11/3, role: control,
//   position: [x, y, z]}]} areas:                          # polygons, [x, y] vertices in `crs`
//   (default: the site CRS)
//     crs: site
//     outline: [[0, 0], [200, 0], [200, 150], [0, 150]]
//     stable: [[[0, 0], [40, 0], [40, 40], [0, 40]]]
//   thresholds: {unit: mm/day, watch: 2, warning: 10, alarm: 50,   # any subset
//                displacement_watch: 10, displacement_warning: 30,  # [mm] since the
//                displacement_alarm: 100,                           #   reference epoch
//                area_growth_watch: 25, area_growth_warning: 100}  # [m^2]
//   aliases: ["radio/tx1 = tag36h11/10"]                          # measured id = monitoring point
//   notification: {hook: /usr/local/bin/notify, timeout: 10, retries: 2, retry_delay: 30}
//
// Relative file names (radio_network, targets.file, notification.hook when
// it contains a '/') are resolved against the site file's folder. The camera
// kind is a field, never read from the camera's name.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace io {

enum class CameraKind { kFixed, kFixedTargetless, kUav };
// "fixed" | "fixed_targetless" | "uav"; throws ConfigError naming the value.
CameraKind CameraKindFromName(const std::string& name);
std::string CameraKindName(CameraKind kind);

struct SiteCamera {
  std::string name;  // namespace of its topics: /<name>/camera/image_raw ...
  CameraKind kind = CameraKind::kFixed;
  std::string calibration_url;  // camera_info_manager URL; "" = CameraInfo from the driver / bag
  double pixel_size = 0.0;      // [mm/px]; 0 = not given (CameraInfo does not carry it)
  // fixed_targetless only (absolute paths; doc/targetless_camera.md):
  std::string pose_file;  // reference photo's pose, resect_camera's PREFIX.pose.yaml (required)
  std::string dem;        // GeoTIFF in `site` the field is projected onto (required)
  std::string stable_polygons;  // stable area in pixels of the reference photo ("" = areas.stable)
};

// Alert thresholds given by the site; absent values keep the estimator's.
struct SiteThresholds {
  std::string unit = "mm/day";                  // mm/day | mm/h
  std::optional<double> watch, warning, alarm;  // [unit]
  // Cumulative displacement since the reference epoch [mm].
  std::optional<double> displacement_watch, displacement_warning, displacement_alarm;
  // Growth of an area of significant surface change [m^2] (change_areas.h).
  std::optional<double> area_growth_watch, area_growth_warning;
};

// The notification hook (deformation/alert_hook.h): an executable run with
// the alert as JSON on standard input at every alert-level change.
struct NotificationOptions {
  std::string hook;           // executable path; "" = no notification
  double timeout = 10.0;      // [s] the hook is killed after this (0.1..600)
  int retries = 2;            // further attempts after a failure (0..10)
  double retry_delay = 30.0;  // [s] wait before each retry (0..3600)
  // Throws InvalidArgument naming the value.
  void Check() const;
};

struct SiteFile {
  std::string path;  // the file read
  std::string name;
  SiteCrsOptions crs;
  std::vector<SiteCamera> cameras;
  std::string radio_network;             // absolute path or "" (no radio)
  std::optional<TargetList> targets;     // absent: the launch's target_list supplies it
  std::string targets_file;              // the file the targets came from ("" inline / absent)
  std::vector<Eigen::Vector2d> outline;  // [m] site x, y; empty = not given
  std::vector<std::vector<Eigen::Vector2d>> stable_areas;  // [m] site x, y
  SiteThresholds thresholds;
  std::vector<std::string> aliases;  // "measured_id = monitoring_point_id"
  NotificationOptions notification;

  const SiteCamera* FindCamera(const std::string& name) const;
  // The cameras of kind fixed or uav, in the file's order: those whose photos
  // are centroided and adjusted (not the fixed_targetless ones).
  std::vector<const SiteCamera*> CamerasWithTargets() const;
};

// The graph's cameras when no site file lists them (replay.launch without
// `site` on a simulator bag; the graph_cameras parameter of the centroider
// and the adjuster, process_bag's kinds): the simulator's names
// (config/sim/*.yaml), fixed_cam_1 and fixed_cam_2 (kind fixed) and uav
// (kind uav). The one place this default is written (dense_epoch.yaml's
// `cameras` mirrors it: test/ros/config_files_test.cpp); no name is special
// once a site file lists cameras.
std::vector<SiteCamera> DefaultCameras();
// The names of the cameras of `kind`, in their order.
std::vector<std::string> CameraNames(const std::vector<SiteCamera>& cameras, CameraKind kind);

// Whether a run on this site has no targets at all, as process_bag and the
// graph's nodes decide it alike: the site file lists none and `target_list`
// (the list given, or the one a replay looks for beside the bag) is "" or
// not a file. Such a site is normal (a UAV flight oriented by its tie points
// and GNSS): no target stage, its UAV cameras tied by their tie points.
bool SiteWithoutTargets(const SiteFile& site, const std::string& target_list);

// SiteWithoutTargets, or a site whose targets are only points picked in the
// photos (a gcp list, family "gcp"): nothing for a target stage to find, and
// the UAV photos are tied by their tie points (the picks come from
// camera_capture).
bool SiteWithoutDetectableTargets(const SiteFile& site, const std::string& target_list);

// Reads and checks a site file (every key validated, unknown keys refused,
// the CRS checked by PROJ).
SiteFile LoadSiteFile(const std::string& path);
SiteFile ParseSiteFile(const std::string& text, const std::string& context,
                       const std::string& folder);

}  // namespace io
}  // namespace slope_monitor
