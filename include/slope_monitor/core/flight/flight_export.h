// What an oriented flight leaves for other tools, in DIR/flight_<k>/:
//
//   sparse/cameras.txt, images.txt, points3D.txt  COLMAP's text model (read by
//       COLMAP's model_analyzer and GUI, OpenMVS, pycolmap): one FULL_OPENCV
//       camera (the collinearity model with b1 = b2 = 0 is OpenCV's plumb_bob,
//       camera_model.h; COLMAP's pixel origin is the top-left corner, so
//       OpenCV pixels + 0.5), poses world-to-camera in the site frame;
//   points.ply       the 3-D tie points in the site frame (x, y, z, grey as
//                    red/green/blue, reprojection error, images seeing them);
//   crs.txt          the site frame: its CRS, its origin in that CRS and the
//                    CRS as WKT (site = CRS coordinates - origin);
//   cameras.csv      per photo: centre [site m], attitude [deg], their sigma
//                    from the adjustment's covariance, observations, rms [px];
//   report.json, report.md  the figures process_flight prints and more.
#pragma once

#include <string>

#include <Eigen/Core>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/flight/flight_matching.h"
#include "slope_monitor/core/flight/flight_orientation.h"

namespace slope_monitor {
namespace flight {

struct FlightFrame {
  std::string crs;  // "EPSG:32611", a PROJ string, or "" (model frame)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  // site origin in the CRS
  std::string wkt;                                   // the CRS as WKT ("" without one)
  // false: site = CRS coordinates - origin; true: east, north, up [m] on the
  // tangent plane at the origin (a site file's local_enu frame); wkt is then
  // that of map_crs, the CRS of the GIS outputs (SiteCrs::MapCrs).
  bool local_enu = false;
  std::string map_crs;
};

// The frame of a site file's CRS options (throws InvalidArgument when PROJ
// does not know the CRS, naming it).
FlightFrame FrameOfSite(const SiteCrsOptions& crs);

struct FlightReportInput {
  int flight = 1;  // k of flight_<k>
  std::string folder;
  const FlightPhotos* photos = nullptr;
  const FlightTies* ties = nullptr;
  const FlightResult* result = nullptr;
  FlightFrame frame;
  double total_seconds = 0.0;
  double peak_memory_gb = 0.0;
};

// Each throws IoError naming the file that cannot be written. Files are
// written to a temporary name and renamed.
// The block writers need of a FlightResult only scene (one camera),
// point_grey, point_error_px, observation_error_px and bundle.precision.
void WriteColmapModel(const FlightResult& block, const std::string& sparse_dir);
// Every pair tried: its photos, tie points, epipolar rms and why it is not
// used ("" when it is).
void WritePairsCsv(const FlightPhotos& photos, const FlightTies& ties, const std::string& path);
void WritePointsPly(const FlightResult& block, const std::string& path);
void WriteCamerasCsv(const FlightResult& block, const std::string& path);
void WriteFrame(const FlightFrame& frame, const std::string& path);
void WriteFlightReport(const FlightReportInput& in, const std::string& json_path,
                       const std::string& md_path);

// sparse/, points.ply, cameras.csv and crs.txt of an oriented block into
// dir (created): what the graph leaves of an accepted UAV epoch.
void WriteBlockOutputs(const FlightResult& block, const FlightFrame& frame, const std::string& dir);

// All of the above and the report into dir (created).
void WriteFlightOutputs(const FlightReportInput& in, const std::string& dir);

}  // namespace flight
}  // namespace slope_monitor
