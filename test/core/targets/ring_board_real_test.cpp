// The centroider with the defaults a user gets (circle_design auto) on a
// real photograph of a ring-marker board (test/data/targets_real_rings/,
// ringgrid's test image, provenance in test/data/README.md): dark coded
// rings with a light centre on a hex lattice, blur across the depth of
// field, perspective and a strong barrel distortion.
//
// Counted by eye (the photo and the centroider's annotated output viewed at
// 2x, row by row): the two sharpest lattice rows (image y ~ 290 and ~ 340,
// edge blur sigma 0.56-0.93 px) hold 12 + 12 = 24 fully visible markers
// (12 from x ~ 31 to 656 on the first; 12 from x ~ 56 to 688 on the
// second, whose last one is at low contrast in the vignetted corner); the
// markers cut by the left and right image borders are not counted.
// Every one of them must be measured exactly once (no two circles closer
// than the marker radius), as design concentric (the code band shows light
// inside the outer ring), and every measured circle must sit on a lattice
// point of the board (board_ringgrid.json) fitted with a homography and a
// radial distortion: RMS <= 0.1 px over the sharp rows. The blurred rows
// above and below are rejected with a reason (blurred, residual, partial)
// or measured; none of those is counted twice either.
#include <cstdio>
#include <fstream>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/targets/board_layout.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

const std::string kRingDir = std::string(SM_TEST_DATA_DIR) + "/targets_real_rings/";
constexpr int kSharpRowMarkers = 24;  // counted by eye, see above
constexpr double kSharpBlur = 1.0;    // [px] edge blur sigma of the sharp rows' markers
constexpr double kSharpRmsPx = 0.1;   // [px] lattice fit RMS goal where sharp

TEST(RingBoardReal, DefaultsFindEveryMarkerOfTheSharpRowsOnceOnTheLattice) {
  const cv::Mat img = cv::imread(kRingDir + "target_3_split_00.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(img.empty());
  const TargetCentroider c{Options(), io::TargetList()};
  const Result r = c.Detect(img, img.channels() == 3 ? "bgr8" : "mono8");
  EXPECT_EQ(r.summary.num_tags, 0);
  std::vector<Eigen::Vector2d> centres;
  std::vector<double> outer;
  for (const auto& o : r.observations) {
    ASSERT_EQ(o.family, "circle");
    centres.push_back(o.centre);
    outer.push_back(o.size_px * std::max(o.ring_ratio, 1.0));
  }
  // One target per marker: no two measured or rejected circles within a
  // marker radius (~20 px) of each other.
  std::vector<Eigen::Vector2d> all = centres;
  for (const auto& rj : r.rejections) all.push_back(rj.where);
  for (size_t a = 0; a < all.size(); ++a)
    for (size_t b = a + 1; b < all.size(); ++b)
      EXPECT_GT((all[a] - all[b]).norm(), 20.0)
          << all[a].transpose() << " / " << all[b].transpose();
  const BoardLayout layout = BoardLayout::Load(kRingDir + "board_ringgrid.json");
  const LatticeFit fit = FitLattice(centres, outer, layout, img.cols, img.rows);
  ASSERT_TRUE(fit.ok) << fit.message;
  EXPECT_TRUE(fit.off_lattice.empty()) << fit.off_lattice.size() << " circles off the board";
  EXPECT_EQ(fit.markers.size(), centres.size());
  EXPECT_LE(fit.rows_seen, layout.rows);
  // The layout's marker radii (9.6 mm across on an 8 mm pitch: markers that
  // would overlap) are not those of the photographed board: a note.
  EXPECT_FALSE(fit.warning.empty());
  int sharp = 0, concentric = 0;
  double ss_sharp = 0, ss_all = 0;
  for (const auto& m : fit.markers) {
    const Observation& o = r.observations[m.observation];
    ss_all += m.residual.squaredNorm();
    if (o.edge_blur <= kSharpBlur) {
      ++sharp;
      ss_sharp += m.residual.squaredNorm();
      concentric += o.design == CircleDesign::kConcentric;
    }
  }
  const double rms_sharp = std::sqrt(ss_sharp / std::max(sharp, 1));
  std::printf(
      "ring board: %d circles, %zu rejected, %zu discarded; lattice %zu markers, %d rows x %d "
      "cols, RMS %.4f px (homography alone %.3f px), k1 %.4f; sharp (blur <= %.1f px) %d, RMS "
      "%.4f px; all %.4f px\n",
      r.summary.num_circles, r.rejections.size(), r.discarded.size(), fit.markers.size(),
      fit.rows_seen, fit.cols_seen, fit.rms_px, fit.rms_homography_px, fit.k1, kSharpBlur, sharp,
      rms_sharp, std::sqrt(ss_all / std::max<size_t>(fit.markers.size(), 1)));
  // The two sharp rows are the lattice rows 1 and 2 of the fit (row 0 is the
  // row at y ~ 250, partly blurred).
  int sharp_rows = 0;
  for (const auto& m : fit.markers) sharp_rows += m.row == 1 || m.row == 2;
  EXPECT_EQ(sharp_rows, kSharpRowMarkers);
  EXPECT_EQ(concentric, sharp);
  EXPECT_LE(rms_sharp, kSharpRmsPx);
  EXPECT_LE(fit.rms_px, 0.12);
}

TEST(RingBoardReal, WrongLatticeIsNamed) {
  const cv::Mat img = cv::imread(kRingDir + "target_3_split_00.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(img.empty());
  const TargetCentroider c{Options(), io::TargetList()};
  const Result r = c.Detect(img, "mono8");
  std::vector<Eigen::Vector2d> centres;
  for (const auto& o : r.observations) centres.push_back(o.centre);
  BoardLayout square;
  square.kind = BoardLayout::Kind::kSquare;
  square.pitch = 8.0;
  square.source = "square.yaml";
  const LatticeFit fit = FitLattice(centres, {}, square, img.cols, img.rows);
  EXPECT_FALSE(fit.ok);
  EXPECT_NE(fit.message.find("does not fit"), std::string::npos) << fit.message;
  std::printf("square layout on the hex board: %s\n", fit.message.c_str());
}

// Our own YAML layout; a wrong pitch is seen against the marker size (the
// homography absorbs the scale): measured 0.79 pitch across, so a board of
// 6.3 mm markers on an 8 mm pitch fits without a note, the same markers on
// a 12 mm pitch get one naming the pitch. A photo without markers, and a
// bad key, are named.
TEST(RingBoardReal, YamlLayoutAndWrongPitch) {
  const cv::Mat img = cv::imread(kRingDir + "target_3_split_00.png", cv::IMREAD_UNCHANGED);
  ASSERT_FALSE(img.empty());
  const TargetCentroider c{Options(), io::TargetList()};
  const Result r = c.Detect(img, "mono8");
  std::vector<Eigen::Vector2d> centres;
  std::vector<double> outer;
  for (const auto& o : r.observations) {
    centres.push_back(o.centre);
    outer.push_back(o.size_px * std::max(o.ring_ratio, 1.0));
  }
  const std::string dir = ::testing::TempDir();
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir + name) << text;
    return dir + name;
  };
  const BoardLayout right = BoardLayout::Load(write(
      "ring_right.yaml", "lattice: hex\npitch: 8.0\nrows: 15\ncols: 14\nmarker_diameter: 6.3\n"));
  const LatticeFit ok = FitLattice(centres, outer, right, img.cols, img.rows);
  ASSERT_TRUE(ok.ok) << ok.message;
  EXPECT_TRUE(ok.warning.empty()) << ok.warning;
  const BoardLayout wrong = BoardLayout::Load(
      write("ring_wrong.yaml", "lattice: hex\npitch: 12.0\nmarker_diameter: 6.3\n"));
  const LatticeFit bad = FitLattice(centres, outer, wrong, img.cols, img.rows);
  EXPECT_NE(bad.warning.find("pitch"), std::string::npos) << bad.warning;
  std::printf("wrong pitch: %s\n", bad.warning.c_str());
  const LatticeFit none = FitLattice({}, {}, right, img.cols, img.rows);
  EXPECT_FALSE(none.ok);
  EXPECT_NE(none.message.find("0 circles"), std::string::npos) << none.message;
  EXPECT_THROW(BoardLayout::Load(write("ring_typo.yaml", "lattice: hex\npitch: 8\npich: 8\n")),
               Error);
  EXPECT_THROW(BoardLayout::Load(write("ring_kind.yaml", "lattice: hexagon\npitch: 8\n")), Error);
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
