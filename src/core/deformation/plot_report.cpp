#include "slope_monitor/core/deformation/plot_report.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <regex>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/subprocess.h"
#include "slope_monitor/core/deformation/units.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace deformation {

void PlotReportOptions::Check() const {
  if (script.empty()) throw InvalidArgument("plot report: no script given");
  if (!(timeout >= 1.0 && timeout <= 3600.0))
    throw InvalidArgument(Message("plot report: timeout ", timeout, " s is outside 1..3600"));
}

std::vector<std::string> RunPlotReport(const PlotReportOptions& options, const std::string& history,
                                       const std::string& folder, const Thresholds& thresholds) {
  options.Check();
  char t[96];
  std::snprintf(t, sizeof(t), "%.6g,%.6g,%.6g", thresholds.watch * kMmPerDay,
                thresholds.warning * kMmPerDay, thresholds.alarm * kMmPerDay);
  std::vector<std::string> argv = {options.script, "--history",    history, "--out",
                                   folder,         "--thresholds", t};
  if (!options.dem.empty()) argv.insert(argv.end(), {"--dem", options.dem});
  if (!options.site.empty()) argv.insert(argv.end(), {"--site", options.site});
  if (!options.polygons.empty()) argv.insert(argv.end(), {"--polygons", options.polygons});
  const RunResult r = RunProgram(argv, "", options.timeout);
  if (!r.ok())
    throw IoError(Message("plot report '", options.script, "' on history '", history,
                          "' failed: ", r.failure));
  std::vector<std::string> files;
  std::istringstream lines(r.output);
  for (std::string line; std::getline(lines, line);)
    if (!line.empty()) files.push_back(line);
  return files;
}

std::string LatestSurface(const std::string& folder) {
  namespace fs = std::filesystem;
  const std::regex name("surface_e([0-9]+)\\.tif");
  std::string best;
  long best_epoch = -1;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    std::smatch m;
    const std::string file = it->path().filename().string();
    if (!std::regex_match(file, m, name)) continue;
    const long epoch = std::stol(m[1]);
    if (epoch > best_epoch) best_epoch = epoch, best = it->path().string();
  }
  return best;
}

std::vector<std::string> WriteAllReports(const Estimator& estimator, const std::string& history,
                                         const PlotReportOptions& plot, const std::string& root,
                                         const std::string& subfolder,
                                         std::vector<std::string> formats,
                                         const ReportOptions& options) {
  if (formats.empty()) formats = {"csv", "geojson", "geotiff", "gpkg", "png"};
  const auto png = std::find(formats.begin(), formats.end(), "png");
  const bool matplotlib = png != formats.end() && !history.empty() && !plot.script.empty();
  if (matplotlib) formats.erase(png);
  std::vector<std::string> files;
  if (!formats.empty()) files = WriteReports(estimator, root, subfolder, formats, options);
  if (matplotlib) {
    PlotReportOptions o = plot;
    // The map is drawn in the site frame (the history's coordinates), the
    // report GeoPackage and the dense step's surface_eNN.tif are in the map
    // CRS: the areas and the latest DEM go to the script in site-frame copies
    // (no georeference), removed after.
    namespace fs = std::filesystem;
    struct Remove {
      std::vector<fs::path> p;
      ~Remove() {
        std::error_code ec;
        for (const fs::path& f : p) fs::remove(f, ec);
      }
    } remove;
    const std::string stem = Message("slope_monitor_plot_", getpid(), "_", &estimator);
    if (o.dem.empty()) o.dem = LatestSurface(root);
    if (!o.dem.empty() && plot.dem.empty()) {
      // A DEM in a map CRS that is not the report's cannot be drawn (named on stderr).
      try {
        const io::GeoRaster dem = io::ReadGeoTiff(o.dem);
        if (dem.epsg != 0) {  // in a map CRS (a local-CRS DEM is in the site frame)
          const std::optional<SiteCrs> site = ReportSiteCrs(options);
          const fs::path copy = fs::temp_directory_path() / (stem + "_dem.tif");
          remove.p.push_back(copy);
          io::WriteGeoTiff(copy.string(), io::SiteRasterFromMap(dem, site ? &*site : nullptr));
          o.dem = copy.string();
        }
      } catch (const Error& e) {
        std::fprintf(stderr, "plot report: no hillshade: %s\n", e.what());
        o.dem.clear();
      }
    }
    const Snapshot s = estimator.GetSnapshot();
    if (!s.areas.empty()) {
      const fs::path site_frame = fs::temp_directory_path() / (stem + ".gpkg");
      remove.p.push_back(site_frame);
      o.polygons = WriteGeoPackage(s, site_frame.string(), ReportOptions());
    }
    const std::vector<std::string> pictures = RunPlotReport(
        o, history, io::ResolveSubfolder(root, subfolder), estimator.options().alerts.thresholds);
    files.insert(files.end(), pictures.begin(), pictures.end());
  }
  return files;
}

}  // namespace deformation
}  // namespace slope_monitor
