// Coarse-to-fine LoG correlation of a rectified image pair (doc/design.md,
// "Coarse-to-fine LoG correlation for surface models").
//
// Input: two epipolar-rectified images (rows are epipolar lines, y-parallax
// zero). Output: a grid of x-parallaxes (disparities)
//     d = x_left - x_right   [px of the full-resolution rectified image]
// at the nodes of a regular grid on the left image, with a validity flag and
// the correlation score.
//
// Per level k = 0 (coarsest) .. levels-1 (full resolution):
//   1. both images are resampled by s_k = 2^(levels-1-k) (area average: 4, 2, 1
//      for three levels) and band-passed by the scale-normalised LoG of
//      matching/filters.h with its peak at omega = 1 rad/pixel OF THE LEVEL,
//      i.e. 1/4, 1/2 and 1 rad/pixel of the full-resolution image;
//   2. the right image is warped by the parallax predicted by the previous
//      level (nearest integer, per pixel), and the zero-mean normalised cross
//      correlation (ZNCC) of window x window pixels is computed for every
//      offset in [-search_radius, +search_radius] (box filters: the cost per
//      pixel does not depend on the window). At the coarsest level the
//      prediction is absent and the search covers [min_disparity,
//      max_disparity] / s_0 instead;
//   3. the best offset per node is refined to sub-pixel by a parabola through
//      the three ZNCC values around the maximum; nodes whose best ZNCC is
//      below min_correlation or that have the maximum at the border of the
//      search are invalid;
//   4. the same is done right -> left, giving a second parallax grid on the
//      right image (full_right_search = true: a second search with the
//      right image's own prediction; false: each right pixel takes its
//      best-scoring left candidate of step 2's correlation volume, at half
//      the cost); where edge_window > 0, pixels whose window spans a depth
//      edge of the prediction are correlated with that smaller window in
//      step 2;
//   5. each grid gets a 3 x 3 median filter (valid nodes only) and an
//      order-consistency check per line: along a line the matched position
//      x - d must not decrease (d(i+1) - d(i) <= node spacing + order_tolerance);
//      both nodes of a violating pair are invalidated;
//   6. the two searches are averaged: a left node with parallax dL looks up
//      the right search at x - dL (linear along the line); if both exist and
//      agree within lr_tolerance px the node gets (dL + dR) / 2, else it is
//      invalid (occlusion, no texture, mismatch);
//   7. the grid density doubles at the next level (the node spacing in level
//      pixels stays grid_spacing, the levels are twice as large), and the
//      averaged grid, holes interpolated FOR THE PREDICTION ONLY, predicts the
//      next level's parallaxes.
// The final level may use a denser grid (final_grid_spacing, e.g. 1 for a
// per-pixel parallax map). Invalid nodes of the final level stay invalid:
// holes are never filled in the output.
#pragma once

#include <string>

#include <opencv2/core.hpp>

namespace slope_monitor {
namespace dense {

struct CorrelationOptions {
  int levels = 3;               // [-] pyramid levels, resampling 2^(levels-1) ... 1; [1, 5]
  double peak_frequency = 1.0;  // [rad/level-pixel] LoG peak at every level; (0, 3]
  int grid_spacing = 8;         // [level px] node spacing on levels 0 .. levels-2; [1, 64]
  int final_grid_spacing = 8;   // [px] node spacing on the full-resolution level; [1, 64]
  int window = 15;              // [px] correlation window (odd) of levels 0 .. levels-2; [3, 51]
  int final_window = 0;   // [px] window of the full-resolution level (odd, [3, 51]); 0: `window`
  int search_radius = 3;  // [level px] search around the prediction; [1, 16]
  int final_search_radius =
      0;  // [px] search of the full-resolution level; [1, 16]; 0: search_radius
  double min_disparity = 0.0;    // [px, full resolution] search range of the coarsest level
  double max_disparity = 64.0;   // [px, full resolution]; > min_disparity
  double min_correlation = 0.3;  // [-] ZNCC below this: invalid; [-1, 1)
  double lr_tolerance = 1.0;     // [px, full resolution] left/right agreement; > 0
  double order_tolerance = 0.5;  // [level px] slack of the order-consistency check; >= 0
  bool median_filter = true;     // 3 x 3 median of parallaxes
  bool order_check = true;       // order-consistency per line
  bool two_way = true;           // left->right and right->left; false: left->right only
  // The right->left matches from a second ZNCC search over the right image
  // (true), or from the left search's correlation volume (false: each right
  // pixel takes its best-scoring left candidate; the same window pairs up to
  // the per-pixel prediction, at half the cost).
  bool full_right_search = true;
  // Least-squares refinement of each final parallax (0: off, parabola only):
  // Gauss-Newton iterations of  l(x) = a + b r(x - d)  over the final window
  // (shift d, gain b, offset a; r linear along the line); a node whose
  // refinement moves by more than 1 px or does not converge keeps the
  // parabola value. [0, 20]
  int lsc_iterations = 0;
  // Edge-aware window: on levels with a prediction, pixels whose window spans
  // predicted parallaxes differing by more than edge_parallax_step [level
  // px] (a depth edge of the coarser level) are correlated with the smaller
  // edge_window instead (less fattening of foreground objects); 0: off.
  // Odd, [3, 51].
  int edge_window = 0;
  double edge_parallax_step = 2.0;  // [level px] > 0
  // Throws ConfigError naming the first bad field.
  void Check() const;
};

struct CorrelationSummary {
  int levels = 0;
  int nodes = 0;        // final-level nodes
  int valid_nodes = 0;  // final-level nodes with a parallax
  int rejected_correlation = 0;
  int rejected_order = 0;
  int rejected_left_right = 0;
  double seconds = 0.0;
  double ValidFraction() const {
    return nodes > 0 ? static_cast<double>(valid_nodes) / nodes : 0.0;
  }
  bool IsSolutionUsable() const { return valid_nodes > 0; }
  std::string BriefReport() const;
};

// The parallax grid on the left rectified image. Node (i, j) sits at pixel
// (x, y) = (j * spacing, i * spacing) of the full-resolution left image.
struct ParallaxGrid {
  int spacing = 1;      // [px]
  cv::Mat disparity;    // CV_32F, d = x_left - x_right [px]; NaN where invalid
  cv::Mat correlation;  // CV_32F, ZNCC of the final level (NaN where invalid)
  bool Valid(int i, int j) const { return disparity.at<float>(i, j) == disparity.at<float>(i, j); }
};

// Matches a rectified pair (single channel, same size, any depth filters.h
// accepts). `valid_left` / `valid_right` (CV_8U, optional) mark pixels that
// carry image content (rectification leaves black borders); correlation
// windows touching invalid pixels are rejected. Throws InvalidArgument when
// the images are empty, of different size, smaller than the coarsest level
// needs, or carry no texture (all black / constant: the LoG is zero).
ParallaxGrid MatchRectified(const cv::Mat& left, const cv::Mat& right,
                            const CorrelationOptions& options,
                            CorrelationSummary* summary = nullptr,
                            const cv::Mat& valid_left = cv::Mat(),
                            const cv::Mat& valid_right = cv::Mat());

// A copy of a per-pixel parallax map (spacing 1) with the holes of each
// line filled from the BACKGROUND side: a run of missing pixels takes the
// smaller parallax (the farther surface) of its two valid ends (the only one
// at the image border); runs longer than max_gap px stay missing. For a
// disparity map to display or score like other stereo methods (occlusions
// next to a foreground object show the background); never used for the
// surface model, whose holes stay nodata. `filled` (optional): CV_8U, 255
// where a value was filled.
cv::Mat FillFromBackground(const cv::Mat& disparity, int max_gap, cv::Mat* filled = nullptr);
// The same in place.
void FillFromBackgroundInPlace(cv::Mat* disparity, int max_gap, cv::Mat* filled = nullptr);

}  // namespace dense
}  // namespace slope_monitor
