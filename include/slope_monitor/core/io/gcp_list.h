// Control points picked in photos, in OpenDroneMap's gcp_list.txt format
// (also read by WebODM's GCP interface and written by its GCP editor):
//
//   <CRS: a PROJ string, "EPSG:NNNN" or "WGS84 UTM 11N">
//   geo_x geo_y geo_z im_x im_y image_name [gcp_name] [extra ...]
//
// one pick (one point seen in one photo) per line, separated by blanks or
// tabs; '#' starts a comment. Picks of one point share its name (or, without
// a name, its coordinates). Pixel coordinates are taken as OpenCV pixels
// (origin at the centre of the top-left pixel; ODM's half-pixel convention
// differs by 0.5 px, far below a pick's precision).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace io {

struct GcpPick {
  std::string image;                                // file name as written (no folder)
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  // [px]
  int line = 0;                                     // 1-based line of the file
};

struct GcpPoint {
  std::string name;                               // gcp_name, or "line<N>" when unnamed
  Eigen::Vector3d geo = Eigen::Vector3d::Zero();  // in the file's CRS
  std::vector<GcpPick> picks;
  int line = 0;  // its first line
};

struct GcpList {
  std::string path;
  std::string crs;  // as written on the first line, normalised: "WGS84 UTM 11N" -> "EPSG:32611"
  std::vector<GcpPoint> points;  // in order of first appearance
};

// Throws IoError naming the file (missing, unreadable, empty) and
// InvalidArgument naming "file:line" and what is wrong: too few fields, a
// number that is not one, a point named twice with other coordinates, the
// same point picked twice in one photo.
GcpList ReadGcpList(const std::string& path);

// What a gcp list leaves unsaid, one place for process_flight and a site
// file's targets (io::LoadGcpTargets):
constexpr double kDefaultGcpSigma = 0.05;  // [m] a control point, horizontal; vertical twice
constexpr double kNoHeightSigma = 10.0;    // [m] vertical, when the list has no heights
constexpr double kGcpPickSigmaPx = 2.0;    // [px] a point picked by hand in a photo
constexpr char kGcpFamily[] = "gcp";       // the target family of picked points (never detected)

// Whether a surveyed point's vertical variance [m^2] says its height is not
// known (a list without heights gives kNoHeightSigma^2).
inline bool HeightUnknown(double vertical_variance) {
  return vertical_variance >= 0.5 * kNoHeightSigma * kNoHeightSigma;
}

// false: every height of the list is 0 (a list without heights: handheld
// GNSS averages written as 2-D coordinates).
bool HasHeights(const GcpList& list);

// The survey sigma [m] (horizontal, vertical) of the list's points given
// `sigma` horizontal: vertical twice that, kNoHeightSigma without heights.
Eigen::Vector2d GcpSigma(const GcpList& list, double sigma);

// The target ID of each point (by name) in the family kGcpFamily: the
// number its name ends in when those tell every point apart ("gcp03" -> 3),
// else its place in the list (0, 1, ...).
std::map<std::string, int> GcpTargetIds(const GcpList& list);

// "EPSG:326NN" (north) / "EPSG:327NN" (south): WGS 84 / UTM zone NN, 1..60.
std::string WgsUtmEpsg(int zone, bool south);

// "WGS84 UTM 11N" / "WGS84 UTM 33S" -> "EPSG:32611" / "EPSG:32733"; anything
// else is returned unchanged (PROJ strings and EPSG codes).
std::string NormaliseGcpCrs(const std::string& crs);

}  // namespace io
}  // namespace slope_monitor
