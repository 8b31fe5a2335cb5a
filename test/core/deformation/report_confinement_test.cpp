// Reports stay inside their folder and survive hostile point ids (issue 22):
// a requested subfolder that leaves the report folder is refused with the
// reason and nothing is written outside; a link planted at the old
// predictable temporary name is never opened; a history holding a 250
// character point id still yields every report file.
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/report.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

namespace fs = std::filesystem;
using testing::kDay;
using testing::kT0;

class ReportConfinementTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() /
            ("sm_report_confinement_" + std::to_string(getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(base_);
    fs::create_directories(base_ / "outside");
    root_ = (base_ / "reports").string();
  }
  void TearDown() override { fs::remove_all(base_); }

  // Two points moving 10 mm/day for a day, with the given ids.
  static void Fill(Estimator* e, const std::vector<std::string>& ids) {
    std::vector<testing::Motion> motions(ids.size());
    for (auto& m : motions) m.v0 = 10e-3 / kDay;
    testing::SourceSpec radio;
    radio.interval = 3600.0;
    for (const Batch& b : testing::MakeBatches(radio, ids, motions, kT0 + kDay)) e->AddBatch(b);
  }
  size_t EntriesOutside() {
    size_t n = 0;
    for (auto it = fs::recursive_directory_iterator(base_ / "outside");
         it != fs::recursive_directory_iterator(); ++it)
      ++n;
    return n;
  }
  std::string Refusal(const Estimator& e, const std::string& subfolder) {
    try {
      WriteReports(e, root_, subfolder, {"csv"}, ReportOptions());
    } catch (const InvalidArgument& ex) {
      return ex.what();
    }
    return "";
  }

  fs::path base_;
  std::string root_;
};

TEST_F(ReportConfinementTest, RequestsThatLeaveTheFolderAreRefused) {
  Estimator e{EstimatorOptions()};
  Fill(&e, {"rock", "tag36h11/1"});
  fs::create_directories(root_);
  fs::create_directory_symlink(base_ / "outside", fs::path(root_) / "link");
  EXPECT_NE(Refusal(e, "../outside").find("'..'"), std::string::npos);
  EXPECT_NE(Refusal(e, "../../etc/x").find("'..'"), std::string::npos);
  EXPECT_NE(Refusal(e, (base_ / "outside").string()).find("absolute path"), std::string::npos);
  EXPECT_NE(Refusal(e, "link").find("symbolic link"), std::string::npos);
  EXPECT_NE(Refusal(e, "two\nlines").find("control character"), std::string::npos);
  EXPECT_EQ(EntriesOutside(), 0u);
  // A plain subfolder works and is where the files land.
  const auto files = WriteReports(e, root_, "after_typhoon", {"csv"}, ReportOptions());
  ASSERT_EQ(files.size(), 1u);
  EXPECT_EQ(files[0], fs::canonical(root_).string() + "/after_typhoon/deformation.csv");
}

TEST_F(ReportConfinementTest, PlantedLinkAtTheTemporaryNameIsNotFollowed) {
  Estimator e{EstimatorOptions()};
  Fill(&e, {"rock", "tag36h11/1"});
  fs::create_directories(root_);
  const fs::path victim = base_ / "outside" / "victim.txt";
  std::ofstream(victim) << "precious";
  const std::string pid = std::to_string(getpid());
  const std::vector<std::string> planted = {
      "deformation.csv.tmp-" + pid, "deformation.geojson.tmp-" + pid,
      "deformation_map.png.tmp-" + pid + ".png", "deformation.csv"};
  for (const std::string& name : planted) fs::create_symlink(victim, fs::path(root_) / name);
  ReportOptions georeferenced;  // GeoJSON (WGS 84) needs one
  georeferenced.geodetic_origin = Eigen::Vector3d(35.0, 139.0, 100.0);
  const auto files = WriteReports(e, root_, "", {"csv", "geojson", "png"}, georeferenced);
  EXPECT_EQ(files.size(), 6u);  // csv, geojson of the points and of the areas, map, 2 series
  std::ifstream in(victim);
  std::stringstream content;
  content << in.rdbuf();
  EXPECT_EQ(content.str(), "precious");
  for (const std::string& f : files) EXPECT_FALSE(fs::is_symlink(f)) << f;
}

TEST_F(ReportConfinementTest, LongPointIdDoesNotBreakReports) {
  Estimator e{EstimatorOptions()};
  const std::string long_id(250, 'L');
  Fill(&e, {"rock", long_id});
  ReportOptions georeferenced;
  georeferenced.geodetic_origin = Eigen::Vector3d(35.0, 139.0, 100.0);
  const auto files = WriteReports(e, root_, "", {}, georeferenced);
  // csv, geojson of the points and of the areas, tif, gpkg, map, one series per point.
  ASSERT_EQ(files.size(), 8u);
  // Without a georeference no GeoJSON (RFC 7946 is WGS 84): csv, tif, gpkg, map, 2 series.
  EXPECT_EQ(WriteReports(e, root_, "", {}, ReportOptions()).size(), 6u);
  for (const std::string& f : files) {
    EXPECT_TRUE(fs::exists(f)) << f;
    EXPECT_LE(fs::path(f).filename().string().size(), 100u) << f;
  }
  // A second export works as well (the defect broke every later one).
  EXPECT_EQ(WriteReports(e, root_, "", {"png"}, ReportOptions()).size(), 3u);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
