// The report pictures drawn by matplotlib: scripts/plot_report run on the
// history file (SQLite) writes deformation_series.png (every point's |d| and
// speed on one shared time axis, markers at the measurements, 1-sigma bands,
// thresholds labelled), deformation_inverse_velocity.png (1/v, the fitted
// line, the forecast failure time with its band) and deformation_map.png
// (arrows with 95 % ellipses, over a DEM's hillshade when one is given, and
// the areas of significant surface change from the report's GeoPackage).
// WriteAllReports (below) calls it for the report format "png" when there is
// a history; without one the OpenCV pictures of report.h are drawn. The
// estimator nodelet and process_bag both write their reports through it.
//
//   PlotReportOptions o;
//   o.script = "/opt/ros/.../share/slope_monitor/scripts/plot_report";
//   std::vector<std::string> files = RunPlotReport(o, "slope.db", "reports", Thresholds());
#pragma once

#include <string>
#include <vector>

#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/report.h"

namespace slope_monitor {
namespace deformation {

struct PlotReportOptions {
  std::string script;      // path of scripts/plot_report (required)
  std::string dem;         // GeoTIFF DEM in site coordinates for the map's hillshade; "" = none
  std::string polygons;    // GeoPackage with layer change_polygons drawn on the map; "" = none
  std::string site;        // site name for the titles; "" = none
  double timeout = 120.0;  // [s] the script is killed after this (1..3600)
  // Throws InvalidArgument naming the value.
  void Check() const;
};

// Runs the script on `history` writing into `folder`; returns the files it
// wrote. Throws IoError naming the script and why it failed (its own message
// is on stderr, which the caller's process shares).
std::vector<std::string> RunPlotReport(const PlotReportOptions& options, const std::string& history,
                                       const std::string& folder, const Thresholds& thresholds);

// The newest surface_eNN.tif (largest NN) in `folder`, "" when none.
std::string LatestSurface(const std::string& folder);

// Every report of `formats` ("csv", "geojson", "geotiff", "gpkg", "png";
// empty: all) into root/subfolder, as report.h's WriteReports, except that
// "png" is drawn by RunPlotReport from `history` when `history` and
// plot.script are both set. The map's hillshade is plot.dem, or else the
// newest surface_eNN.tif in `root` (the dense step writes them there); the
// areas of surface change are drawn from the GeoPackage written in the same
// call. Returns the files written; throws what the writers throw.
std::vector<std::string> WriteAllReports(const Estimator& estimator, const std::string& history,
                                         const PlotReportOptions& plot, const std::string& root,
                                         const std::string& subfolder,
                                         std::vector<std::string> formats,
                                         const ReportOptions& options);

}  // namespace deformation
}  // namespace slope_monitor
