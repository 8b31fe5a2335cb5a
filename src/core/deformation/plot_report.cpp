#include "slope_monitor/core/deformation/plot_report.h"

#include <cstdio>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/subprocess.h"

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
  constexpr double kMmPerDay = 86400e3;
  std::snprintf(t, sizeof(t), "%.6g,%.6g,%.6g", thresholds.watch * kMmPerDay,
                thresholds.warning * kMmPerDay, thresholds.alarm * kMmPerDay);
  std::vector<std::string> argv = {options.script, "--history",    history, "--out",
                                   folder,         "--thresholds", t};
  if (!options.dem.empty()) argv.insert(argv.end(), {"--dem", options.dem});
  if (!options.site.empty()) argv.insert(argv.end(), {"--site", options.site});
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

}  // namespace deformation
}  // namespace slope_monitor
