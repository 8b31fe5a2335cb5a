#include "slope_monitor/core/io/map_raster.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/site_crs.h"

namespace slope_monitor {
namespace io {

const char* const kCategoricalBands[3] = {"count", "class", "significant"};

namespace {

bool IsCategorical(const std::string& name) {
  for (const char* c : kCategoricalBands)
    if (name == c) return true;
  return false;
}

// A band of `r` at (x, y) in its own coordinates: bilinear, else (a nodata
// neighbour, a categorical band) the containing cell; NaN outside.
float SampleBand(const GeoRaster& r, int band, bool categorical, double x, double y) {
  if (!categorical) {
    const double v = r.Interpolate(band, x, y);
    if (!std::isnan(v)) return static_cast<float>(v);
  }
  int row = 0, col = 0;
  if (!r.CellOf(x, y, &row, &col)) return std::numeric_limits<float>::quiet_NaN();
  const float v = r.At(band, row, col);
  return r.IsNoData(v) ? std::numeric_limits<float>::quiet_NaN() : v;
}

// An empty copy of the grid with `like`'s bands (all nodata NaN).
GeoRaster EmptyLike(const GeoRaster& bands_of, int width, int height, double x0, double y1,
                    double cell) {
  GeoRaster out(width, height, x0, y1, cell);
  out.rgb = bands_of.rgb;
  for (const std::string& name : bands_of.band_names) out.AddBand(name);
  return out;
}

}  // namespace

void SetMapCrs(GeoRaster* raster, const SiteCrs& site) {
  raster->epsg = site.MapEpsg();
  raster->srs_wkt = raster->epsg == 0 ? site.CrsWkt() : std::string();
}

GeoRaster MapRasterFromSite(const GeoRaster& in_site, const SiteCrs* site) {
  in_site.Check("MapRasterFromSite");
  if (!site) return in_site;
  const int height_band = in_site.BandIndex("height");
  const Eigen::Vector3d& o = site->options().origin;
  if (site->options().frame == SiteCrsOptions::Frame::kShiftedCrs) {
    GeoRaster out = in_site;
    out.origin_x += o.x();
    out.origin_y += o.y();
    if (height_band >= 0)
      for (float& z : out.bands[height_band])
        if (!out.IsNoData(z)) z = static_cast<float>(z + o.z());
    SetMapCrs(&out, *site);
    return out;
  }
  // The site raster's outline in the map (edges sampled every 16 cells: the
  // mapping is nearly affine, the grid keeps a cell of margin).
  const double cell = in_site.cell_size;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  const double x0 = in_site.origin_x, y1 = in_site.origin_y;
  const double x1 = x0 + in_site.width * cell, y0 = y1 - in_site.height * cell;
  const int n = 16 + std::max(in_site.width, in_site.height) / 16;
  for (int i = 0; i <= n; ++i) {
    const double t = static_cast<double>(i) / n;
    for (const Eigen::Vector2d& p :
         {Eigen::Vector2d(x0 + t * (x1 - x0), y0), Eigen::Vector2d(x0 + t * (x1 - x0), y1),
          Eigen::Vector2d(x0, y0 + t * (y1 - y0)), Eigen::Vector2d(x1, y0 + t * (y1 - y0))}) {
      const Eigen::Vector2d m = site->MapFromSite(Eigen::Vector3d(p.x(), p.y(), 0.0)).head<2>();
      lo = lo.cwiseMin(m);
      hi = hi.cwiseMax(m);
    }
  }
  const double mx0 = std::floor(lo.x() / cell) * cell, my1 = std::ceil(hi.y() / cell) * cell;
  const int width = static_cast<int>(std::ceil((hi.x() - mx0) / cell));
  const int height = static_cast<int>(std::ceil((my1 - lo.y()) / cell));
  GeoRaster out = EmptyLike(in_site, std::max(1, width), std::max(1, height), mx0, my1, cell);
  SetMapCrs(&out, *site);
  std::vector<bool> categorical;
  for (const std::string& name : in_site.band_names) categorical.push_back(IsCategorical(name));
  // Cell centres at the origin's height (map z of site z = 0).
  const double map_z = site->MapFromSite(Eigen::Vector3d::Zero()).z();
  for (int row = 0; row < out.height; ++row)
    for (int col = 0; col < out.width; ++col) {
      const Eigen::Vector2d m = out.CellCentre(row, col);
      const Eigen::Vector3d s = site->SiteFromMap(Eigen::Vector3d(m.x(), m.y(), map_z));
      int r = 0, c = 0;
      if (!in_site.CellOf(s.x(), s.y(), &r, &c)) continue;
      for (int b = 0; b < in_site.num_bands(); ++b)
        out.At(b, row, col) = SampleBand(in_site, b, categorical[b], s.x(), s.y());
      if (height_band >= 0 && !std::isnan(out.At(height_band, row, col)))
        out.At(height_band, row, col) = static_cast<float>(
            site->MapFromSite(Eigen::Vector3d(s.x(), s.y(), out.At(height_band, row, col))).z());
    }
  return out;
}

GeoRaster SiteRasterFromMap(const GeoRaster& in_map, const SiteCrs* site,
                            const GeoRaster& site_grid) {
  in_map.Check("SiteRasterFromMap");
  if (site && site->MapEpsg() != 0 && in_map.epsg != site->MapEpsg())
    throw InvalidArgument(Message("a raster in EPSG:", in_map.epsg,
                                  " is not in the site's map CRS ", site->MapCrs()));
  if (!site && in_map.epsg != 0)
    throw InvalidArgument(
        Message("a raster in EPSG:", in_map.epsg,
                " for a site without a georeference (local CRS 'site' expected)"));
  GeoRaster out = EmptyLike(in_map, site_grid.width, site_grid.height, site_grid.origin_x,
                            site_grid.origin_y, site_grid.cell_size);
  const int height_band = in_map.BandIndex("height");
  std::vector<bool> categorical;
  for (const std::string& name : in_map.band_names) categorical.push_back(IsCategorical(name));
  for (int row = 0; row < out.height; ++row)
    for (int col = 0; col < out.width; ++col) {
      const Eigen::Vector2d s = out.CellCentre(row, col);
      const Eigen::Vector2d m =
          site ? site->MapFromSite(Eigen::Vector3d(s.x(), s.y(), 0.0)).head<2>().eval() : s;
      for (int b = 0; b < in_map.num_bands(); ++b)
        out.At(b, row, col) = SampleBand(in_map, b, categorical[b], m.x(), m.y());
      if (site && height_band >= 0 && !std::isnan(out.At(height_band, row, col)))
        out.At(height_band, row, col) = static_cast<float>(
            site->SiteFromMap(Eigen::Vector3d(m.x(), m.y(), out.At(height_band, row, col))).z());
    }
  return out;
}

GeoRaster SiteRasterFromMap(const GeoRaster& in_map, const SiteCrs* site) {
  in_map.Check("SiteRasterFromMap");
  if (!site) return SiteRasterFromMap(in_map, site, in_map);
  const double map_z = site->MapFromSite(Eigen::Vector3d::Zero()).z(), cell = in_map.cell_size;
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  for (const double x : {in_map.origin_x, in_map.origin_x + in_map.width * cell})
    for (const double y : {in_map.origin_y, in_map.origin_y - in_map.height * cell}) {
      const Eigen::Vector2d c = site->SiteFromMap(Eigen::Vector3d(x, y, map_z)).head<2>();
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
  const double x0 = std::floor(lo.x() / cell) * cell, y1 = std::ceil(hi.y() / cell) * cell;
  const GeoRaster grid(std::max(1, static_cast<int>(std::ceil((hi.x() - x0) / cell))),
                       std::max(1, static_cast<int>(std::ceil((y1 - lo.y()) / cell))), x0, y1,
                       cell);
  return SiteRasterFromMap(in_map, site, grid);
}

}  // namespace io
}  // namespace slope_monitor
