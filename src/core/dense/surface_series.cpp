#include "slope_monitor/core/dense/surface_series.h"

#include <cstdio>
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
  RequireOption(
      "surface series", options_.ortho_subdivision >= 1 && options_.ortho_subdivision <= 16,
      "ortho_subdivision", Message("= ", options_.ortho_subdivision, " must be in [1, 16]"));
  if (options_.site_crs) site_ = std::make_unique<SiteCrs>(*options_.site_crs);
}

std::string SurfaceSeries::ReportPath(const std::string& name) const {
  std::filesystem::create_directories(options_.report_dir);
  return (std::filesystem::path(options_.report_dir) / name).string();
}

void SurfaceSeries::WriteProducts(const EpochSurfaceInput& input, SeriesEpoch* out) const {
  const EpochSurfaceResult& s = *out->surface;
  const int k = input.epoch;
  auto attempt = [&](const char* what, const std::function<std::string()>& write) {
    try {
      const std::string path = write();
      if (!path.empty()) out->files.push_back(path);
    } catch (const std::exception& e) {
      out->errors.push_back(Message("epoch ", k, " ", what, ": ", e.what()));
    }
  };
  attempt("surface file", [&] {
    std::string path = ReportPath(EpochSurfaceFileName(k));
    io::WriteGeoTiff(path, io::MapRasterFromSite(s.dem, site_.get()));
    return path;
  });
  attempt("orthophoto", [&] {
    std::vector<OrientedImage> uav;
    for (const EpochImage& im : input.images)
      if (im.kind == ImageKind::kUav && im.image.oriented && !im.image.image.empty())
        uav.push_back(im.image);
    if (uav.empty()) return std::string();  // fixed stereo pairs only: no orthophoto
    std::string path = ReportPath(EpochOrthoFileName(k));
    io::WriteGeoTiff(path,
                     io::MapRasterFromSite(ColourOrthophoto(s.dem, uav, options_.ortho_subdivision),
                                           site_.get()));
    return path;
  });
  attempt("cloud file", [&] {
    std::string path = ReportPath(EpochCloudFileName(k));
    WriteCloudPly(s.points, path);
    return path;
  });
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
  const bool files = !options_.report_dir.empty();
  if (files) WriteProducts(input, &out);
  if (!reference_) {
    reference_ = std::make_unique<io::GeoRaster>(out.surface->dem);
    reference_epoch_ = input.epoch;
  } else {
    try {
      SurfaceChangeInput in;
      in.reference = reference_.get();
      in.after = &out.surface->dem;
      in.moving = options_.outlines;
      in.stable_name = options_.stable_mask.empty()
                           ? std::string("the ground outside monitored_outline")
                           : options_.stable_mask;
      if (!options_.stable_mask.empty()) {
        const io::GeoRaster m = io::ReadGeoTiff(options_.stable_mask);
        for (float v : m.bands.at(0)) in.stable_mask.push_back(!m.IsNoData(v) && v != 0.0f);
      }
      CoregisteredChange c = CompareSurfaces(in, options_.change);
      out.change = std::move(c.result);
      out.change_summary = c.summary;
      if (files) {
        const std::string path = ReportPath(EpochChangeFileName(input.epoch));
        io::WriteGeoTiff(path, io::MapRasterFromSite(out.change->change, site_.get()));
        out.files.push_back(path);
      }
    } catch (const std::exception& e) {
      out.errors.push_back(
          Message("epoch ", input.epoch, " change (the surface is kept): ", e.what()));
      out.change.reset();
      out.change_summary.reset();
    }
  }
  if (files) {
    try {
      const std::string json = ReportPath(EpochFileName("surface_report", input.epoch, "json"));
      WriteEpochSurfaceReport(out.surface->summary,
                              out.change_summary ? &*out.change_summary : nullptr,
                              EpochSurfaceFileName(reference_epoch_), json,
                              ReportPath(EpochFileName("surface_report", input.epoch, "md")));
      out.files.push_back(json);
    } catch (const std::exception& e) {
      out.errors.push_back(Message("epoch ", input.epoch, " surface report: ", e.what()));
    }
  }
  return out;
}

}  // namespace dense
}  // namespace slope_monitor
