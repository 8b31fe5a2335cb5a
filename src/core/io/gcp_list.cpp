#include "slope_monitor/core/io/gcp_list.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

std::string GcpTrim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  const size_t b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

double GcpNumber(const std::string& text, const std::string& where, const char* field) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(v))
    throw InvalidArgument(Message(where, ": ", field, " '", text, "' is not a number"));
  return v;
}

}  // namespace

std::string WgsUtmEpsg(int zone, bool south) {
  return Message("EPSG:", (south ? 32700 : 32600) + zone);
}

std::string NormaliseGcpCrs(const std::string& crs) {
  std::istringstream in(crs);
  std::string datum, utm, zone;
  if (in >> datum >> utm >> zone && (datum == "WGS84" || datum == "WGS 84") && utm == "UTM" &&
      zone.size() >= 2) {
    const char hemi = zone.back();
    const int z = std::atoi(zone.substr(0, zone.size() - 1).c_str());
    if (z >= 1 && z <= 60 && (hemi == 'N' || hemi == 'S' || hemi == 'n' || hemi == 's'))
      return WgsUtmEpsg(z, hemi == 'S' || hemi == 's');
  }
  // A PROJ string of UTM on WGS 84 is that EPSG code (GIS tools want one);
  // any other PROJ string is made a CRS definition.
  if (crs.rfind("+proj=", 0) == 0) {
    std::istringstream words(crs);
    std::map<std::string, std::string> kv;
    for (std::string w; words >> w;) {
      const size_t eq = w.find('=');
      kv[w.substr(0, eq)] = eq == std::string::npos ? "" : w.substr(eq + 1);
    }
    const bool wgs84 =
        kv["+datum"] == "WGS84" || (kv.count("+datum") == 0 && kv["+ellps"] == "WGS84");
    const int zone = std::atoi(kv["+zone"].c_str());
    const bool plain = (kv.count("+units") == 0 || kv["+units"] == "m") &&
                       kv.count("+towgs84") == 0 && kv.count("+x_0") == 0 && kv.count("+k") == 0 &&
                       kv.count("+k_0") == 0;
    if (kv["+proj"] == "utm" && wgs84 && zone >= 1 && zone <= 60 && plain)
      return WgsUtmEpsg(zone, kv.count("+south") > 0);
    if (kv.count("+type") == 0) return crs + " +type=crs";
  }
  return crs;
}

GcpList ReadGcpList(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(Message(path, ": cannot be opened (no such file, or not readable)"));
  GcpList list;
  list.path = path;
  std::map<std::string, size_t> by_key;
  std::string raw;
  int line_no = 0;
  bool have_crs = false;
  while (std::getline(in, raw)) {
    ++line_no;
    const std::string line = GcpTrim(raw.substr(0, raw.find('#')));
    if (line.empty()) continue;
    const std::string where = Message(path, ":", line_no);
    if (!have_crs) {
      list.crs = NormaliseGcpCrs(line);
      have_crs = true;
      continue;
    }
    std::istringstream fields(line);
    std::vector<std::string> f;
    for (std::string s; fields >> s;) f.push_back(s);
    if (f.size() < 6)
      throw InvalidArgument(Message(
          where, ": ", f.size(),
          " fields where 'geo_x geo_y geo_z im_x im_y image_name [gcp_name]' needs 6 or 7"));
    const Eigen::Vector3d geo(GcpNumber(f[0], where, "geo_x"), GcpNumber(f[1], where, "geo_y"),
                              GcpNumber(f[2], where, "geo_z"));
    GcpPick pick;
    pick.pixel = Eigen::Vector2d(GcpNumber(f[3], where, "im_x"), GcpNumber(f[4], where, "im_y"));
    pick.image = f[5];
    pick.line = line_no;
    const std::string name = f.size() >= 7 ? f[6] : "";
    const std::string key = name.empty() ? Message("@", f[0], " ", f[1], " ", f[2]) : name;
    auto it = by_key.find(key);
    if (it == by_key.end()) {
      GcpPoint p;
      p.name = name.empty() ? Message("line", line_no) : name;
      p.geo = geo;
      p.line = line_no;
      it = by_key.emplace(key, list.points.size()).first;
      list.points.push_back(p);
    }
    GcpPoint& p = list.points[it->second];
    if ((p.geo - geo).norm() > 1e-6 * std::max(1.0, geo.norm()))
      throw InvalidArgument(
          Message(where, ": point '", p.name, "' has other coordinates than on line ", p.line));
    for (const GcpPick& q : p.picks)
      if (q.image == pick.image)
        throw InvalidArgument(Message(where, ": point '", p.name, "' is picked in '", pick.image,
                                      "' again (first on line ", q.line, ")"));
    p.picks.push_back(pick);
  }
  if (!have_crs) throw IoError(Message(path, ": empty (the first line must name the CRS)"));
  if (list.points.empty()) throw IoError(Message(path, ": names a CRS but no picks"));
  return list;
}

bool HasHeights(const GcpList& list) {
  for (const GcpPoint& p : list.points)
    if (p.geo.z() != 0.0) return true;
  return false;
}

Eigen::Vector2d GcpSigma(const GcpList& list, double sigma) {
  return {sigma, HasHeights(list) ? 2.0 * sigma : kNoHeightSigma};
}

std::map<std::string, int> GcpTargetIds(const GcpList& list) {
  std::map<std::string, int> by_number, by_order;
  std::set<int> numbers;
  for (const GcpPoint& p : list.points) {
    const int place = static_cast<int>(by_order.size());
    by_order[p.name] = place;
    const size_t digits = p.name.find_last_not_of("0123456789") + 1;  // npos + 1 == 0
    const std::string tail = p.name.substr(digits);
    if (tail.empty() || tail.size() > 9) continue;
    const int n = std::stoi(tail);
    if (numbers.insert(n).second) by_number[p.name] = n;
  }
  return by_number.size() == list.points.size() ? by_number : by_order;
}

}  // namespace io
}  // namespace slope_monitor
