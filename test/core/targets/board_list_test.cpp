// A board given as a list of marker positions (board_layout.h, lattice:
// list): 10 markers at irregular positions [mm] seen through a known
// perspective homography; the detections are the exact images, shuffled,
// one marker missing and two circles that are not on the board added. The
// fit must number every seen marker by its index in the list, leave the two
// strangers off the board and reproduce the images (residual < 1e-4 px). A
// list that is not this board (its y coordinates permuted) is named as not
// fitting.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "slope_monitor/core/targets/board_layout.h"

namespace slope_monitor {
namespace targets {
namespace {

const std::vector<Eigen::Vector2d>& ListPositions() {
  static const std::vector<Eigen::Vector2d> p = {{0, 0},   {35, 4},  {71, -3}, {112, 6}, {8, 41},
                                                 {52, 47}, {95, 38}, {20, 88}, {63, 95}, {118, 80}};
  return p;
}

// image = H board: a board about 120 mm wide seen obliquely, ~600 px across.
Eigen::Matrix3d ListHomography() {
  Eigen::Matrix3d h;
  h << 4.6, 0.9, 120.0, -0.4, 3.1, 90.0, 0.0011, 0.0024, 1.0;
  return h;
}

BoardLayout WriteAndLoad(const std::vector<Eigen::Vector2d>& positions, const std::string& name) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream f(path);
  f << "lattice: list\npositions: [";
  for (size_t k = 0; k < positions.size(); ++k)
    f << (k ? ", " : "") << "[" << positions[k].x() << ", " << positions[k].y() << "]";
  f << "]\n";
  f.close();
  BoardLayout b = BoardLayout::Load(path);
  std::remove(path.c_str());
  return b;
}

TEST(BoardList, ListedMarkersNumberedByTheirIndex) {
  const BoardLayout board = WriteAndLoad(ListPositions(), "sm_list_board.yaml");
  ASSERT_EQ(board.kind, BoardLayout::Kind::kList);
  const Eigen::Matrix3d h = ListHomography();
  std::vector<Eigen::Vector2d> centres;
  std::vector<int> truth;  // list index of each centre, -1 for a stranger
  for (size_t k = 0; k < ListPositions().size(); ++k) {
    if (k == 6) continue;  // not seen
    centres.push_back((h * ListPositions()[k].homogeneous()).hnormalized());
    truth.push_back(static_cast<int>(k));
  }
  centres.emplace_back(60.0, 500.0);  // two circles not on the board
  truth.push_back(-1);
  centres.emplace_back(700.0, 40.0);
  truth.push_back(-1);
  std::vector<int> order(centres.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = static_cast<int>(k);
  std::shuffle(order.begin(), order.end(), std::mt19937(3));
  std::vector<Eigen::Vector2d> shuffled;
  std::vector<int> shuffled_truth;
  for (int k : order) {
    shuffled.push_back(centres[k]);
    shuffled_truth.push_back(truth[k]);
  }
  const LatticeFit fit = FitLattice(shuffled, {}, board);
  ASSERT_TRUE(fit.ok) << fit.message;
  ASSERT_EQ(fit.markers.size(), 9u);
  for (const LatticeMarker& m : fit.markers) {
    EXPECT_EQ(m.id, shuffled_truth[m.observation]) << "centre " << m.observation;
    EXPECT_LT(m.residual.norm(), 1e-4) << "marker " << m.id;  // cv::findHomography's precision
    EXPECT_TRUE(m.inlier);
  }
  ASSERT_EQ(fit.off_lattice.size(), 2u);
  for (int k : fit.off_lattice) EXPECT_EQ(shuffled_truth[k], -1);
  EXPECT_LT(fit.rms_px, 1e-4);
  std::printf("list of 10, 9 seen + 2 strangers: %zu numbered, RMS %.2e px\n", fit.markers.size(),
              fit.rms_px);
}

TEST(BoardList, WrongListIsNamed) {
  // A different board: the same x, the y of another marker.
  std::vector<Eigen::Vector2d> other;
  const auto& p = ListPositions();
  for (size_t k = 0; k < p.size(); ++k) other.emplace_back(p[k].x(), p[(3 * k + 1) % p.size()].y());
  const BoardLayout board = WriteAndLoad(other, "sm_list_wrong.yaml");
  std::vector<Eigen::Vector2d> centres;
  for (const Eigen::Vector2d& p : ListPositions())
    centres.push_back((ListHomography() * p.homogeneous()).hnormalized());
  const LatticeFit fit = FitLattice(centres, {}, board);
  EXPECT_FALSE(fit.ok);
  EXPECT_NE(fit.message.find("does not fit"), std::string::npos) << fit.message;
  std::printf("wrong list: %s (%zu matched, RMS %.3f px)\n", fit.message.c_str(),
              fit.markers.size(), fit.rms_px);
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
