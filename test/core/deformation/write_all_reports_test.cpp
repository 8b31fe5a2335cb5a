// deformation::WriteAllReports, the one report writer of the estimator
// nodelet and process_bag: which DEM lies under the map (the newest
// surface_eNN.tif of the report folder), and who draws the pictures
// (matplotlib from the history, else OpenCV).
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <ogrsf_frmts.h>

#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/deformation/plot_report.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

struct ReportsTempDir {
  ReportsTempDir() {
    char tmpl[] = "/tmp/write_all_reports_test_XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~ReportsTempDir() { std::system(("rm -rf '" + path + "'").c_str()); }
  std::string path;
};

void Touch(const std::string& path) { std::ofstream(path) << "x"; }

bool Has(const std::vector<std::string>& files, const std::string& name) {
  return std::any_of(files.begin(), files.end(), [&](const std::string& f) {
    return f.size() >= name.size() && f.compare(f.size() - name.size(), name.size(), name) == 0;
  });
}

TEST(WriteAllReports, LatestSurfaceIsTheLargestEpoch) {
  ReportsTempDir dir;
  EXPECT_EQ(LatestSurface(dir.path), "");
  for (const char* f : {"surface_e09.tif", "surface_e10.tif", "surface_e2.tif",
                        "surface_e11.tif.tmp", "change_e12.tif", "surface_e12.tiff"})
    Touch(dir.path + "/" + f);
  EXPECT_EQ(LatestSurface(dir.path), dir.path + "/surface_e10.tif");
  EXPECT_EQ(LatestSurface(dir.path + "/absent"), "");
}

// Two points measured by radio every 2 h for a day, into `db` (or no history).
std::unique_ptr<Estimator> Measured(History* history) {
  auto est = std::make_unique<Estimator>(EstimatorOptions(), history);
  std::vector<testing::Motion> motions(2);
  motions[0].v0 = 5e-3 / testing::kDay;
  testing::SourceSpec radio;
  radio.interval = 7200.0;
  for (const Batch& b :
       testing::MakeBatches(radio, {"p1", "p2"}, motions, testing::kT0 + testing::kDay))
    est->AddBatch(b);
  return est;
}

TEST(WriteAllReports, MatplotlibWithAHistoryOpenCvWithout) {
  ReportsTempDir dir;
  PlotReportOptions plot;
  plot.script = std::string(SM_SOURCE_DIR) + "/scripts/plot_report";
  {
    History history(dir.path + "/h.db");
    const auto est = Measured(&history);
    const std::vector<std::string> files = WriteAllReports(
        *est, dir.path + "/h.db", plot, dir.path + "/with", "", {}, ReportOptions());
    EXPECT_TRUE(Has(files, "/with/deformation.gpkg"));
    EXPECT_TRUE(Has(files, "/with/deformation_series.png"));  // one plot for every point
    EXPECT_TRUE(Has(files, "/with/deformation_inverse_velocity.png"));
    EXPECT_FALSE(Has(files, "/with/deformation_series_p1.png"));
  }
  const auto est = Measured(nullptr);
  const std::vector<std::string> files =
      WriteAllReports(*est, "", plot, dir.path + "/without", "", {"png"}, ReportOptions());
  EXPECT_TRUE(Has(files, "/without/deformation_map.png"));
  EXPECT_TRUE(Has(files, "/without/deformation_series_p1.png"));  // OpenCV: a plot per point
  EXPECT_FALSE(Has(files, "/without/deformation.gpkg"));
}

// The map of scripts/plot_report is in site coordinates (the history's), the
// report GeoPackage in the map CRS (issue 38: UTM of a local_enu site's zone):
// the script gets the change areas in a site-frame copy, removed after. A
// stand-in script keeps what it was given.
TEST(WriteAllReports, ThePlotScriptGetsTheAreasInSiteCoordinates) {
  ReportsTempDir dir;
  const std::string seen = dir.path + "/polygons_seen.gpkg";
  PlotReportOptions plot;
  plot.script = dir.path + "/plot_stand_in";
  std::ofstream(plot.script) << "#!/bin/sh\nwhile [ $# -gt 0 ]; do\n  [ \"$1\" = --polygons ] && "
                                "cp \"$2\" '"
                             << seen << "' && echo \"$2\" > '" << seen << ".name'\n  shift\ndone\n";
  ASSERT_EQ(chmod(plot.script.c_str(), 0755), 0);
  Estimator est{EstimatorOptions()};
  AreaBatch b;
  b.stamp = 1.7e9;
  b.epoch = 1;
  ChangeArea a;  // 8 x 8 m at site (10, 20)
  a.sign = -1;
  a.area = 64.0;
  a.outline = {{10, 20}, {18, 20}, {18, 28}, {10, 28}};
  b.areas = {a};
  est.AddAreas(b);
  ReportOptions georeferenced;
  georeferenced.geodetic_origin = Eigen::Vector3d(35.0, 139.0, 100.0);
  const std::vector<std::string> files = WriteAllReports(
      est, dir.path + "/h.db", plot, dir.path + "/r", "", {"gpkg", "png"}, georeferenced);
  EXPECT_TRUE(Has(files, "/r/deformation.gpkg"));
  GDALAllRegister();
  const auto extent = [](const std::string& path, std::string* epsg) {
    GDALDataset* ds = GDALDataset::Open(path.c_str(), GDAL_OF_VECTOR | GDAL_OF_READONLY);
    OGREnvelope env;
    if (!ds) return env;
    OGRLayer* layer = ds->GetLayerByName("change_polygons");
    if (layer) {
      layer->GetExtent(&env);
      const char* code =
          layer->GetSpatialRef() ? layer->GetSpatialRef()->GetAuthorityCode(nullptr) : nullptr;
      *epsg = code ? code : "";
    }
    GDALClose(ds);
    return env;
  };
  std::string epsg;
  const OGREnvelope site = extent(seen, &epsg);
  EXPECT_EQ(epsg, "");  // the local CRS "site"
  EXPECT_DOUBLE_EQ(site.MinX, 10.0);
  EXPECT_DOUBLE_EQ(site.MaxY, 28.0);
  const OGREnvelope map = extent(dir.path + "/r/deformation.gpkg", &epsg);
  EXPECT_EQ(epsg, "32654");  // UTM zone 54: easting about 317 km
  EXPECT_GT(map.MinX, 3e5);
  std::ifstream name(seen + ".name");
  std::string copy;
  std::getline(name, copy);
  EXPECT_FALSE(copy.empty());
  EXPECT_FALSE(std::ifstream(copy).good()) << copy << " left behind";
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
