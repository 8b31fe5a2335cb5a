#include "slope_monitor/core/io/target_csv.h"

#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

constexpr char kColumns[] = "id,role,x,y,z,sigma_h,sigma_v";

std::string Trim(const std::string& s) {
  const size_t b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> fields;
  std::stringstream s(line);
  std::string f;
  while (std::getline(s, f, ',')) fields.push_back(Trim(f));
  if (!line.empty() && line.back() == ',') fields.push_back("");
  return fields;
}

bool IsWgs84(const std::string& crs) {
  return crs == "WGS 84" || crs == "EPSG:4326" || crs == "EPSG:4979";
}

// A CRS other than the site's, as a shifted frame with zero origin (its
// "site" coordinates are its own).
SiteCrs OtherCrs(const std::string& crs) {
  SiteCrsOptions o;
  o.crs = crs;
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  return SiteCrs(o);
}

double Number(const std::string& field, const std::string& where, const char* column) {
  size_t used = 0;
  double v = NAN;
  try {
    v = std::stod(field, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != field.size() || !std::isfinite(v)) {
    throw ConfigError(Message(where, ": column ", column, " '", field, "' is not a finite number"));
  }
  return v;
}

// Converts the list's coordinates to site; `other` is the list's CRS when it
// is neither site, WGS 84 nor the site CRS.
struct ListFrame {
  const SiteCrs& site;
  std::string crs;
  std::unique_ptr<SiteCrs> other;
  Eigen::Vector3d ToSite(const Eigen::Vector3d& x) const {
    return other ? site.SiteFromWgs84(other->Wgs84FromSite(x)) : SiteFromListCrs(site, crs, x);
  }
};

SurveyedPoint ParseRow(const std::vector<std::string>& f, const std::string& where,
                       const ListFrame& frame, const std::string& default_family) {
  if (f.size() != 7) {
    throw ConfigError(Message(where, ": ", f.size(), " columns, expected 7 (", kColumns, ")"));
  }
  SurveyedPoint p;
  const size_t slash = f[0].find('/');
  p.family = slash == std::string::npos ? default_family : f[0].substr(0, slash);
  const std::string number = slash == std::string::npos ? f[0] : f[0].substr(slash + 1);
  const double id = Number(number, where, "id");
  if (id < 0 || id != std::floor(id) || id > 1e9) {
    throw ConfigError(
        Message(where, ": id '", f[0], "' is not <family>/<number> or a number >= 0"));
  }
  p.id = static_cast<int>(id);
  try {
    p.role = TargetRoleFromName(f[1]);
  } catch (const ConfigError& e) {
    throw ConfigError(Message(where, ": column role: ", e.what()));
  }
  const Eigen::Vector3d x(Number(f[2], where, "x"), Number(f[3], where, "y"),
                          Number(f[4], where, "z"));
  p.sigma = Eigen::Vector2d(Number(f[5], where, "sigma_h"), Number(f[6], where, "sigma_v"));
  if (p.sigma.minCoeff() <= 0.0)
    throw ConfigError(Message(where, ": sigma_h and sigma_v must be > 0 [m]"));
  try {
    p.position_in_site = frame.ToSite(x);
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message(where, ": ", e.what()));
  }
  return p;
}

}  // namespace

Eigen::Vector3d SiteFromListCrs(const SiteCrs& site, const std::string& crs,
                                const Eigen::Vector3d& x) {
  if (crs == "site") return x;
  if (crs == site.options().crs) return site.SiteFromCrs(x);
  if (IsWgs84(crs)) return site.SiteFromWgs84(x);
  return site.SiteFromWgs84(OtherCrs(crs).Wgs84FromSite(x));
}

Eigen::Vector3d ListCrsFromSite(const SiteCrs& site, const std::string& crs,
                                const Eigen::Vector3d& x_in_site) {
  if (crs == "site") return x_in_site;
  if (crs == site.options().crs) return site.CrsFromSite(x_in_site);
  if (IsWgs84(crs)) return site.Wgs84FromSite(x_in_site);
  return OtherCrs(crs).SiteFromWgs84(site.Wgs84FromSite(x_in_site));
}

std::vector<SurveyedPoint> ParseTargetCsv(const std::string& text, const std::string& context,
                                          const SiteCrs& site, const std::string& default_family) {
  std::stringstream in(text);
  std::string line;
  std::getline(in, line);
  line = Trim(line);
  const std::string prefix = "# crs:";
  if (line.compare(0, prefix.size(), prefix) != 0 || Trim(line.substr(prefix.size())).empty()) {
    throw ConfigError(Message(context,
                              ":1: the first line must name the CRS, e.g. '# crs: EPSG:6677', "
                              "'# crs: WGS 84' or '# crs: site'; found '",
                              line, "'"));
  }
  ListFrame frame{site, Trim(line.substr(prefix.size())), nullptr};
  if (frame.crs != "site" && frame.crs != site.options().crs && !IsWgs84(frame.crs)) {
    try {
      frame.other = std::make_unique<SiteCrs>(OtherCrs(frame.crs));
    } catch (const InvalidArgument& e) {
      throw ConfigError(Message(context, ":1: crs '", frame.crs, "' of the list: ", e.what()));
    }
  }
  std::getline(in, line);
  if (Trim(line) != kColumns) {
    throw ConfigError(
        Message(context, ":2: the second line must be '", kColumns, "'; found '", Trim(line), "'"));
  }
  std::vector<SurveyedPoint> points;
  std::map<std::string, int> seen;
  for (int number = 3; std::getline(in, line); ++number) {
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    const std::string where = Message(context, ":", number);
    points.push_back(ParseRow(SplitCsv(t), where, frame, default_family));
    const std::string key = points.back().family + "/" + std::to_string(points.back().id);
    if (seen.count(key))
      throw ConfigError(Message(where, ": target ", key, " already on line ", seen[key]));
    seen[key] = number;
  }
  return points;
}

std::vector<SurveyedPoint> ReadTargetCsv(const std::string& path, const SiteCrs& site,
                                         const std::string& default_family) {
  std::ifstream in(path);
  if (!in) throw ConfigError(Message("cannot open target list '", path, "'"));
  std::stringstream s;
  s << in.rdbuf();
  return ParseTargetCsv(s.str(), path, site, default_family);
}

void ApplySurveyedPoints(const std::vector<SurveyedPoint>& points, double size, TargetList* list) {
  std::map<std::string, const SurveyedPoint*> by_key;
  for (const SurveyedPoint& p : points) by_key[p.family + "/" + std::to_string(p.id)] = &p;
  TargetList out;
  for (TargetSpec spec : list->targets()) {
    auto it = by_key.find(spec.Key());
    if (it != by_key.end()) {
      spec.role = it->second->role;
      spec.position = it->second->position_in_site;
      spec.sigma = it->second->sigma;
      if (!it->second->name.empty()) spec.name = it->second->name;
      by_key.erase(it);
    }
    out.Add(spec);
  }
  for (const SurveyedPoint& p : points) {
    const std::string key = p.family + "/" + std::to_string(p.id);
    if (!by_key.count(key)) continue;
    if (!(size > 0.0))
      throw InvalidArgument(
          Message("target ", key, " is new to the list and size ", size, " <= 0"));
    TargetSpec spec;
    spec.family = p.family;
    spec.id = p.id;
    spec.size = size;
    spec.role = p.role;
    spec.position = p.position_in_site;
    spec.sigma = p.sigma;
    spec.name = p.name;
    out.Add(spec);
  }
  *list = out;
}

}  // namespace io
}  // namespace slope_monitor
