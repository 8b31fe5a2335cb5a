// scripts/plot_report (matplotlib) on a small history: three PNGs of the
// expected pixel size with something drawn in them; a missing or corrupt
// history fails with a message naming the file.
#include "slope_monitor/core/deformation/plot_report.h"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/io/geotiff.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

using testing::kDay;
using testing::kMmPerDay;
using testing::kT0;
const std::string kScript = std::string(SM_SOURCE_DIR) + "/scripts/plot_report";

struct PlotTempDir {
  PlotTempDir() {
    char tmpl[] = "/tmp/plot_report_test_XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~PlotTempDir() { std::system(("rm -rf '" + path + "'").c_str()); }
  std::string path;
};

// Two points on a body accelerating to failure at t0 + 3 d and one on stable
// ground, radio every 2 h for 2.5 days, into a history file.
void FillHistory(const std::string& db) {
  History history(db);
  Estimator est(EstimatorOptions(), &history);
  const std::vector<std::string> ids = {"body1", "body2", "stable1"};
  std::vector<testing::Motion> motions(3);
  for (int i = 0; i < 2; ++i) {
    motions[i].v0 = 8 * kMmPerDay;
    motions[i].accelerating = true;
    motions[i].failure_time = kT0 + 3 * kDay;
  }
  testing::SourceSpec radio;
  radio.interval = 7200.0;
  radio.sigma = Eigen::Vector3d(0.003, 0.003, 0.003);
  radio.seed = 5;
  for (const Batch& b : testing::MakeBatches(radio, ids, motions, kT0 + 2.5 * kDay))
    est.AddBatch(b);
}

// Pixels that are not (near) white.
int Drawn(const cv::Mat& image) {
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return cv::countNonZero(grey < 240);
}

TEST(PlotReport, ThreePicturesOfTheExpectedSize) {
  PlotTempDir dir;
  const std::string db = dir.path + "/history.db";
  FillHistory(db);
  // A DEM under the points (site x 0..20, y 40..60: a tilted plane with a bump) for the hillshade.
  io::GeoRaster dem(60, 60, -20.0, 80.0, 1.0);
  dem.AddBand("height");
  for (int r = 0; r < dem.height; ++r)
    for (int c = 0; c < dem.width; ++c) {
      const Eigen::Vector2d x = dem.CellCentre(r, c);
      dem.At(0, r, c) = static_cast<float>(
          0.3 * x.y() + 5.0 * std::exp(-(x - Eigen::Vector2d(10, 50)).squaredNorm() / 50));
    }
  io::WriteGeoTiff(dir.path + "/dem.tif", dem);

  PlotReportOptions o;
  o.script = kScript;
  o.dem = dir.path + "/dem.tif";
  o.site = "test";
  const std::vector<std::string> files = RunPlotReport(o, db, dir.path + "/out", Thresholds());
  ASSERT_EQ(files.size(), 3u);
  // figsize x 100 dpi: series 11 x 7.5 in, inverse velocity 10 x 6, map 10 x 8.
  const std::vector<std::pair<std::string, cv::Size>> expected = {
      {"deformation_series.png", {1100, 750}},
      {"deformation_inverse_velocity.png", {1000, 600}},
      {"deformation_map.png", {1000, 800}}};
  for (size_t k = 0; k < expected.size(); ++k) {
    EXPECT_EQ(files[k], dir.path + "/out/" + expected[k].first);
    const cv::Mat image = cv::imread(files[k]);
    ASSERT_FALSE(image.empty()) << files[k];
    EXPECT_EQ(image.size(), expected[k].second) << files[k];
    EXPECT_GT(Drawn(image), image.total() / 50) << files[k] << " looks blank";
  }
  // The hillshade fills the map's background (a map without one is mostly white).
  EXPECT_GT(Drawn(cv::imread(files[2])), cv::imread(files[2]).total() / 2);
}

std::string StderrOf(const std::string& history) {
  const std::string err = history + ".stderr";
  const std::string cmd =
      "'" + kScript + "' --history '" + history + "' --out '" + history + ".out' 2> '" + err + "'";
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 2) << cmd;
  std::ifstream in(err);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(PlotReport, MissingOrCorruptHistoryIsNamed) {
  PlotTempDir dir;
  const std::string missing = dir.path + "/none.db";
  EXPECT_NE(StderrOf(missing).find("plot_report: history file '" + missing + "' does not exist"),
            std::string::npos);
  const std::string corrupt = dir.path + "/corrupt.db";
  std::ofstream(corrupt) << std::string(4096, 'x');
  const std::string e = StderrOf(corrupt);
  EXPECT_NE(e.find("history file '" + corrupt + "' cannot be read: file is not a database"),
            std::string::npos)
      << e;
  PlotReportOptions o;
  o.script = kScript;
  try {
    RunPlotReport(o, missing, dir.path + "/out", Thresholds());
    FAIL() << "no error";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("exit status 2"), std::string::npos) << e.what();
  }
}

// A picture that cannot be written (here a folder where the file goes; a
// full disk alike) ends with one line naming it and exit status 1, no
// traceback, no temporary left (issue 38).
TEST(PlotReport, AnUnwritablePictureIsOneLineWithoutTraceback) {
  PlotTempDir dir;
  const std::string db = dir.path + "/slope.db";
  FillHistory(db);
  const std::string out = dir.path + "/out";
  const std::string blocked = out + "/deformation_series.png";
  std::filesystem::create_directories(blocked);
  const std::string err = dir.path + "/stderr";
  const int status = std::system(
      ("'" + kScript + "' --history '" + db + "' --out '" + out + "' 2> '" + err + "'").c_str());
  EXPECT_EQ(WEXITSTATUS(status), 1);
  std::ifstream in(err);
  std::stringstream s;
  s << in.rdbuf();
  EXPECT_EQ(s.str(),
            "plot_report: cannot write '" + blocked +
                "': Is a directory; the pictures not yet written keep their previous version\n");
  for (const auto& f : std::filesystem::directory_iterator(out))
    EXPECT_EQ(f.path().filename().string().rfind(".plot_report-", 0), std::string::npos)
        << f.path();
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
