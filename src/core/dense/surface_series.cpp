#include "slope_monitor/core/dense/surface_series.h"

#include <exception>
#include <filesystem>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"

namespace slope_monitor {
namespace dense {

SurfaceSeries::SurfaceSeries(const SurfaceSeriesOptions& options) : options_(options) {
  options_.surface.Check();
  options_.change.Check();
  if (options_.site_crs) site_ = std::make_unique<SiteCrs>(*options_.site_crs);
}

std::string SurfaceSeries::ReportPath(const std::string& name) const {
  std::filesystem::create_directories(options_.report_dir);
  return (std::filesystem::path(options_.report_dir) / name).string();
}

SeriesEpoch SurfaceSeries::Measure(const EpochSurfaceInput& input,
                                   const std::function<void(const std::string&)>& progress) {
  SeriesEpoch out;
  out.epoch = input.epoch;
  try {
    EpochSurfaceOptions o = options_.surface;
    if (reference_) o.region = RegionOf(*reference_);
    out.surface = MeasureEpochSurface(input, o, progress);
  } catch (const std::exception& e) {
    out.errors.push_back(Message("epoch ", input.epoch, " surface: ", e.what()));
    return out;
  }
  if (!options_.report_dir.empty()) {
    try {
      const std::string path = ReportPath(EpochSurfaceFileName(input.epoch));
      io::WriteGeoTiff(path, io::MapRasterFromSite(out.surface->dem, site_.get()));
      out.files.push_back(path);
    } catch (const std::exception& e) {
      out.errors.push_back(Message("epoch ", input.epoch, " surface file: ", e.what()));
    }
  }
  if (!reference_) {
    reference_ = std::make_unique<io::GeoRaster>(out.surface->dem);
    return out;
  }
  try {
    std::vector<uint8_t> mask;
    if (!options_.stable_mask.empty()) {
      const io::GeoRaster m = io::ReadGeoTiff(options_.stable_mask);
      for (float v : m.bands.at(0)) mask.push_back(!m.IsNoData(v) && v != 0.0f);
    }
    const std::vector<uint8_t> stable =
        StableMask(*reference_, options_.outlines, mask, options_.stable_mask);
    out.change =
        DemChange(*reference_, out.surface->dem, options_.outlines, stable, options_.change);
    if (!options_.report_dir.empty()) {
      const std::string path = ReportPath(EpochChangeFileName(input.epoch));
      io::WriteGeoTiff(path, io::MapRasterFromSite(out.change->change, site_.get()));
      out.files.push_back(path);
    }
  } catch (const std::exception& e) {
    out.errors.push_back(
        Message("epoch ", input.epoch, " change (the surface is kept): ", e.what()));
    out.change.reset();
  }
  return out;
}

}  // namespace dense
}  // namespace slope_monitor
