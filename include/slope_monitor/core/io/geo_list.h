// Photo positions from a flight log or a receiver, in OpenDroneMap's geo.txt
// format (the positions a crew has when the photos' EXIF has none, or better
// ones than it):
//
//   <CRS: a PROJ string, "EPSG:NNNN" or "WGS84 UTM 11N">
//   image_name geo_x geo_y geo_z [yaw pitch roll [horizontal_sigma vertical_sigma [extra ...]]]
//
// one photo per line, separated by blanks or tabs; '#' starts a comment.
// Angles and accuracies are read past, not used.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace io {

struct GeoEntry {
  std::string image;                              // file name as written (no folder)
  Eigen::Vector3d geo = Eigen::Vector3d::Zero();  // in the file's CRS
  int line = 0;                                   // 1-based
};

struct GeoList {
  std::string path;
  std::string crs;  // first line, normalised as the gcp list's (NormaliseGcpCrs)
  std::vector<GeoEntry> entries;
};

// Throws IoError naming the file (missing, unreadable, no CRS line) and
// InvalidArgument naming "file:line" and what is wrong: fewer than 4 fields,
// a coordinate that is not a finite number, a photo listed twice.
GeoList ReadGeoList(const std::string& path);

}  // namespace io
}  // namespace slope_monitor
