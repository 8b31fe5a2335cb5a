// Interest points by the modified-LSC rule (doc/design.md):
//   1. LoG filter (sigma = 2 by default, scale-normalised, filters.h);
//   2. its zero-crossings are the edges (thin, 8-connected; weak crossings
//      below zero_crossing_contrast * RMS(LoG) are dropped);
//   3. corner rule on each edge pixel O with k edge pixels among its 8
//      neighbours: k >= 3 -> corner; k == 2 -> with A, B the two neighbours,
//      corner when the angle AOB <= max_corner_angle (135 deg: a straight
//      edge, AOB = 180 deg, is not a corner); k <= 1 -> not a corner;
//   4. around each corner the pixel of maximum Sobel gradient magnitude in a
//      gradient_window x gradient_window (11 x 11) neighbourhood is the point;
//   5. points closer than min_distance to a stronger point, weaker than
//      min_gradient or within `border` of the image edge are dropped, and at
//      most max_points (the strongest) are kept.
// Positions are integer pixels (OpenCV convention); LSC refines them.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace slope_monitor {
namespace matching {

struct InterestPointOptions {
  double log_sigma = 2.0;               // [px] > 0
  double zero_crossing_contrast = 0.5;  // [-] x RMS of the LoG image, >= 0
  double max_corner_angle_deg = 135.0;  // [deg] (0, 180)
  int gradient_window = 11;             // [px] odd, [3, 51]
  double min_gradient = 4.0;            // [grey/px] Sobel magnitude, >= 0
  int min_distance = 5;                 // [px] >= 1
  int max_points = 2000;                // >= 1
  // [0, 100]; > 0: the image is cut into cells x cells and each keeps at most
  // max_points / cells^2 (rounded up) before the rest are filled by
  // strength, so the points cover the image instead of its most contrasted
  // part (a real photo's 1000 strongest left 16 in the overlap of a turn pair).
  int cells = 0;
  int border = 8;      // [px] >= 0
  void Check() const;  // throws ConfigError naming the field
};

struct InterestPoint {
  Eigen::Vector2d x = Eigen::Vector2d::Zero();  // [px] column, row
  double strength = 0.0;                        // [grey/px] Sobel magnitude
};

// Corner test of the rule above on an edge mask (CV_8U, non-zero = edge) at
// (col, row). Exposed for tests.
bool IsEdgeCorner(const cv::Mat& edges, int col, int row, double max_corner_angle_deg);

// Detects interest points in a single-channel image (8U/16U/32F/64F).
// Throws InvalidArgument for an empty or multi-channel image. A textureless
// image gives no points.
std::vector<InterestPoint> DetectInterestPoints(const cv::Mat& image,
                                                const InterestPointOptions& options);

}  // namespace matching
}  // namespace slope_monitor
