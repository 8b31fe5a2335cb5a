// A stable-area polygons file in image pixels (track_camera
// --stable-polygons, a fixed_targetless camera's `stable_polygons`): one
// polygon per line, its vertices as `u v` pairs (OpenCV convention),
// `u1 v1 u2 v2 u3 v3 ...`; `#` starts a comment.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace io {

// Throws IoError (unreadable) or InvalidArgument naming `what`, the file and
// the line (malformed number, odd count, fewer than 3 vertices, no polygon).
std::vector<std::vector<Eigen::Vector2d>> ReadImagePolygons(const std::string& path,
                                                            const std::string& what);

// Even-odd rule: p inside the polygon (any units; pixels here, metres for the
// site's ground polygons).
bool InsidePolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p);
// Inside any of them.
bool InsideAny(const std::vector<std::vector<Eigen::Vector2d>>& polygons, const Eigen::Vector2d& p);

}  // namespace io
}  // namespace slope_monitor
