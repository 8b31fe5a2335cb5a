// Reports read back: CSV parses to the numbers written, GeoJSON has the
// FeatureCollection structure (checked with yaml-cpp, a JSON superset
// parser), the GeoTIFF reads back through GDAL with the right geotransform
// and an interpolated field that honours the points, the PNGs decode.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gdal_priv.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/report.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

using testing::kDay;
using testing::kT0;

std::string ReportTempDir(const std::string& name) {
  const std::string d = "/tmp/sm_deformation_reports_" + std::to_string(getpid()) + "_" + name;
  mkdir(d.c_str(), 0755);
  return d;
}

// Three points: two moving (10 mm/day south-down), one stable; radio, 2 days.
// Reference positions (test_scenario.h): tag36h11/1 at x = 0, tag36h11/2 at
// x = 10, rock at x = 20, all y = 50. Snapshots list points sorted by id.
Estimator& ReportScenario() {
  static Estimator* est = [] {
    auto* e = new Estimator(EstimatorOptions());
    std::vector<testing::Motion> motions(3);
    motions[0].v0 = motions[1].v0 = 10e-3 / kDay;
    testing::SourceSpec radio;
    radio.interval = 3600.0;
    radio.sigma = Eigen::Vector3d(0.002, 0.002, 0.002);
    for (const Batch& b :
         testing::MakeBatches(radio, {"tag36h11/1", "tag36h11/2", "rock"}, motions, kT0 + 2 * kDay))
      e->AddBatch(b);
    return e;
  }();
  return *est;
}

std::vector<std::string> SplitCsvLine(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        cur += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

TEST(Report, CsvParsesBackToTheEstimates) {
  const Snapshot s = ReportScenario().GetSnapshot();
  const std::string path = ReportTempDir("csv") + "/points.csv";
  WriteCsv(s, path);
  std::ifstream in(path);
  std::string header, line;
  std::getline(in, header);
  const std::vector<std::string> cols = SplitCsvLine(header);
  ASSERT_EQ(cols[0], "id");
  auto col = [&](const std::string& name) {
    return static_cast<size_t>(std::find(cols.begin(), cols.end(), name) - cols.begin());
  };
  ASSERT_LT(col("d_mm"), cols.size());
  ASSERT_LT(col("speed_mm_per_day"), cols.size());
  int rows = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = SplitCsvLine(line);
    ASSERT_EQ(f.size(), cols.size()) << line;
    const PointState& p = s.points.at(rows);
    EXPECT_EQ(f[0], p.id);
    EXPECT_NEAR(std::stod(f[col("d_mm")]), p.displacement.norm() * 1e3, 1e-3);
    EXPECT_NEAR(std::stod(f[col("speed_mm_per_day")]), p.speed * 86400e3, 1e-3);
    EXPECT_EQ(f[col("alert")], AlertName(p.alert));
    ++rows;
  }
  EXPECT_EQ(rows, 3);
  // The moving points show ~20 mm after 2 days at 10 mm/day (truth), the rock ~0.
  ASSERT_EQ(s.points[0].id, "rock");
  EXPECT_LT(s.points[0].displacement.norm(), 0.004);
  EXPECT_NEAR(s.points[1].displacement.norm(), 0.020, 0.004);
}

TEST(Report, GeoJsonIsAFeatureCollection) {
  const Snapshot s = ReportScenario().GetSnapshot();
  const std::string dir = ReportTempDir("geojson");
  ReportOptions o;
  o.geodetic_origin = Eigen::Vector3d(35.0, 139.0, 100.0);
  const std::string path = dir + "/geo.geojson";
  WriteGeoJson(s, path, o);
  const YAML::Node root = YAML::LoadFile(path);
  // RFC 7946 members only (issue 38: no "crs_note" nor snapshot members beside them).
  ASSERT_TRUE(root.IsMap());
  EXPECT_EQ(root.size(), 2u);
  EXPECT_EQ(root["type"].as<std::string>(), "FeatureCollection");
  ASSERT_TRUE(root["features"].IsSequence());
  ASSERT_EQ(root["features"].size(), 3u);
  for (size_t i = 0; i < 3; ++i) {
    const YAML::Node f = root["features"][i];
    EXPECT_EQ(f["type"].as<std::string>(), "Feature");
    EXPECT_EQ(f["geometry"]["type"].as<std::string>(), "Point");
    ASSERT_EQ(f["geometry"]["coordinates"].size(), 3u);
    const YAML::Node p = f["properties"];
    EXPECT_EQ(p["id"].as<std::string>(), s.points[i].id);
    EXPECT_NEAR(p["d_mm"].as<double>(), s.points[i].displacement.norm() * 1e3, 1e-3);
    EXPECT_NEAR(p["dx_mm"].as<double>(), s.points[i].displacement.x() * 1e3, 1e-3);
    EXPECT_TRUE(p["vz_mm_per_day"].IsScalar());
    EXPECT_TRUE(p["sigma_dz_mm"].IsScalar());
    EXPECT_TRUE(p["alert"].IsScalar());
    EXPECT_TRUE(p["forecast_valid"].IsScalar());
    EXPECT_EQ(p["reference_epoch"].as<long>(), s.reference_epoch);
    const double x = f["geometry"]["coordinates"][0].as<double>();
    const double y = f["geometry"]["coordinates"][1].as<double>();
    const double east = s.points[i].reference_position.x();
    // `east` metres east, 50 m north of (35 N, 139 E): 1 deg of latitude
    // there is 110.94 km, 1 deg of longitude 91.29 km (WGS 84).
    EXPECT_NEAR(y, 35.0 + 50.0 / 110941.0, 2e-7);
    EXPECT_NEAR(x, 139.0 + east / 91288.0, 2e-7);
  }
  // Without a georeference there are no WGS 84 coordinates to write: refused, named.
  try {
    WriteGeoJson(s, dir + "/local.geojson", ReportOptions());
    FAIL() << "a GeoJSON in site metres was written";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("RFC 7946"), std::string::npos) << e.what();
  }
}

TEST(Report, GeoTiffReadsBackThroughGdal) {
  const Snapshot s = ReportScenario().GetSnapshot();
  ReportOptions o;
  o.grid_resolution = 0.5;
  o.grid_margin = 5.0;
  const std::string path = ReportTempDir("tif") + "/field.tif";
  WriteDisplacementGeoTiff(s, path, o);
  GDALAllRegister();
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  ASSERT_NE(ds, nullptr);
  double gt[6];
  ASSERT_EQ(ds->GetGeoTransform(gt), CE_None);
  // Points at x = 0, 10, 20 and y = 50: grid from x -5 to 25, y 55 down to 45.
  EXPECT_DOUBLE_EQ(gt[0], -5.0);
  EXPECT_DOUBLE_EQ(gt[1], 0.5);
  EXPECT_DOUBLE_EQ(gt[2], 0.0);
  EXPECT_DOUBLE_EQ(gt[3], 55.0);
  EXPECT_DOUBLE_EQ(gt[4], 0.0);
  EXPECT_DOUBLE_EQ(gt[5], -0.5);
  EXPECT_EQ(ds->GetRasterXSize(), 60);
  EXPECT_EQ(ds->GetRasterYSize(), 20);
  ASSERT_EQ(ds->GetRasterCount(), 7);
  EXPECT_STREQ(ds->GetRasterBand(5)->GetDescription(), "vx_mm_per_day");
  // The cell whose corner touches tag36h11/2 (x = 10, y = 50): IDW is exact
  // at a point, so the cells around it are close to its magnitude; the cell
  // at the stable rock (x = 20) is close to the rock's.
  ASSERT_EQ(s.points[2].id, "tag36h11/2");
  float v = 0;
  GDALRasterBand* band = ds->GetRasterBand(1);
  ASSERT_EQ(band->RasterIO(GF_Read, 29, 9, 1, 1, &v, 1, 1, GDT_Float32, 0, 0), CE_None);
  EXPECT_NEAR(v, s.points[2].displacement.norm(), 0.002);
  ASSERT_EQ(band->RasterIO(GF_Read, 49, 9, 1, 1, &v, 1, 1, GDT_Float32, 0, 0), CE_None);
  EXPECT_NEAR(v, s.points[0].displacement.norm(), 0.003);
  // The velocity bands in mm/day: the cell at x = 10, y = 50 (its centre
  // 0.25 m from the point) holds about the point's velocity.
  for (int k = 0; k < 3; ++k) {
    ASSERT_EQ(ds->GetRasterBand(5 + k)->RasterIO(GF_Read, 29, 9, 1, 1, &v, 1, 1, GDT_Float32, 0, 0),
              CE_None);
    const double expected = s.points[2].velocity(k) * 86400e3;
    EXPECT_NEAR(v, expected, 0.01 * std::abs(expected) + 0.001) << "band " << 5 + k;
  }
  GDALClose(ds);
}

TEST(Report, PngsDecodeWithTheExpectedSize) {
  Estimator& est = ReportScenario();
  ReportOptions o;
  o.map_width = 900;
  o.series_width = 800;
  o.series_height = 500;
  const std::string dir = ReportTempDir("png") + "/nested/reports";
  const std::vector<std::string> files =
      WriteReports(est, ReportTempDir("png"), "nested/reports", {"png", "csv"}, o);
  ASSERT_EQ(files.size(), 5u);  // map + 3 series + csv
  const cv::Mat map = cv::imread(dir + "/deformation_map.png");
  ASSERT_FALSE(map.empty());
  EXPECT_EQ(map.cols, 900);
  EXPECT_GT(map.rows, 300);
  const cv::Mat series = cv::imread(dir + "/deformation_series_tag36h11_1.png");
  ASSERT_FALSE(series.empty());
  EXPECT_EQ(series.cols, 800);
  EXPECT_EQ(series.rows, 500);
  // Not blank: the arrows and curves draw coloured pixels.
  cv::Mat diff;
  cv::absdiff(series, cv::Scalar(255, 255, 255), diff);
  EXPECT_GT(cv::countNonZero(diff.reshape(1)), 2000);
  // No temporary file is left behind: the folder holds exactly the files listed.
  size_t entries = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    ++entries;
    EXPECT_NE(std::find(files.begin(), files.end(), entry.path().string()), files.end())
        << entry.path();
  }
  EXPECT_EQ(entries, files.size());
}

TEST(Report, UnwritableDirectoryNamesTheFile) {
  const Snapshot s = ReportScenario().GetSnapshot();
  try {
    WriteCsv(s, "/proc/no_such_dir/points.csv");
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("/proc/no_such_dir/points.csv"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(WriteReports(ReportScenario(), ReportTempDir("bad"), "", {"pdf"}, ReportOptions()),
               InvalidArgument);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
