// Areas of significant surface change in the reports: the GeoPackage layer
// change_polygons (site CRS) and the GeoJSON Polygon features (WGS 84),
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
  const OGRPolygon* g = f->GetGeometryRef()->toPolygon();
  EXPECT_DOUBLE_EQ(g->get_Area(), 64.0);  // site metres
  OGREnvelope env;
  g->getEnvelope(&env);
  EXPECT_DOUBLE_EQ(env.MinX, 10.0);
  EXPECT_DOUBLE_EQ(env.MaxY, 28.0);
}

TEST(ReportAreas, GeoJsonPolygonInWgs84) {
  const std::string path =
      WriteGeoJson(Scenario(), TempDir("json") + "/deformation.geojson", Georeferenced());
  const YAML::Node root = YAML::LoadFile(path);
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
  EXPECT_EQ(root["alert"].as<std::string>(), "watch");
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
