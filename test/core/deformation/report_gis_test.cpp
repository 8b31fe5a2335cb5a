// The reports as GIS tools see them (GDAL's own utilities through its API,
// the equivalents of gdalinfo, gdalwarp -t_srs EPSG:4326 and ogrinfo):
//  * the GeoTIFF carries the EPSG code of the UTM zone of the site's origin
//    (local_enu) or of the site's CRS (shifted_crs), gdalwarp takes it to EPSG:4326, and the
//    warped raster holds each point's displacement at the point's longitude
//    and latitude (hand values: at 35 N one degree of latitude is 110.94 km
//    and one of longitude 91.29 km on WGS 84); cells beyond the points'
//    convex hull plus the margin are nodata;
//  * the GeoJSON's properties are flat: a number or a word each;
//  * the GeoPackage has layers points and latest_displacement in that EPSG
//    CRS, times as DateTime; a feature transformed by OGR to EPSG:4326 lands
//    on the hand values;
//  * the CSV has lon/lat and ISO 8601 UTC times.
#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <ctime>
#include <fstream>
#include <memory>
#include <regex>
#include <sstream>

#include <gdal_priv.h>
#include <gdal_utils.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>
#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/deformation/report.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

using testing::kDay;
using testing::kT0;

// tag36h11/1 at x = 0, tag36h11/2 at x = 10 (both 10 mm/day), rock at x = 20
// (stable), all y = 50 (test_scenario.h); site origin 35 N 139 E, 100 m.
Snapshot GisScenario() {
  Estimator e{EstimatorOptions()};
  std::vector<testing::Motion> motions(3);
  motions[0].v0 = motions[1].v0 = 10e-3 / kDay;
  testing::SourceSpec radio;
  radio.interval = 3600.0;
  radio.sigma = Eigen::Vector3d(0.002, 0.002, 0.002);
  for (const Batch& b :
       testing::MakeBatches(radio, {"tag36h11/1", "tag36h11/2", "rock"}, motions, kT0 + 2 * kDay))
    e.AddBatch(b);
  return e.GetSnapshot();
}

ReportOptions GisGeoreferenced() {
  ReportOptions o;
  o.geodetic_origin = Eigen::Vector3d(35.0, 139.0, 100.0);
  return o;
}

// Hand values: longitude, latitude of site (x, 50).
double Lon(double x) { return 139.0 + x / 91288.0; }
double Lat() { return 35.0 + 50.0 / 110941.0; }

std::string GisTempDir(const std::string& name) {
  const std::string d = "/tmp/sm_report_gis_" + std::to_string(getpid()) + "_" + name;
  mkdir(d.c_str(), 0755);
  return d;
}

const PointState& PointById(const Snapshot& s, const std::string& id) {
  for (const PointState& p : s.points)
    if (p.id == id) return p;
  throw std::runtime_error("no point " + id);
}

// gdalwarp -t_srs EPSG:4326 -r near src -> out; nullptr when GDAL fails.
GDALDatasetH GisWarpToWgs84(GDALDatasetH src, const std::string& out, int* failed) {
  const char* args[] = {"-t_srs", "EPSG:4326", "-r", "near", nullptr};
  GDALWarpAppOptions* wo = GDALWarpAppOptionsNew(const_cast<char**>(args), nullptr);
  GDALDatasetH warped = GDALWarp(out.c_str(), nullptr, 1, &src, wo, failed);
  GDALWarpAppOptionsFree(wo);
  return warped;
}

// ogrinfo: a vector file opened read-only, closed with its owner.
using GisVector = std::unique_ptr<GDALDataset, void (*)(GDALDataset*)>;
GisVector GisOpenVector(const std::string& path) {
  return GisVector(GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY),
                   [](GDALDataset* d) { GDALClose(d); });
}

float Sample(GDALDataset* ds, double x, double y) {
  double gt[6];
  EXPECT_EQ(ds->GetGeoTransform(gt), CE_None);
  const int col = static_cast<int>(std::floor((x - gt[0]) / gt[1]));
  const int row = static_cast<int>(std::floor((y - gt[3]) / gt[5]));
  float v = NAN;
  if (col < 0 || row < 0 || col >= ds->GetRasterXSize() || row >= ds->GetRasterYSize()) return v;
  EXPECT_EQ(ds->GetRasterBand(1)->RasterIO(GF_Read, col, row, 1, 1, &v, 1, 1, GDT_Float32, 0, 0),
            CE_None);
  return v;
}

TEST(ReportGis, GeoTiffWarpsToWgs84WithThePointsInPlace) {
  const Snapshot s = GisScenario();
  const std::string dir = GisTempDir("tif");
  const std::string path =
      WriteDisplacementGeoTiff(s, dir + "/deformation.tif", GisGeoreferenced());
  GDALAllRegister();
  GDALDatasetH src = GDALOpen(path.c_str(), GA_ReadOnly);
  ASSERT_NE(src, nullptr);
  // gdalinfo -json: the UTM zone of the origin (35 N, 139 E: zone 54, EPSG:32654) by its
  // EPSG code, a north-up grid (issue 38: was a custom orthographic CRS named "unknown").
  const char* json[] = {"-json", nullptr};
  GDALInfoOptions* io = GDALInfoOptionsNew(const_cast<char**>(json), nullptr);
  char* info = GDALInfo(src, io);
  GDALInfoOptionsFree(io);
  ASSERT_NE(info, nullptr);
  EXPECT_NE(std::string(info).find("ID[\\\"EPSG\\\",32654]]"), std::string::npos) << info;
  EXPECT_EQ(std::string(info).find("unknown"), std::string::npos) << info;
  CPLFree(info);
  double gt[6];
  ASSERT_EQ(GDALGetGeoTransform(src, gt), CE_None);
  EXPECT_EQ(gt[2], 0.0);
  EXPECT_EQ(gt[4], 0.0);
  // Masked: the corner cell (13.4 m from the nearest point, margin 10 m) is nodata, the points'
  // cells are not (tag36h11/2 at site (10, 50) taken to UTM by SiteCrs, site_crs_test).
  GDALDataset* tif = GDALDataset::FromHandle(src);
  // nodata is NaN and declared so on every band, as in the dense GeoTIFFs (issue 38: was -9999)
  EXPECT_TRUE(std::isnan(Sample(tif, gt[0] + 0.5, gt[3] - 0.5)));  // its north-west corner cell
  const Eigen::Vector3d at_point =
      SiteCrs::LocalEnuAtWgs84(35.0, 139.0, 100.0).MapFromSite(Eigen::Vector3d(10.0, 50.0, 0.0));
  EXPECT_TRUE(std::isfinite(Sample(tif, at_point.x(), at_point.y())));
  for (int b = 1; b <= tif->GetRasterCount(); ++b) {
    int has_nodata = 0;
    EXPECT_TRUE(std::isnan(tif->GetRasterBand(b)->GetNoDataValue(&has_nodata))) << "band " << b;
    EXPECT_TRUE(has_nodata) << "band " << b;
  }
  int failed = 0;
  GDALDatasetH warped = GisWarpToWgs84(src, dir + "/wgs84.tif", &failed);
  ASSERT_NE(warped, nullptr);
  EXPECT_EQ(failed, 0);
  GDALDataset* w = GDALDataset::FromHandle(warped);
  for (const char* id : {"tag36h11/1", "tag36h11/2", "rock"}) {
    const PointState& p = PointById(s, id);
    const float v = Sample(w, Lon(p.reference_position.x()), Lat());
    EXPECT_NEAR(v, p.displacement.norm(), 0.002)
        << id << " at " << Lon(p.reference_position.x()) << ", " << Lat();
  }
  GDALClose(warped);
  GDALClose(src);
}

TEST(ReportGis, GeoJsonPropertiesAreFlat) {
  const Snapshot s = GisScenario();
  const std::string path =
      WriteGeoJson(s, GisTempDir("json") + "/deformation.geojson", GisGeoreferenced());
  const YAML::Node root = YAML::LoadFile(path);
  ASSERT_EQ(root["features"].size(), 3u);
  for (const YAML::Node& f : root["features"]) {
    const YAML::Node c = f["geometry"]["coordinates"];
    EXPECT_NEAR(c[1].as<double>(), Lat(), 2e-7);
    for (const auto& kv : f["properties"]) {
      const std::string key = kv.first.as<std::string>();
      ASSERT_TRUE(kv.second.IsScalar()) << key << " is not a number or a word";
      const std::string v = kv.second.as<std::string>();
      EXPECT_TRUE(v.empty() || (v[0] != '{' && v[0] != '['))
          << key << " holds JSON in a string: " << v;
      if (key.size() > 3 &&
          (key.find("_mm") != std::string::npos || key.find("forecast_valid") == 0)) {
        EXPECT_NO_THROW(kv.second.as<double>()) << key << " = " << v;
      }
    }
  }
}

TEST(ReportGis, GeoPackageHasThePointLayersInTheSiteCrs) {
  const Snapshot s = GisScenario();
  const std::string path =
      WriteGeoPackage(s, GisTempDir("gpkg") + "/deformation.gpkg", GisGeoreferenced());
  GDALAllRegister();
  const GisVector ds = GisOpenVector(path);
  ASSERT_NE(ds, nullptr);
  ASSERT_EQ(ds->GetLayerCount(), 3);  // and change_polygons (empty here)
  OGRLayer* points = ds->GetLayerByName("points");
  OGRLayer* latest = ds->GetLayerByName("latest_displacement");
  ASSERT_NE(points, nullptr);
  ASSERT_NE(latest, nullptr);
  EXPECT_EQ(points->GetFeatureCount(), 3);
  EXPECT_EQ(latest->GetFeatureCount(), 3);
  ASSERT_NE(latest->GetSpatialRef(), nullptr);
  EXPECT_TRUE(latest->GetSpatialRef()->IsProjected());
  // ogrinfo: EPSG:32654, the UTM zone of the origin (35 N, 139 E), on every layer.
  for (OGRLayer* l : {points, latest, ds->GetLayerByName("change_polygons")}) {
    ASSERT_NE(l, nullptr);
    ASSERT_NE(l->GetSpatialRef(), nullptr) << l->GetName();
    EXPECT_STREQ(l->GetSpatialRef()->GetAuthorityName(nullptr), "EPSG") << l->GetName();
    EXPECT_STREQ(l->GetSpatialRef()->GetAuthorityCode(nullptr), "32654") << l->GetName();
  }
  // Times are DateTime fields in UTC (issue 38: were text).
  OGRFeatureDefn* defn = latest->GetLayerDefn();
  for (const char* field : {"time_utc", "forecast_failure_time_utc"}) {
    const int k = defn->GetFieldIndex(field);
    ASSERT_GE(k, 0) << field;
    EXPECT_EQ(defn->GetFieldDefn(k)->GetType(), OFTDateTime) << field;
  }
  const std::time_t stamp = static_cast<std::time_t>(std::floor(s.stamp));
  std::tm utc{};
  gmtime_r(&stamp, &utc);
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> to_wgs84(
      OGRCreateCoordinateTransformation(latest->GetSpatialRef(), &wgs84));
  ASSERT_NE(to_wgs84, nullptr);
  int n = 0;
  for (auto& f : *latest) {
    const PointState& p = PointById(s, f->GetFieldAsString("point_id"));
    EXPECT_NEAR(f->GetFieldAsDouble("d_mm"), p.displacement.norm() * 1e3, 1e-9);
    EXPECT_STREQ(f->GetFieldAsString("alert"), AlertName(p.alert).c_str());
    int year = 0, month = 0, day = 0, hour = 0, minute = 0, tz = 0;
    float second = 0.0f;
    ASSERT_TRUE(f->GetFieldAsDateTime(defn->GetFieldIndex("time_utc"), &year, &month, &day, &hour,
                                      &minute, &second, &tz));
    EXPECT_EQ(year, utc.tm_year + 1900);
    EXPECT_EQ(month, utc.tm_mon + 1);
    EXPECT_EQ(day, utc.tm_mday);
    EXPECT_EQ(hour * 3600 + minute * 60 + second,
              utc.tm_hour * 3600 + utc.tm_min * 60 + utc.tm_sec + (s.stamp - std::floor(s.stamp)));
    EXPECT_EQ(tz, 100);  // UTC
    const OGRPoint* g = f->GetGeometryRef()->toPoint();
    // z: WGS 84 ellipsoidal height; the origin is 100 m, and a point 50 m from it
    // is below the tangent plane by 50^2 / (2 R) = 0.2 mm.
    EXPECT_NEAR(g->getZ(), 100.0 + p.reference_position.z(), 0.001);
    double x = g->getX(), y = g->getY();
    ASSERT_TRUE(to_wgs84->Transform(1, &x, &y));
    EXPECT_NEAR(x, Lon(p.reference_position.x()), 2e-7);
    EXPECT_NEAR(y, Lat(), 2e-7);
    ++n;
  }
  EXPECT_EQ(n, 3);
}

// A site in a shifted projected CRS (UTM zone 54N, site = easting/northing/height
// minus the origin 500000, 3985000, 100): the GeoTIFF and the GeoPackage are in
// EPSG:32654 itself. Hand value for the check: tag36h11/1 (site x = 0) is on the
// zone's central meridian (141 E), where the northing is 0.9996 times the WGS 84
// meridian arc, so its latitude inverts the arc series (below) at
// 3985050 / 0.9996 m; gdalwarp to EPSG:4326 puts its displacement there.
double LatitudeOnTheCentralMeridian(double northing) {
  const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2.0 - f);
  const double e4 = e2 * e2, e6 = e4 * e2;
  auto arc = [&](double p) {
    return a * ((1 - e2 / 4 - 3 * e4 / 64 - 5 * e6 / 256) * p -
                (3 * e2 / 8 + 3 * e4 / 32 + 45 * e6 / 1024) * std::sin(2 * p) +
                (15 * e4 / 256 + 45 * e6 / 1024) * std::sin(4 * p) -
                (35 * e6 / 3072) * std::sin(6 * p));
  };
  double p = northing / 0.9996 / a;
  for (int i = 0; i < 20; ++i) p += (northing / 0.9996 - arc(p)) / a * 0.99;  // dM/dphi ~ a
  return p * 180.0 / M_PI;
}

TEST(ReportGis, ShiftedCrsSiteWritesTheGeoTiffAndGeoPackageInThatCrs) {
  const Snapshot s = GisScenario();
  ReportOptions o;
  SiteCrsOptions crs;
  crs.crs = "EPSG:32654";
  crs.origin = Eigen::Vector3d(500000.0, 3985000.0, 100.0);
  crs.frame = SiteCrsOptions::Frame::kShiftedCrs;
  o.site_crs = crs;
  const std::string dir = GisTempDir("utm");
  const std::string tif = WriteDisplacementGeoTiff(s, dir + "/deformation.tif", o);
  GDALAllRegister();
  GDALDatasetH src = GDALOpen(tif.c_str(), GA_ReadOnly);
  ASSERT_NE(src, nullptr);
  GDALDataset* t = GDALDataset::FromHandle(src);
  ASSERT_NE(t->GetSpatialRef(), nullptr);
  EXPECT_STREQ(t->GetSpatialRef()->GetAuthorityCode(nullptr), "32654");
  double gt[6];
  ASSERT_EQ(t->GetGeoTransform(gt), CE_None);
  // Points at site x = 0..20, y = 50, margin 10 m, 1 m cells.
  EXPECT_DOUBLE_EQ(gt[0], 500000.0 - 10.0);
  EXPECT_DOUBLE_EQ(gt[3], 3985000.0 + 60.0);
  const PointState& p1 = PointById(s, "tag36h11/1");
  EXPECT_NEAR(Sample(t, 500000.25, 3985050.25), p1.displacement.norm(), 0.002);
  int failed = 0;
  GDALDatasetH warped = GisWarpToWgs84(src, dir + "/wgs84.tif", &failed);
  ASSERT_NE(warped, nullptr);
  EXPECT_EQ(failed, 0);
  const double lat = LatitudeOnTheCentralMeridian(3985050.0);
  EXPECT_NEAR(Sample(GDALDataset::FromHandle(warped), 141.0, lat), p1.displacement.norm(), 0.002)
      << "at 141 E, " << lat << " N";
  GDALClose(warped);
  GDALClose(src);

  const std::string gpkg = WriteGeoPackage(s, dir + "/deformation.gpkg", o);
  const GisVector ds = GisOpenVector(gpkg);
  ASSERT_NE(ds, nullptr);
  OGRLayer* points = ds->GetLayerByName("points");
  ASSERT_NE(points, nullptr);
  ASSERT_NE(points->GetSpatialRef(), nullptr);
  EXPECT_STREQ(points->GetSpatialRef()->GetAuthorityCode(nullptr), "32654");
  int n = 0;
  for (auto& f : *points) {
    const PointState& p = PointById(s, f->GetFieldAsString("point_id"));
    const OGRPoint* g = f->GetGeometryRef()->toPoint();
    EXPECT_NEAR(g->getX(), 500000.0 + p.reference_position.x(), 1e-6);
    EXPECT_NEAR(g->getY(), 3985000.0 + p.reference_position.y(), 1e-6);
    EXPECT_NEAR(g->getZ(), 100.0 + p.reference_position.z(), 1e-6);
    ++n;
  }
  EXPECT_EQ(n, 3);
  // The CSV's longitude and latitude (SiteCrs, PROJ) of the point on the central meridian.
  std::ifstream csv(WriteCsv(s, dir + "/deformation.csv", o));
  std::string line;
  std::getline(csv, line);
  bool found = false;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    ASSERT_GE(f.size(), 6u);
    if (f[0] != "\"tag36h11/1\"") continue;
    found = true;
    EXPECT_NEAR(std::stod(f[4]), 141.0, 1e-9) << line;
    EXPECT_NEAR(std::stod(f[5]), lat, 2e-7) << line;
  }
  EXPECT_TRUE(found);
}

TEST(ReportGis, CsvHasLonLatAndIsoTimes) {
  const Snapshot s = GisScenario();
  const std::string path = WriteCsv(s, GisTempDir("csv") + "/deformation.csv", GisGeoreferenced());
  std::ifstream in(path);
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("id,x,y,z,lon,lat,h,time_utc,", 0), 0u) << header;
  const std::regex iso(R"(\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}Z)");
  int rows = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, ',');) f.push_back(c);
    ASSERT_GE(f.size(), 8u);
    const PointState& p = PointById(s, f[0].substr(1, f[0].size() - 2));
    EXPECT_NEAR(std::stod(f[4]), Lon(p.reference_position.x()), 2e-7);
    EXPECT_NEAR(std::stod(f[5]), Lat(), 2e-7);
    EXPECT_TRUE(std::regex_match(f[7], iso)) << f[7];
    ++rows;
  }
  EXPECT_EQ(rows, 3);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
