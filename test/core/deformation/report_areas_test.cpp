// Areas of significant surface change in the reports: the GeoPackage layer
// change_polygons (the map CRS, EPSG:32654 here) and the GeoJSON Polygon features (WGS 84),
// checked against the hand-made squares that went in.
#include <sys/stat.h>
#include <unistd.h>

#include <memory>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>
#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/report.h"

namespace slope_monitor {
namespace deformation {
namespace {

ChangeArea AreasSquare(double x, double y, double side) {
  ChangeArea a;
  a.sign = -1;
  a.area = side * side;
  a.volume = -0.4 * a.area;
  a.mean_change = -0.4;
  a.max_change = -0.7;
  a.outline = {{x, y}, {x + side, y}, {x + side, y + side}, {x, y + side}};
  return a;
}

// Epoch 1: 5 x 5 m at (10, 20); epoch 2: 8 x 8 m there (+39 m^2: watch).
Snapshot Scenario() {
  Estimator e{EstimatorOptions()};
  AreaBatch b;
  b.stamp = 1.7e9;
  b.epoch = 1;
  b.areas = {AreasSquare(10, 20, 5)};
  e.AddAreas(b);
  b.epoch = 2;
  b.stamp += 21600.0;
  b.areas = {AreasSquare(10, 20, 8)};
  e.AddAreas(b);
  return e.GetSnapshot();
}

ReportOptions Georeferenced() {
  ReportOptions o;
  o.geodetic_origin = Eigen::Vector3d(35.0, 139.0, 100.0);
  return o;
}

std::string TempDir(const std::string& name) {
  const std::string d = "/tmp/sm_report_areas_" + std::to_string(getpid()) + "_" + name;
  mkdir(d.c_str(), 0755);
  return d;
}

TEST(ReportAreas, GeoPackageLayerChangePolygons) {
  const std::string path =
      WriteGeoPackage(Scenario(), TempDir("gpkg") + "/deformation.gpkg", Georeferenced());
  GDALAllRegister();
  std::unique_ptr<GDALDataset, void (*)(GDALDataset*)> ds(
      GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY),
      [](GDALDataset* d) { GDALClose(d); });
  ASSERT_NE(ds, nullptr);
  OGRLayer* layer = ds->GetLayerByName("change_polygons");
  ASSERT_NE(layer, nullptr);
  ASSERT_EQ(layer->GetFeatureCount(), 1);
  ASSERT_NE(layer->GetSpatialRef(), nullptr);  // the site CRS, as the points' layer
  ASSERT_NE(ds->GetLayerByName("points"), nullptr);
  EXPECT_TRUE(layer->GetSpatialRef()->IsSame(ds->GetLayerByName("points")->GetSpatialRef()));
  std::unique_ptr<OGRFeature> f(layer->GetNextFeature());
  ASSERT_NE(f, nullptr);
  EXPECT_STREQ(f->GetFieldAsString("area_id"), "e02/1");
  EXPECT_STREQ(f->GetFieldAsString("alert"), "watch");
  EXPECT_DOUBLE_EQ(f->GetFieldAsDouble("area_m2"), 64.0);
  EXPECT_DOUBLE_EQ(f->GetFieldAsDouble("growth_m2"), 39.0);
  EXPECT_EQ(layer->GetLayerDefn()
                ->GetFieldDefn(layer->GetLayerDefn()->GetFieldIndex("time_utc"))
                ->GetType(),
            OFTDateTime);
  // In EPSG:32654 (the UTM zone of 35 N, 139 E), 2 deg west of the central
  // meridian: scale 0.9996 (1 + (2 deg cos 35)^2 / 2) = 1.000009, and 100 m up
  // (the origin's height) ENU metres are R / (R + h) = 0.999984 of the
  // ellipsoid's: 64 m^2 becomes 64 x 0.99999^2, 0.001 m^2 less.
  const OGRPolygon* g = f->GetGeometryRef()->toPolygon();
  EXPECT_NEAR(g->get_Area(), 64.0, 0.005);
  EXPECT_STREQ(layer->GetSpatialRef()->GetAuthorityCode(nullptr), "32654");
  // Its corner (10, 20) at the hand values (as report_gis_test): lon = 139 + x /
  // 91288, lat = 35 + y / 110941.
  OGRSpatialReference wgs84;
  wgs84.importFromEPSG(4326);
  wgs84.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
  std::unique_ptr<OGRCoordinateTransformation> to_wgs84(
      OGRCreateCoordinateTransformation(layer->GetSpatialRef(), &wgs84));
  ASSERT_NE(to_wgs84, nullptr);
  OGRPoint corner;
  g->getExteriorRing()->getPoint(0, &corner);
  double x = corner.getX(), y = corner.getY();
  ASSERT_TRUE(to_wgs84->Transform(1, &x, &y));
  EXPECT_NEAR(x, 139.0 + 10.0 / 91288.0, 2e-7);
  EXPECT_NEAR(y, 35.0 + 20.0 / 110941.0, 2e-7);
}

TEST(ReportAreas, GeoJsonPolygonInWgs84) {
  // Split by geometry type (issue 38): the points in one file, the areas in another.
  const std::string dir = TempDir("json");
  const YAML::Node points =
      YAML::LoadFile(WriteGeoJson(Scenario(), dir + "/deformation.geojson", Georeferenced()));
  EXPECT_EQ(points["features"].size(), 0u);  // this scenario has areas only
  const std::string path =
      WriteAreasGeoJson(Scenario(), dir + "/deformation_areas.geojson", Georeferenced());
  const YAML::Node root = YAML::LoadFile(path);
  EXPECT_EQ(root.size(), 2u);  // "type" and "features" only
  ASSERT_EQ(root["features"].size(), 1u);
  const YAML::Node f = root["features"][0];
  EXPECT_EQ(f["geometry"]["type"].as<std::string>(), "Polygon");
  const YAML::Node ring = f["geometry"]["coordinates"][0];
  ASSERT_EQ(ring.size(), 5u);  // closed
  // Hand values (as report_gis_test): lon = 139 + x / 91288, lat = 35 + y / 110941.
  EXPECT_NEAR(ring[0][0].as<double>(), 139.0 + 10.0 / 91288.0, 2e-7);
  EXPECT_NEAR(ring[0][1].as<double>(), 35.0 + 20.0 / 110941.0, 2e-7);
  EXPECT_EQ(f["properties"]["kind"].as<std::string>(), "change_area");
  EXPECT_DOUBLE_EQ(f["properties"]["area_m2"].as<double>(), 64.0);
  EXPECT_EQ(f["properties"]["alert_level"].as<int>(), 1);
  EXPECT_EQ(f["properties"]["alert"].as<std::string>(), "watch");
  // RFC 7946: the exterior ring counter-clockwise (shoelace sum > 0).
  double twice_area = 0.0;
  for (size_t k = 0; k + 1 < ring.size(); ++k)
    twice_area += ring[k][0].as<double>() * ring[k + 1][1].as<double>() -
                  ring[k + 1][0].as<double>() * ring[k][1].as<double>();
  EXPECT_GT(twice_area, 0.0);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
