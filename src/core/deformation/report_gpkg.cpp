// GeoPackage report through OGR: layers "points", "latest_displacement" and
// "change_polygons".
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <functional>
#include <iterator>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/deformation/report.h"
#include "slope_monitor/core/deformation/units.h"

namespace slope_monitor {
namespace deformation {
namespace {

// The map CRS (SiteCrs::MapCrs: an EPSG code where it has one), else the
// local engineering CRS "site".
OGRSpatialReference ReportSrs(const std::optional<SiteCrs>& site, const std::string& path) {
  OGRSpatialReference srs;
  if (site && site->MapEpsg() > 0) {
    if (srs.importFromEPSG(site->MapEpsg()) != OGRERR_NONE)
      throw IoError(Message("GeoPackage '", path, "': GDAL does not know ", site->MapCrs()));
  } else if (site) {
    const std::string wkt = site->CrsWkt();
    if (srs.importFromWkt(wkt.c_str()) != OGRERR_NONE)
      throw IoError(Message("GeoPackage '", path, "': GDAL cannot read the site CRS"));
  } else {
    srs.SetLocalCS("site");
    srs.SetLinearUnits(SRS_UL_METER, 1.0);
  }
  srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  return srs;
}

// Site -> the layers' coordinates (the map CRS; the site frame without a georeference).
using ToMap = std::function<Eigen::Vector3d(const Eigen::Vector3d&)>;

// A UTC time as an OGR DateTime field (time zone flag 100: UTC), to the millisecond.
void SetTime(OGRFeature* f, const char* field, double stamp) {
  const double whole = std::floor(stamp);
  const std::time_t t = static_cast<std::time_t>(whole);
  std::tm tm{};
  gmtime_r(&t, &tm);
  const double seconds = tm.tm_sec + std::round((stamp - whole) * 1e3) / 1e3;
  f->SetField(field, tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min,
              static_cast<float>(seconds), 100);
}

OGRLayer* NewLayer(GDALDataset* ds, const char* name, OGRSpatialReference* srs,
                   const std::string& path, OGRwkbGeometryType type = wkbPoint25D) {
  OGRLayer* layer = ds->CreateLayer(name, srs, type, nullptr);
  if (!layer)
    throw IoError(
        Message("GeoPackage '", path, "': cannot create layer ", name, ": ", CPLGetLastErrorMsg()));
  return layer;
}

void AddField(OGRLayer* layer, const char* name, OGRFieldType type, const std::string& path) {
  OGRFieldDefn f(name, type);
  if (layer->CreateField(&f) != OGRERR_NONE)
    throw IoError(
        Message("GeoPackage '", path, "': cannot add field ", name, ": ", CPLGetLastErrorMsg()));
}

// x in site, written in the layer's CRS.
void AddPoint(OGRLayer* layer, OGRFeature* f, const Eigen::Vector3d& x, const ToMap& to_map,
              const std::string& path) {
  const Eigen::Vector3d c = to_map(x);
  OGRPoint pt(c.x(), c.y(), c.z());
  f->SetGeometry(&pt);
  if (layer->CreateFeature(f) != OGRERR_NONE)
    throw IoError(
        Message("GeoPackage '", path, "': cannot write a feature: ", CPLGetLastErrorMsg()));
}

void WritePointsLayer(GDALDataset* ds, const Snapshot& s, OGRSpatialReference* srs,
                      const ToMap& to_map, const std::string& path) {
  OGRLayer* layer = NewLayer(ds, "points", srs, path);
  AddField(layer, "point_id", OFTString, path);
  AddField(layer, "sources", OFTString, path);
  for (const PointState& p : s.points) {
    OGRFeature f(layer->GetLayerDefn());
    f.SetField("point_id", p.id.c_str());
    std::string sources;
    for (Source src : p.sources) sources += (sources.empty() ? "" : "+") + SourceName(src);
    f.SetField("sources", sources.c_str());
    AddPoint(layer, &f, p.reference_position, to_map, path);
  }
}

void WriteDisplacementLayer(GDALDataset* ds, const Snapshot& s, OGRSpatialReference* srs,
                            const ToMap& to_map, const std::string& path) {
  OGRLayer* layer = NewLayer(ds, "latest_displacement", srs, path);
  const char* reals[] = {"dx_mm",
                         "dy_mm",
                         "dz_mm",
                         "d_mm",
                         "sigma_dx_mm",
                         "sigma_dy_mm",
                         "sigma_dz_mm",
                         "vx_mm_per_day",
                         "vy_mm_per_day",
                         "vz_mm_per_day",
                         "speed_mm_per_day",
                         "sigma_speed_mm_per_day",
                         "forecast_sigma_h"};
  AddField(layer, "point_id", OFTString, path);
  AddField(layer, "time_utc", OFTDateTime, path);
  for (const char* r : reals) AddField(layer, r, OFTReal, path);
  AddField(layer, "alert", OFTString, path);
  AddField(layer, "alert_level", OFTInteger, path);
  AddField(layer, "forecast_valid", OFTInteger, path);
  AddField(layer, "forecast_failure_time_utc", OFTDateTime, path);
  for (const PointState& p : s.points) {
    OGRFeature f(layer->GetLayerDefn());
    f.SetField("point_id", p.id.c_str());
    SetTime(&f, "time_utc", s.stamp);
    const double values[] = {p.displacement.x() * 1e3,
                             p.displacement.y() * 1e3,
                             p.displacement.z() * 1e3,
                             p.displacement.norm() * 1e3,
                             std::sqrt(p.displacement_covariance(0, 0)) * 1e3,
                             std::sqrt(p.displacement_covariance(1, 1)) * 1e3,
                             std::sqrt(p.displacement_covariance(2, 2)) * 1e3,
                             p.velocity.x() * kMmPerDay,
                             p.velocity.y() * kMmPerDay,
                             p.velocity.z() * kMmPerDay,
                             p.speed * kMmPerDay,
                             p.speed_sigma * kMmPerDay,
                             p.forecast.valid ? p.forecast.sigma / 3600.0 : NAN};
    for (size_t k = 0; k < std::size(reals); ++k) {
      if (std::isfinite(values[k])) f.SetField(reals[k], values[k]);
    }
    f.SetField("alert", AlertName(p.alert).c_str());
    f.SetField("alert_level", static_cast<int>(p.alert));
    f.SetField("forecast_valid", p.forecast.valid ? 1 : 0);
    if (p.forecast.valid) SetTime(&f, "forecast_failure_time_utc", p.forecast.failure_time);
    AddPoint(layer, &f, p.reference_position, to_map, path);
  }
}

// The areas of significant surface change (Snapshot::areas), one polygon
// each with its holes, in the site CRS; written even when empty, so a reader
// finds the layer.
void WriteChangePolygonsLayer(GDALDataset* ds, const Snapshot& s, OGRSpatialReference* srs,
                              const ToMap& to_map, const std::string& path) {
  OGRLayer* layer = NewLayer(ds, "change_polygons", srs, path, wkbPolygon);
  AddField(layer, "area_id", OFTString, path);
  AddField(layer, "epoch", OFTInteger, path);
  AddField(layer, "time_utc", OFTDateTime, path);
  AddField(layer, "sign", OFTInteger, path);
  const char* reals[] = {"area_m2", "volume_m3", "mean_change_m", "max_change_m", "growth_m2"};
  for (const char* r : reals) AddField(layer, r, OFTReal, path);
  AddField(layer, "alert", OFTString, path);
  AddField(layer, "alert_level", OFTInteger, path);
  AddField(layer, "alert_reason", OFTString, path);
  for (const AreaState& a : s.areas) {
    OGRFeature f(layer->GetLayerDefn());
    f.SetField("area_id", a.id.c_str());
    f.SetField("epoch", static_cast<int>(a.epoch));
    SetTime(&f, "time_utc", a.stamp);
    f.SetField("sign", a.area.sign);
    const double values[] = {a.area.area, a.area.volume, a.area.mean_change, a.area.max_change,
                             a.growth};
    for (size_t k = 0; k < std::size(reals); ++k) f.SetField(reals[k], values[k]);
    f.SetField("alert", AlertName(a.alert).c_str());
    f.SetField("alert_level", static_cast<int>(a.alert));
    f.SetField("alert_reason", a.reason.c_str());
    OGRPolygon poly;
    // Vertices at the origin's height (site z = 0): the outlines are horizontal.
    const auto add_ring = [&poly, &to_map](const std::vector<Eigen::Vector2d>& pts) {
      OGRLinearRing ring;
      for (const Eigen::Vector2d& v : pts) {
        const Eigen::Vector3d m = to_map(Eigen::Vector3d(v.x(), v.y(), 0.0));
        ring.addPoint(m.x(), m.y());
      }
      ring.closeRings();
      poly.addRing(&ring);
    };
    add_ring(a.area.outline);
    for (const auto& h : a.area.holes) add_ring(h);
    f.SetGeometry(&poly);
    if (layer->CreateFeature(&f) != OGRERR_NONE)
      throw IoError(Message("GeoPackage '", path,
                            "': cannot write a change polygon: ", CPLGetLastErrorMsg()));
  }
}

}  // namespace

std::string WriteGeoPackage(const Snapshot& s, const std::string& path,
                            const ReportOptions& options) {
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (!driver) throw IoError(Message("GeoPackage '", path, "': GDAL has no GPKG driver"));
  const std::optional<SiteCrs> site = ReportSiteCrs(options);
  OGRSpatialReference srs = ReportSrs(site, path);
  const ToMap to_map = [&site](const Eigen::Vector3d& x) {
    return site ? site->MapFromSite(x) : x;
  };
  const std::string tmp = path + ".tmp-" + std::to_string(getpid()) + ".gpkg";
  std::remove(tmp.c_str());
  GDALDataset* ds = driver->Create(tmp.c_str(), 0, 0, 0, GDT_Unknown, nullptr);
  if (!ds) throw IoError(Message("cannot create GeoPackage '", path, "': ", CPLGetLastErrorMsg()));
  try {
    WritePointsLayer(ds, s, &srs, to_map, path);
    WriteDisplacementLayer(ds, s, &srs, to_map, path);
    WriteChangePolygonsLayer(ds, s, &srs, to_map, path);
  } catch (...) {
    GDALClose(ds);
    std::remove(tmp.c_str());
    throw;
  }
  GDALClose(ds);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    throw IoError(Message("cannot rename '", tmp, "' to report '", path, "': ", why));
  }
  return path;
}

}  // namespace deformation
}  // namespace slope_monitor
