// deformation::WriteAllReports, the one report writer of the estimator
// nodelet and process_bag: which DEM lies under the map (the newest
// surface_eNN.tif of the report folder), and who draws the pictures
// (matplotlib from the history, else OpenCV).
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
