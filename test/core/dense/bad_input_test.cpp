// Bad pairs through the writing entry point (MeasureSurfaceToFiles, used by
// the dense_matcher nodelet and the dense_surface tool): each gives a clear
// InvalidArgument naming the image and the problem, and leaves the output
// directory empty (no surface, no orthophoto, no temporary file). A good pair
// writes both files.
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/surface.h"
#include "slope_monitor/core/io/geotiff.h"
#include "synthetic_scene.h"

namespace slope_monitor {
namespace dense {
namespace {

namespace fs = std::filesystem;

SurfaceOptions BadInputOptions() {
  SurfaceOptions o;
  o.correlation.final_grid_spacing = 4;
  return o;
}

SurfaceConfig BadInputConfig() {
  SurfaceConfig c;
  c.min_depth = 30.0;
  c.max_depth = 50.0;
  c.region = Eigen::Vector4d(10.0, 30.0, 6.0, 24.0);
  return c;
}

class BadInputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("dense_bad_input_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    if (!pair_) {  // rendered once for all tests
      static const test_scene::Scene scene;
      pair_ = new std::pair<OrientedImage, OrientedImage>(
          test_scene::MakeImage(scene, "left", 16.0, -2e-3),
          test_scene::MakeImage(scene, "right", 24.0, 0.0));
    }
    left_ = pair_->first;
    right_ = pair_->second;
  }
  static void TearDownTestSuite() {
    delete pair_;
    pair_ = nullptr;
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Stem() const { return (dir_ / "pair").string(); }
  std::vector<std::string> Files() const {
    std::vector<std::string> f;
    for (const auto& e : fs::directory_iterator(dir_)) f.push_back(e.path().filename().string());
    return f;
  }
  // Expects InvalidArgument whose message contains every one of `parts`, and no file.
  void ExpectRejected(const OrientedImage& l, const OrientedImage& r,
                      const std::vector<std::string>& parts) {
    try {
      MeasureSurfaceToFiles(l, r, BadInputOptions(), BadInputConfig(), Stem());
      ADD_FAILURE() << "no error";
    } catch (const InvalidArgument& e) {
      for (const std::string& p : parts)
        EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
    }
    EXPECT_TRUE(Files().empty()) << Files().front();
  }

  static std::pair<OrientedImage, OrientedImage>* pair_;
  OrientedImage left_, right_;
  fs::path dir_;
};
std::pair<OrientedImage, OrientedImage>* BadInputTest::pair_ = nullptr;

TEST_F(BadInputTest, GoodPairWritesSurfaceAndOrthophoto) {
  SurfaceSummary s;
  MeasureSurfaceToFiles(left_, right_, BadInputOptions(), BadInputConfig(), Stem(), &s);
  ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
  const io::GeoRaster model = io::ReadGeoTiff(Stem() + "_surface.tif");
  const io::GeoRaster ortho = io::ReadGeoTiff(Stem() + "_ortho.tif");
  EXPECT_EQ(model.width, 40);
  EXPECT_EQ(ortho.width, 40);
  EXPECT_EQ(Files().size(), 2u);
}

TEST_F(BadInputTest, UnorientedImage) {
  OrientedImage r = right_;
  r.oriented = false;
  ExpectRejected(left_, r, {"right", "not oriented"});
  OrientedImage l = left_;
  l.oriented = false;
  ExpectRejected(l, right_, {"left", "not oriented"});
}

TEST_F(BadInputTest, ZeroBaseline) {
  OrientedImage r = right_;
  r.pose = left_.pose;
  ExpectRejected(left_, r, {"baseline"});
}

TEST_F(BadInputTest, NoOverlap) {
  OrientedImage r = right_;
  r.pose.position.x() += 500.0;  // looks at ground 500 m away
  ExpectRejected(left_, r, {"do not overlap"});
}

TEST_F(BadInputTest, AllBlackImages) {
  OrientedImage black_r = right_;
  black_r.image = cv::Mat(right_.image.size(), CV_8U, cv::Scalar(0));
  ExpectRejected(left_, black_r, {"right", "no texture"});
  OrientedImage black_l = left_;
  black_l.image = cv::Mat(left_.image.size(), CV_8U, cv::Scalar(0));
  ExpectRejected(black_l, black_r, {"no texture"});
}

TEST_F(BadInputTest, UnwritableDirectoryLeavesNoFile) {
  // The stem's directory does not exist: IoError naming the file, nothing written.
  const std::string stem = (dir_ / "missing" / "pair").string();
  try {
    MeasureSurfaceToFiles(left_, right_, BadInputOptions(), BadInputConfig(), stem);
    ADD_FAILURE() << "no error";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("pair_surface.tif"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(Files().empty());
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
