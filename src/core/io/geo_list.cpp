#include "slope_monitor/core/io/geo_list.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace io {

GeoList ReadGeoList(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(Message(path, ": cannot open the geo list"));
  GeoList list;
  list.path = path;
  std::set<std::string> seen;
  int n = 0;
  for (std::string line; std::getline(in, line);) {
    ++n;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::stringstream ss(line);
    std::vector<std::string> f;
    for (std::string w; ss >> w;) f.push_back(w);
    if (f.empty()) continue;
    if (list.crs.empty()) {
      const size_t a = line.find_first_not_of(" \t\r"), b = line.find_last_not_of(" \t\r");
      list.crs = NormaliseGcpCrs(line.substr(a, b - a + 1));
      continue;
    }
    if (f.size() < 4)
      throw InvalidArgument(
          Message(path, ":", n, ": ", f.size(), " fields; need image_name geo_x geo_y geo_z"));
    GeoEntry e;
    e.image = f[0];
    e.line = n;
    for (int k = 0; k < 3; ++k) {
      char* end = nullptr;
      e.geo[k] = std::strtod(f[k + 1].c_str(), &end);
      if (*end || !std::isfinite(e.geo[k]))
        throw InvalidArgument(Message(path, ":", n, ": '", f[k + 1], "' is not a number"));
    }
    if (!seen.insert(e.image).second)
      throw InvalidArgument(Message(path, ":", n, ": photo '", e.image, "' is listed twice"));
    list.entries.push_back(e);
  }
  if (list.crs.empty()) throw IoError(Message(path, ": empty geo list (no CRS line)"));
  return list;
}

}  // namespace io
}  // namespace slope_monitor
