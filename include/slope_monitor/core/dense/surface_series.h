// The surfaces of a survey, epoch after epoch, with no ROS in it: the first
// epoch measured is the reference; its grid is the grid of every later epoch,
// whose DoD against it (dense/dem_change.h) is computed. With a report
// directory, surface_eNN.tif and change_eNN.tif are written there, in the
// site's map CRS when a site CRS is given (io::MapRasterFromSite: its EPSG
// code; a local_enu site's rasters resampled onto a north-up UTM grid), else
// in the local CRS `site`; the DoD itself is computed in `site`. The
// dense_epoch nodelet, process_bag and `dense_surface --bag` use it.
//
// A failing step is named in SeriesEpoch::errors and the epoch's other
// outputs are kept: a DoD that fails still leaves the surface and its file.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"

namespace slope_monitor {
namespace dense {

struct SurfaceSeriesOptions {
  EpochSurfaceOptions surface;
  DemChangeOptions change;
  std::vector<Polygon> outlines;  // monitored outline(s), site
  std::string stable_mask;        // GeoTIFF on the DEM grid, non-zero = stable; "" = none
  std::string report_dir;         // "" = no files
  // The site's CRS: the files' map CRS (none: the local CRS `site`).
  std::optional<SiteCrsOptions> site_crs;
};

struct SeriesEpoch {
  int epoch = 0;
  std::optional<EpochSurfaceResult> surface;  // none: the surface failed (errors)
  std::optional<DemChangeResult> change;      // none: reference epoch, or the DoD failed
  std::vector<std::string> files;             // written
  std::vector<std::string> errors;            // "epoch 3 surface: ..."
};

class SurfaceSeries {
 public:
  explicit SurfaceSeries(const SurfaceSeriesOptions& options);  // ConfigError
  // Measures one epoch (slow: seconds). `progress` gets each step.
  SeriesEpoch Measure(const EpochSurfaceInput& input,
                      const std::function<void(const std::string&)>& progress = {});
  const io::GeoRaster* reference() const { return reference_.get(); }

 private:
  std::string ReportPath(const std::string& name) const;
  SurfaceSeriesOptions options_;
  std::unique_ptr<io::GeoRaster> reference_;
  std::unique_ptr<SiteCrs> site_;  // from options_.site_crs
};

}  // namespace dense
}  // namespace slope_monitor
