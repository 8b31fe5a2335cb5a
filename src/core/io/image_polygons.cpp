#include "slope_monitor/core/io/image_polygons.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {

std::vector<std::vector<Eigen::Vector2d>> ReadImagePolygons(const std::string& path,
                                                            const std::string& what) {
  std::ifstream in(path);
  if (!in) throw IoError(Message(what, ": cannot read '", path, "'"));
  std::vector<std::vector<Eigen::Vector2d>> polygons;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t c = line.find('#');
    if (c != std::string::npos) line.resize(c);
    std::istringstream s(line);
    std::vector<double> v;
    for (std::string t; s >> t;) {
      char* end = nullptr;
      const double x = std::strtod(t.c_str(), &end);
      if (*end != '\0' || !std::isfinite(x))
        throw InvalidArgument(Message(path, ":", number, ": malformed number '", t, "'"));
      v.push_back(x);
    }
    if (v.empty()) continue;
    if (v.size() % 2 != 0 || v.size() < 6)
      throw InvalidArgument(Message(path, ":", number, ": a polygon needs >= 3 `u v` pairs, got ",
                                    v.size(), " numbers"));
    std::vector<Eigen::Vector2d> p;
    for (size_t k = 0; k < v.size(); k += 2) p.emplace_back(v[k], v[k + 1]);
    polygons.push_back(p);
  }
  if (polygons.empty()) throw InvalidArgument(Message(what, " '", path, "': no polygon"));
  return polygons;
}

bool InsidePolygon(const std::vector<Eigen::Vector2d>& polygon, const Eigen::Vector2d& p) {
  bool in = false;
  for (size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

bool InsideAny(const std::vector<std::vector<Eigen::Vector2d>>& polygons,
               const Eigen::Vector2d& p) {
  for (const auto& polygon : polygons)
    if (InsidePolygon(polygon, p)) return true;
  return false;
}

}  // namespace io
}  // namespace slope_monitor
