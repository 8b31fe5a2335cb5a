#include "slope_monitor/core/io/target_file.h"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/target_csv.h"

namespace slope_monitor {
namespace io {
namespace {

bool HasExtension(const std::string& path, const char* extension) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == extension;
}

bool IsCsvName(const std::string& path) { return HasExtension(path, ".csv"); }

}  // namespace

bool IsGcpListName(const std::string& path) { return HasExtension(path, ".txt"); }

TargetList LoadGcpTargets(const std::string& path, const SiteCrs& site,
                          const std::vector<std::string>& check, double sigma, double size) {
  GcpList gcp;
  try {
    gcp = ReadGcpList(path);
  } catch (const std::exception& e) {
    throw ConfigError(Message("gcp list: ", e.what()));
  }
  const std::map<std::string, int> ids = GcpTargetIds(gcp);
  for (const std::string& name : check)
    if (ids.count(name) == 0)
      throw ConfigError(Message(path, ": check point '", name, "' is not in the list"));
  const Eigen::Vector2d sigmas = GcpSigma(gcp, sigma);
  std::vector<SurveyedPoint> points;
  for (const GcpPoint& p : gcp.points) {
    SurveyedPoint s;
    s.family = kGcpFamily;
    s.id = ids.at(p.name);
    s.name = p.name;
    s.role = std::find(check.begin(), check.end(), p.name) != check.end() ? TargetRole::kCheck
                                                                          : TargetRole::kControl;
    try {
      s.position_in_site = SiteFromListCrs(site, gcp.crs, p.geo);
    } catch (const std::exception& e) {
      throw ConfigError(Message(path, ":", p.line, ": point '", p.name, "': ", e.what()));
    }
    s.sigma = sigmas;
    points.push_back(s);
  }
  TargetList list;
  ApplySurveyedPoints(points, size, &list);
  return list;
}

TargetList LoadTargetFile(const std::string& path, const SiteCrs* site, double size) {
  if (IsGcpListName(path)) {
    if (!site)
      throw ConfigError(Message("gcp list '", path,
                                "': no site file gives the site frame to turn its coordinates "
                                "into: give the site file (process_bag --site, the launch's "
                                "site:=)"));
    return LoadGcpTargets(path, *site, {}, kDefaultGcpSigma, size);
  }
  if (!IsCsvName(path)) return TargetList::Load(path);
  std::ifstream in(path);
  if (!in) throw ConfigError(Message("cannot open target list '", path, "'"));
  std::stringstream text;
  text << in.rdbuf();
  TargetList list;
  if (site) {
    ApplySurveyedPoints(ParseTargetCsv(text.str(), path, *site), size, &list);
    return list;
  }
  // No site: only a list in the site frame itself can be placed. Any origin
  // serves for it (SiteFromListCrs does not use it for crs site).
  std::istringstream lines(text.str());
  std::string first;
  std::getline(lines >> std::ws, first);
  const size_t colon = first.find(':');
  std::string crs = colon == std::string::npos ? "" : first.substr(colon + 1);
  crs.erase(0, crs.find_first_not_of(" \t"));
  crs.erase(crs.find_last_not_of(" \t\r") + 1);
  if (first.rfind("# crs:", 0) == 0 && crs != "site")
    throw ConfigError(Message("target list '", path, "': its coordinates are in '", crs,
                              "', and no site file gives the site frame (its crs and origin) to "
                              "turn them into: give the site file (process_bag --site, the "
                              "launch's site:=), or a list in '# crs: site'"));
  const SiteCrs any = SiteCrs::LocalEnuAtWgs84(0.0, 0.0, 0.0);
  ApplySurveyedPoints(ParseTargetCsv(text.str(), path, any), size, &list);
  return list;
}

TargetList LoadTargetFileInSite(const std::string& path, const SiteCrsOptions* site_crs,
                                double size) {
  if (!site_crs || !(IsCsvName(path) || IsGcpListName(path)))
    return LoadTargetFile(path, nullptr, size);
  const SiteCrs site(*site_crs);
  return LoadTargetFile(path, &site, size);
}

}  // namespace io
}  // namespace slope_monitor
