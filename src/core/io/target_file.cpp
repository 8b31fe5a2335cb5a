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

bool IsCsvName(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".csv";
}

}  // namespace

TargetList LoadTargetFile(const std::string& path, const SiteCrs* site, double size) {
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
  if (!site_crs || !IsCsvName(path)) return LoadTargetFile(path, nullptr, size);
  const SiteCrs site(*site_crs);
  return LoadTargetFile(path, &site, size);
}

}  // namespace io
}  // namespace slope_monitor
