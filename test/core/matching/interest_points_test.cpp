// The MLSC corner rule on hand-drawn edge masks, and detection on simple
// images whose corners are known.
#include "slope_monitor/core/matching/interest_points.h"

#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace matching {
namespace {

TEST(InterestPoints, CornerRuleOnEdgeMasks) {
  cv::Mat e(9, 9, CV_8U, cv::Scalar(0));
  // Straight horizontal edge: A, B opposite (180 deg) -> not a corner.
  e.row(4).setTo(255);
  EXPECT_FALSE(IsEdgeCorner(e, 4, 4, 135.0));
  // Straight diagonal: not a corner either.
  cv::Mat d(9, 9, CV_8U, cv::Scalar(0));
  for (int i = 0; i < 9; ++i) d.at<uint8_t>(i, i) = 255;
  EXPECT_FALSE(IsEdgeCorner(d, 4, 4, 135.0));
  // A bend of 135 deg (right, then down-left) is a corner; 90 deg too.
  cv::Mat b(9, 9, CV_8U, cv::Scalar(0));
  b.at<uint8_t>(4, 4) = b.at<uint8_t>(4, 5) = b.at<uint8_t>(5, 3) = 255;
  EXPECT_TRUE(IsEdgeCorner(b, 4, 4, 135.0));
  EXPECT_FALSE(IsEdgeCorner(b, 4, 4, 120.0));  // 135 > 120
  // Three edge neighbours (a junction) -> corner.
  cv::Mat t = e.clone();
  t.at<uint8_t>(5, 4) = 255;
  EXPECT_TRUE(IsEdgeCorner(t, 4, 4, 135.0));
  // An end point (one neighbour) is not.
  cv::Mat one(9, 9, CV_8U, cv::Scalar(0));
  one.at<uint8_t>(4, 4) = one.at<uint8_t>(4, 5) = 255;
  EXPECT_FALSE(IsEdgeCorner(one, 4, 4, 135.0));
}

TEST(InterestPoints, RectangleCornersAreFound) {
  cv::Mat img(100, 120, CV_8U, cv::Scalar(40));
  cv::rectangle(img, cv::Rect(30, 25, 50, 40), cv::Scalar(200), cv::FILLED);
  InterestPointOptions o;
  const auto pts = DetectInterestPoints(img, o);
  ASSERT_FALSE(pts.empty());
  // Every point lies near the rectangle's outline.
  for (const auto& p : pts) {
    const double dx = std::min(std::fabs(p.x.x() - 29.5), std::fabs(p.x.x() - 79.5));
    const double dy = std::min(std::fabs(p.x.y() - 24.5), std::fabs(p.x.y() - 64.5));
    EXPECT_LT(std::min(dx, dy), 2.0) << p.x.transpose();
  }
  // Each of the four corners has a point within 6 px.
  for (const cv::Point2d c : {cv::Point2d(29.5, 24.5), cv::Point2d(79.5, 24.5),
                              cv::Point2d(29.5, 64.5), cv::Point2d(79.5, 64.5)}) {
    double best = 1e9;
    for (const auto& p : pts) best = std::min(best, std::hypot(p.x.x() - c.x, p.x.y() - c.y));
    EXPECT_LT(best, 6.0) << c;
  }
}

// Squares of contrast 160 in the top-left quarter, of contrast 30 in the
// other three (each square gives corners). The 8 strongest all lie in the
// top-left; spread over 2 x 2 cells, each quarter keeps 2.
TEST(InterestPoints, CellsSpreadThePointsOverTheImage) {
  cv::Mat img(200, 200, CV_8U, cv::Scalar(60));
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      const bool strong = r < 2 && c < 2;
      cv::rectangle(img, cv::Rect(15 + 50 * c, 15 + 50 * r, 20, 20), cv::Scalar(strong ? 220 : 90),
                    cv::FILLED);
    }
  const auto quarter = [](const InterestPoint& p) {
    return (p.x.y() >= 100 ? 2 : 0) + (p.x.x() >= 100 ? 1 : 0);
  };
  InterestPointOptions o;
  o.max_points = 8;
  std::vector<int> count(4, 0);
  for (const InterestPoint& p : DetectInterestPoints(img, o)) ++count[quarter(p)];
  EXPECT_EQ(count, (std::vector<int>{8, 0, 0, 0}));
  o.cells = 2;
  const auto spread = DetectInterestPoints(img, o);
  std::fill(count.begin(), count.end(), 0);
  for (const InterestPoint& p : spread) ++count[quarter(p)];
  EXPECT_EQ(count, (std::vector<int>{2, 2, 2, 2}));
  for (size_t k = 1; k < spread.size(); ++k) EXPECT_GE(spread[k - 1].strength, spread[k].strength);
  o.cells = 101;
  EXPECT_THROW(DetectInterestPoints(img, o), ConfigError);
}

TEST(InterestPoints, FlatImageHasNone) {
  EXPECT_TRUE(
      DetectInterestPoints(cv::Mat(50, 50, CV_8U, cv::Scalar(90)), InterestPointOptions()).empty());
  InterestPointOptions bad;
  bad.gradient_window = 10;
  EXPECT_THROW(bad.Check(), ConfigError);
  EXPECT_THROW(DetectInterestPoints(cv::Mat(), InterestPointOptions()), InvalidArgument);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
