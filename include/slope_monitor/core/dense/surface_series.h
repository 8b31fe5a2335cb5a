// The surfaces of a survey, epoch after epoch, with no ROS in it: the first
// epoch measured is the reference; its grid is the grid of every later epoch,
// whose change against it is computed by dense::CompareSurfaces
// (surface_products.h: a whole-cell shift search and the Nuth-Kaab
// co-registration on stable ground, the DoD with its LoD, volumes), the
// function process_flight calls for a real flight. With a report directory,
// per epoch (what process_flight writes per flight):
//
//   surface_eNN.tif         the DEM (bands height, uncertainty, count, spread)
//   ortho_eNN.tif           the RGB orthophoto of the epoch's UAV photos on it
//                           (surface_products.h; 4 x 4 cells per DEM cell; none
//                           without a UAV photo; grey photos give grey)
//   cloud_eNN.ply           the dense cloud (binary PLY, site frame, sigma_z, RGB)
//   change_eNN.tif          later epochs: bands change, lod, class
//   surface_report_eNN.json / .md  the surface's figures and, for later epochs,
//                           the co-registration (shift and vertical with sigma,
//                           stable median dz, NMAD, share flagged) and the
//                           volumes of significant gain and loss with sigma
//
// The GeoTIFFs are in the site's map CRS when a site CRS is given
// (io::MapRasterFromSite: its EPSG code; a local_enu site's rasters resampled
// onto a north-up UTM grid), else in the local CRS `site`; the DoD itself is
// computed in `site`. The dense_epoch nodelet, process_bag and
// `dense_surface --bag` use it.
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
#include "slope_monitor/core/dense/surface_products.h"

namespace slope_monitor {
namespace dense {

struct SurfaceSeriesOptions {
  EpochSurfaceOptions surface;
  SurfaceChangeOptions change;
  int ortho_subdivision =
      4;  // [-] orthophoto cells per DEM cell side (as process_flight's); [1, 16]
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
  std::optional<SurfaceChangeSummary>
      change_summary;               // with `change`: co-registration, stable figures
  std::vector<std::string> files;   // written
  std::vector<std::string> errors;  // "epoch 3 surface: ..."
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
  // surface_eNN.tif, ortho_eNN.tif, cloud_eNN.ply (a failing one is named in out->errors).
  void WriteProducts(const EpochSurfaceInput& input, SeriesEpoch* out) const;
  SurfaceSeriesOptions options_;
  std::unique_ptr<io::GeoRaster> reference_;
  int reference_epoch_ = -1;
  std::unique_ptr<SiteCrs> site_;  // from options_.site_crs
};

}  // namespace dense
}  // namespace slope_monitor
