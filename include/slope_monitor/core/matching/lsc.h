// Least-squares correlation (LSC) of a window of image a to image b, and the
// modified LSC (MLSC) that first correlates to the nearest pixel (doc/design.md).
//
// Model. Window coordinates (u, v) are integer offsets from the point
// (xa, ya) in image a, |u|, |v| <= half_window. The window maps into b by
//   eq. 1 (affine):  X = xb + (1 + a1) u + a2 v,   Y = yb + a4 u + (1 + a5) v
//   eq. 2 (shift):   X = xb + u,                   Y = yb + v
// (the published a3, a6 are the shift xb, yb; a1, a5 are stored relative to
// 1 so that zero is the identity). Radiometry: A(u, v) = g * B(X, Y) + o,
// o the intensity offset (always estimated: removing the local means), g the
// gain (estimated when Options::estimate_gain, else 1).
//
// Solved by Gauss-Newton on the residuals r = g B(X, Y) + o - A(u, v) with B
// read from the interpolant (bilinear or bicubic, see filters.h). The image
// gradient of the Jacobian is the template's (central differences of window
// a mapped into b by the affine part, Options::gradient kTemplate), or b's
// interpolant derivative (kResampled). Eq. 1 starts from the converged eq. 2
// solution; its four affine parameters are kept only when their F statistic
// against eq. 2, ((SSR2 - SSR1) / 4) / (SSR1 / (n - m)), reaches
// Options::affine_min_f, else the eq. 2 solution is returned
// (Summary::affine_used). Parameter vector, in order:
//   [0] xb, [1] yb [px];  affine only: [2] a1, [3] a2, [4] a4, [5] a5 [-];
//   then gain g [-] (if estimated), then offset o [grey].
//
// Precision. With n window pixels and m parameters,
//   s0^2 = sum r^2 / (n - m),   Cov = s0^2 (J^T J)^-1,
// and Summary::covariance is the 2 x 2 block of (xb, yb) [px^2]; it grows
// with noise and shrinks with gradient energy in the window.
//
// Convergence and blunder criteria (Summary::status):
//   kConverged           |step in xb, yb| < convergence_shift and affine step
//                        < convergence_affine
//   kNotConverged        max_iterations reached
//   kOutside             the window in a or its image in b leaves the image
//   kTextureless         gradient energy of window a below min_gradient_energy,
//                        its structure tensor eigenvalue ratio below
//                        min_eigen_ratio (a straight edge), or the normal
//                        matrix is singular/ill-conditioned
//   kDiverged            the solution moved more than max_shift from the start,
//                        or |a1|, |a2|, |a4|, |a5| > max_affine, or gain outside
//                        [1/max_gain_ratio, max_gain_ratio]
//   kLowCorrelation      NCC at the solution < min_correlation
//   kImprecise           sqrt of the larger covariance eigenvalue > max_sigma
//   kIllConditioned      eq. 1 kept the affine terms but the shift is not
//                        separable from them: the largest |correlation|
//                        between xb or yb and a1, a2, a4, a5 (from
//                        (J^T J)^-1) exceeds max_shift_affine_correlation
//                        (a straight edge with a corner near the window
//                        border: shift trades against scale/shear)
// Only kConverged is usable (Summary::IsSolutionUsable()).
#pragma once

#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace matching {

enum class LscModel {
  kAffine,  // "affine": eq. 1
  kShift,   // "shift": eq. 2
};
LscModel LscModelFromName(const std::string& name);  // throws InvalidArgument
const char* LscModelName(LscModel model);

// Where the image gradient of the Jacobian comes from.
enum class LscGradient {
  // "template": central differences of window a, mapped into b by the affine
  // part (default). Uncorrelated with the residual noise: unbiased.
  kTemplate,
  // "resampled": derivative of b's interpolant at the current position (the
  // textbook Gauss-Newton). Its noise is correlated with the interpolated
  // noise of b, which pulls the solution towards sub-pixel positions where
  // the interpolant smooths the noise most (measured: affine eq. 1 error RMS
  // 0.07-0.14 px instead of <= 0.05 px, see doc/nodes/hex_matcher.md).
  kResampled,
};
LscGradient LscGradientFromName(const std::string& name);  // throws InvalidArgument
const char* LscGradientName(LscGradient gradient);

struct LscOptions {
  LscModel model = LscModel::kAffine;
  Interpolation interpolation = Interpolation::kBicubic;
  LscGradient gradient = LscGradient::kTemplate;
  int half_window = 5;               // [px] window is (2 h + 1)^2; h in [1, 50]
  bool estimate_gain = false;        // radiometric gain besides the offset
  int max_iterations = 30;           // [1, 1000]
  double convergence_shift = 1e-3;   // [px] > 0
  double convergence_affine = 1e-4;  // [-] > 0
  double max_shift = 6.0;            // [px] > 0, from the start position
  double max_affine = 0.5;           // [-] > 0
  // Eq. 1: smallest F statistic of the four affine parameters against the
  // eq. 2 fit of the same window to keep them, >= 0; below it the eq. 2
  // solution is returned (Summary::affine_used false). 0 = always eq. 1.
  // 2.45 is the 95 % quantile of F(4, 100) (11 x 11 window).
  double affine_min_f = 2.45;
  double max_gain_ratio = 3.0;       // [-] > 1
  double min_correlation = 0.7;      // [-1, 1]
  double min_gradient_energy = 1.0;  // [grey^2/px^2] mean squared gradient in window a, >= 0
  double max_sigma = 0.5;            // [px] > 0
  // Eq. 1 quality control, (0, 1]: largest |correlation| between a shift
  // parameter and an affine one in (J^T J)^-1 when the affine terms are
  // kept; above it the match is kIllConditioned. 1 = off.
  double max_shift_affine_correlation = 1.0;
  // Eq. 1 falling back to eq. 2 (F test): check max_sigma on the eq. 1
  // covariance of the shift (the affine terms were not determined, which
  // does not show they are zero). The reported covariance stays eq. 2's.
  bool fallback_affine_precision = false;
  // Smaller / larger eigenvalue of window a's structure tensor, [0, 1):
  // below it the window holds a single straight edge (aperture problem, the
  // shift along the edge is set by noise only) -> kTextureless.
  double min_eigen_ratio = 0.1;
  // Modified LSC: integer NCC search radius around the start [px], >= 0;
  // 0 = plain LSC from the start position.
  int search_radius = 0;
  // Half window of that integer search [px]; 0 = half_window. A small LSC
  // window (5 x 5) is refined from an 11 x 11 search (search_half_window 5).
  int search_half_window = 0;
  // Vertical search radius [px]; -1 = search_radius (square search). A
  // rectified pair searches along the row: search_radius_y 1.
  int search_radius_y = -1;

  // Throws ConfigError naming the field when a value is out of range.
  void Check() const;
};

struct LscSummary {
  enum class Status {
    kConverged,
    kNotConverged,
    kOutside,
    kTextureless,
    kDiverged,
    kLowCorrelation,
    kImprecise,
    kIllConditioned,
  };
  Status status = Status::kNotConverged;
  Eigen::Vector2d xb = Eigen::Vector2d::Zero();  // [px] matched position in b
  // Affine part [a1, a2, a4, a5] (zero for eq. 2).
  Eigen::Vector4d affine = Eigen::Vector4d::Zero();
  Eigen::Vector4d affine_sigma = Eigen::Vector4d::Zero();  // [-] their standard deviations (eq. 1)
  bool affine_used = false;  // eq. 1 kept (false for eq. 2 and when the F test fell back to it)
  double affine_f = 0.0;     // F statistic of the affine parameters (eq. 1)
  // Largest |correlation| of xb or yb with an affine parameter (eq. 1 with
  // the affine terms kept; 0 otherwise).
  double shift_affine_correlation = 0.0;
  // |xb of eq. 1 - xb of the eq. 2 solution of the same window| [px] (eq. 1
  // with the affine terms kept; 0 otherwise).
  double model_difference = 0.0;
  double gain = 1.0;
  double offset = 0.0;
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2] of xb
  double sigma0 = 0.0;       // [grey] residual RMS (a posteriori unit weight)
  double correlation = 0.0;  // NCC of window a and the resampled window of b
  int iterations = 0;
  // Start position after the integer correlation search (MLSC), [px].
  Eigen::Vector2d start = Eigen::Vector2d::Zero();

  bool IsSolutionUsable() const { return status == Status::kConverged; }
};
const char* LscStatusName(LscSummary::Status status);

// Plain LSC (or MLSC if options.search_radius > 0) of the window around
// xa in image a, starting at xb_start in b. Images must be CV_32F single
// channel (use ToFloat); the window may be any size up to the image. Throws
// InvalidArgument only for wrong image types; all data problems are
// reported in the Summary status.
LscSummary MatchLsc(const cv::Mat& image_a, const cv::Mat& image_b, const Eigen::Vector2d& xa,
                    const Eigen::Vector2d& xb_start, const LscOptions& options);

// Integer-pixel NCC search of the (2 h + 1)^2 window around the rounded xa
// over positions within +-radius of the rounded xb_start; returns the best
// position (integer) and its NCC in *ncc (-2 if no position was inside).
// radius_y < 0 means radius_y = radius.
Eigen::Vector2d CorrelateInteger(const cv::Mat& image_a, const cv::Mat& image_b,
                                 const Eigen::Vector2d& xa, const Eigen::Vector2d& xb_start,
                                 int half_window, int radius, double* ncc, int radius_y = -1);

}  // namespace matching
}  // namespace slope_monitor
