// Least-squares correlation against truth:
//  * synthetic shifts / affine warps of real texture (Middlebury Cones left
//    image) with known sub-pixel truth and added noise: precision and the
//    convergence rate from +-5 px for MLSC vs plain LSC;
//  * the published LSC table on the real rectified Cones pair (true
//    y-parallax 0) and disparities against the ground-truth disparity;
//  * bad input.
#include "slope_monitor/core/matching/lsc.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/interest_points.h"

#include "cones_images.h"  // the Middlebury Cones pair (header only)

namespace slope_monitor {
namespace matching {
namespace {

using slope_monitor::testing::AddNoise;
using slope_monitor::testing::LoadCones;

struct WarpCase {
  cv::Mat a, b;
  cv::Matx23d m;  // xb = M [xa; 1]
};

// Image b = image a warped by M, both with independent Gaussian noise of
// sigma grey levels. The real texture is first band-limited like a camera's
// optics would (Gaussian sigma 0.7 px); the continuous scene is its bicubic
// interpolant, and both images integrate it over each pixel's area (4 x 4
// sub-samples, as a sensor pixel does), a at the identity and b through M.
// Point-sampling the scene instead leaves aliasing that is a truth error of
// its own (noise-free floor of eq. 1: 0.05 px point-sampled, 0.03 px
// integrated).
WarpCase MakeWarp(const cv::Matx23d& m, double noise, unsigned seed) {
  const cv::Mat left = GaussianBlur(ToFloat(LoadCones("left.tif")), 0.7);
  WarpCase w;
  w.m = m;
  const cv::Matx22d a(m(0, 0), m(0, 1), m(1, 0), m(1, 1));
  const cv::Matx22d ai = a.inv();
  constexpr int kSub = 4;
  cv::Mat ref(left.size(), CV_32F), warped(left.size(), CV_32F);
  for (int r = 0; r < left.rows; ++r)
    for (int c = 0; c < left.cols; ++c) {
      double sa = 0, sb = 0;
      for (int i = 0; i < kSub; ++i)
        for (int j = 0; j < kSub; ++j) {
          const double x = c - 0.5 + (j + 0.5) / kSub, y = r - 0.5 + (i + 0.5) / kSub;
          sa += SampleBicubic(left, x, y);
          const cv::Vec2d src = ai * cv::Vec2d(x - m(0, 2), y - m(1, 2));
          sb += SampleBicubic(left, src[0], src[1]);
        }
      ref.at<float>(r, c) = static_cast<float>(sa / (kSub * kSub));
      warped.at<float>(r, c) = static_cast<float>(sb / (kSub * kSub));
    }
  w.a = AddNoise(ref, noise, seed);
  w.b = AddNoise(warped, noise, seed + 1);
  return w;
}

Eigen::Vector2d Apply(const cv::Matx23d& m, const Eigen::Vector2d& x) {
  return Eigen::Vector2d(m(0, 0) * x.x() + m(0, 1) * x.y() + m(0, 2),
                         m(1, 0) * x.x() + m(1, 1) * x.y() + m(1, 2));
}

std::vector<InterestPoint> PointsInside(const cv::Mat& a, int margin) {
  InterestPointOptions io;
  io.border = margin;
  io.min_distance = 8;
  io.max_points = 300;
  return DetectInterestPoints(a, io);
}

struct PrecisionResult {
  int n = 0, total = 0;
  double rms = 0, median = 0, predicted = 0;
};

// LSC of every interest point of w.a (11 x 11 unless options say otherwise),
// started at the rounded truth (as after correlation to 1 px).
PrecisionResult Precision(const WarpCase& w, const LscOptions& o) {
  PrecisionResult res;
  std::vector<double> err;
  double sum_pred = 0;
  for (const InterestPoint& p : PointsInside(w.a, 20)) {
    const Eigen::Vector2d truth = Apply(w.m, p.x);
    if (truth.x() < 20 || truth.y() < 20 || truth.x() > w.b.cols - 21 || truth.y() > w.b.rows - 21)
      continue;
    ++res.total;
    const Eigen::Vector2d start = truth.array().round();
    const LscSummary s = MatchLsc(w.a, w.b, p.x, start, o);
    if (!s.IsSolutionUsable()) continue;
    err.push_back((s.xb - truth).norm());
    sum_pred += s.covariance.trace();
  }
  res.n = static_cast<int>(err.size());
  if (res.n == 0) return res;
  double sum2 = 0;
  for (double e : err) sum2 += e * e;
  res.rms = std::sqrt(sum2 / res.n);
  std::sort(err.begin(), err.end());
  res.median = err[err.size() / 2];
  res.predicted = std::sqrt(sum_pred / res.n);
  return res;
}

const cv::Matx23d kShift(1, 0, 0.37, 0, 1, -0.81);
const cv::Matx23d kAffine(1.02 * std::cos(0.035), -1.02 * std::sin(0.035), 3.3,
                          1.02 * std::sin(0.035), 1.02 * std::cos(0.035),
                          -5.6);  // 2 deg rotation, 2 % scale

TEST(Lsc, SubPixelPrecisionOnWarpedRealTexture) {
  // Noise per image [grey]: 2 is realistic for an 8-bit camera (the
  // simulator's model, read noise 1.5 DN plus shot noise, gives 2-3 DN at
  // mid grey); 1 is a good camera in good light.
  const struct {
    const char* name;
    const cv::Matx23d* m;
    LscModel model;
    double noise;
    double max_rms;     // asserted bound on the error RMS [px]
    double max_median;  // and on the median error [px]
  } cases[] = {
      {"shift (0.37, -0.81)", &kShift, LscModel::kShift, 2.0, 0.05, 0.04},
      {"shift (0.37, -0.81)", &kShift, LscModel::kAffine, 2.0, 0.10, 0.05},
      {"rot 2deg scale 1.02", &kAffine, LscModel::kAffine, 2.0, 0.10, 0.05},
      {"shift (0.37, -0.81)", &kShift, LscModel::kAffine, 1.0, 0.05, 0.03},
      {"rot 2deg scale 1.02", &kAffine, LscModel::kAffine, 1.0, 0.05, 0.035},
  };
  for (const auto& c : cases) {
    const WarpCase w = MakeWarp(*c.m, c.noise, 7);
    for (Interpolation interp : {Interpolation::kBilinear, Interpolation::kBicubic}) {
      LscOptions o;
      o.model = c.model;
      o.interpolation = interp;
      o.half_window = 5;  // 11 x 11
      const PrecisionResult r = Precision(w, o);
      std::printf(
          "LSC 11x11 %-20s noise %.0f %-6s %-8s: %3d/%3d usable, error RMS %.4f px, median %.4f px "
          "(predicted %.4f px)\n",
          c.name, c.noise, LscModelName(c.model), InterpolationName(interp), r.n, r.total, r.rms,
          r.median, r.predicted);
      ASSERT_GT(r.total, 100);
      EXPECT_GT(r.n, 0.4 * r.total);  // the rest: straight-edge windows (kTextureless)
      // The precision estimate is of the right size (within a factor 3).
      EXPECT_LT(r.predicted, 3.0 * r.rms + 0.01);
      EXPECT_GT(r.predicted, r.rms / 3.0);
      if (interp == Interpolation::kBilinear) {
        // Reported; bilinear resampling is the less precise choice (eq. 2
        // measured 0.050 px, eq. 1 0.09-0.12 px).
        EXPECT_LE(r.rms, 0.15) << c.name << " " << LscModelName(c.model);
        continue;
      }
      // Bicubic: the bounds of the table. Eq. 1 at 2 grey levels does not
      // reach 0.05 px RMS (measured 0.074-0.078 px, median 0.034-0.043 px;
      // see doc/nodes/hex_matcher.md for why).
      EXPECT_LE(r.rms, c.max_rms) << c.name << " " << LscModelName(c.model);
      EXPECT_LE(r.median, c.max_median) << c.name << " " << LscModelName(c.model);
    }
  }
}

// Eq. 1 at 2 grey levels with the quality control a crew would use when it
// asks for 0.05 px: reject matches whose predicted sigma (larger eigenvalue
// of the shift covariance) exceeds 0.05 px, checked on eq. 1's covariance
// also where the F test fell back to eq. 2 (fallback_affine_precision: the
// affine terms were not determined, not shown to be zero), and windows where
// the shift correlates with an affine term by more than 0.8 (kIllConditioned).
// Checked on two noise seeds and three warps (two shifts, the rotation),
// not tuned on one; the share of matches kept is printed and bounded below.
TEST(Lsc, Eq1WithQualityControlWithinFiveHundredthsPixel) {
  const cv::Matx23d kShift2(1, 0, -0.62, 0, 1, 0.27);
  const struct {
    const char* name;
    const cv::Matx23d* m;
  } warps[] = {{"shift (0.37, -0.81)", &kShift},
               {"shift (-0.62, 0.27)", &kShift2},
               {"rot 2deg scale 1.02", &kAffine}};
  for (unsigned seed : {7u, 8u}) {
    for (const auto& c : warps) {
      const WarpCase w = MakeWarp(*c.m, 2.0, seed);
      LscOptions plain;  // eq. 1 bicubic, defaults (max_sigma 0.5, no correlation test)
      LscOptions qc = plain;
      qc.max_sigma = 0.05;
      qc.fallback_affine_precision = true;
      qc.max_shift_affine_correlation = 0.8;
      const PrecisionResult r0 = Precision(w, plain);
      const PrecisionResult r = Precision(w, qc);
      std::printf(
          "LSC 11x11 eq. 1 noise 2 seed %u %-20s: without QC %3d usable, RMS %.4f px; with QC %3d "
          "kept "
          "(%.0f %%), RMS %.4f px, median %.4f px (predicted %.4f px)\n",
          seed, c.name, r0.n, r0.rms, r.n, 100.0 * r.n / std::max(1, r0.n), r.rms, r.median,
          r.predicted);
      EXPECT_LE(r.rms, 0.05) << c.name << " seed " << seed;
      EXPECT_LT(r.rms, r0.rms) << c.name << " seed " << seed;
      EXPECT_GE(r.n, 0.4 * r0.n) << c.name << " seed " << seed;  // measured 45-59 %
    }
  }
}

// The two causes of the old eq. 1 imprecision, each measured against its fix
// on the same data: the Jacobian from the resampled image b instead of the
// template (noise-correlated gradient), and the F test that falls back to
// eq. 2 where the affine terms are not significant.
TEST(Lsc, TemplateGradientAndAffineTestImproveEq1) {
  const WarpCase w = MakeWarp(kShift, 2.0, 7);
  LscOptions o;
  o.model = LscModel::kAffine;
  o.interpolation = Interpolation::kBicubic;
  const PrecisionResult ours = Precision(w, o);
  LscOptions resampled = o;
  resampled.gradient = LscGradient::kResampled;
  const PrecisionResult r_res = Precision(w, resampled);
  LscOptions plain = o;
  plain.affine_min_f = 0.0;  // always eq. 1
  const PrecisionResult r_plain = Precision(w, plain);
  std::printf(
      "eq. 1 bicubic, noise 2, true shift: median error template+F %.4f, resampled gradient %.4f, "
      "no F test %.4f px\n",
      ours.median, r_res.median, r_plain.median);
  EXPECT_LT(ours.median, r_res.median);
  EXPECT_LT(ours.median, r_plain.median);
}

TEST(Lsc, ModifiedLscConvergesFromFivePixels) {
  const cv::Matx23d m = kShift;
  const WarpCase w = MakeWarp(m, 2.0, 11);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> off(-5.0, 5.0);
  int n = 0, ok_plain = 0, ok_mlsc = 0;
  for (const InterestPoint& p : PointsInside(w.a, 25)) {
    const Eigen::Vector2d truth = Apply(m, p.x);
    const Eigen::Vector2d start = truth + Eigen::Vector2d(off(rng), off(rng));
    LscOptions plain;
    plain.model = LscModel::kShift;
    plain.max_shift = 8.0;
    LscOptions mlsc = plain;
    mlsc.search_radius = 6;
    // Only windows LSC can use at all (not a straight edge, not flat).
    if (MatchLsc(w.a, w.b, p.x, truth, plain).status == LscSummary::Status::kTextureless) continue;
    const LscSummary a = MatchLsc(w.a, w.b, p.x, start, plain);
    const LscSummary b = MatchLsc(w.a, w.b, p.x, start, mlsc);
    ++n;
    if (a.IsSolutionUsable() && (a.xb - truth).norm() < 0.2) ++ok_plain;
    if (b.IsSolutionUsable() && (b.xb - truth).norm() < 0.2) ++ok_mlsc;
  }
  ASSERT_GT(n, 80);
  const double r_plain = double(ok_plain) / n, r_mlsc = double(ok_mlsc) / n;
  std::printf("convergence from +-5 px (%d points): plain LSC %.1f %%, MLSC %.1f %%\n", n,
              100 * r_plain, 100 * r_mlsc);
  EXPECT_GT(r_mlsc, 0.9);
  EXPECT_GT(r_mlsc, r_plain + 0.05);
}

// The cells of the published LSC table on Cones, in its order: eq. 1
// (affine) / eq. 2 (shift) x 5x5 / 11x11 windows (half window h), with the
// published y-parallax RMS [px].
struct PublishedCell {
  LscModel model;
  int h;
  double published;
};
const PublishedCell kPublishedCells[] = {{LscModel::kAffine, 2, 0.48},
                                         {LscModel::kShift, 2, 0.76},
                                         {LscModel::kAffine, 5, 0.40},
                                         {LscModel::kShift, 5, 0.44}};

// The published LSC table on the real rectified pair, and disparities
// against the ground truth outside occlusions.
//
// Every interest point of the left image is matched with the four
// configurations (MLSC: correlation to 1 px along the row with an 11 x 11
// window, then LSC, bicubic). Columns: "ours" = residual y-parallax RMS of
// matches whose disparity is within 1 px of the ground truth (non-occluded),
// "all" = every usable match incl. blunders, "common" = the points that all
// four configurations match within 1 px (the same points in every cell, so
// the cells compare like with like).
TEST(Lsc, PublishedTableOnCones) {
  const slope_monitor::testing::ConesPair cones = slope_monitor::testing::LoadConesPair();
  const cv::Mat left = ToFloat(cones.left), right = ToFloat(cones.right);
  const cv::Mat &gt = cones.gt, &occl = cones.occl;
  ASSERT_EQ(gt.type(), CV_32FC1);
  ASSERT_EQ(gt.size(), left.size());
  const std::vector<InterestPoint> pts = PointsInside(left, 12);
  ASSERT_GT(pts.size(), 200u);
  // Cells in the published table's order: eq. 1 / eq. 2 x 5x5 / 11x11.
  const auto& cells = kPublishedCells;
  const size_t np = pts.size();
  std::vector<std::vector<double>> dy(4, std::vector<double>(np, 0.0));
  std::vector<std::vector<char>> ok(4, std::vector<char>(np, 0));
  double ours[4], all_rms[4], within05[4], within1[4];
  int usable[4];
  for (int i = 0; i < 4; ++i) {
    LscOptions o;
    o.model = cells[i].model;
    o.half_window = cells[i].h;
    o.interpolation = Interpolation::kBicubic;
    o.search_radius = 40;  // correlation to 1 px (11 x 11) along the row, then LSC
    o.search_radius_y = 1;
    o.search_half_window = 5;
    o.max_shift = 3.0;
    double sy2 = 0, sy2_ok = 0;
    int n = 0, valid = 0, w05 = 0, w1 = 0;
    for (size_t k = 0; k < np; ++k) {
      const InterestPoint& p = pts[k];
      const int c = static_cast<int>(p.x.x()), r = static_cast<int>(p.x.y());
      // Start at disparity 35 (the middle of Cones' 0..~60 px range).
      const LscSummary s = MatchLsc(left, right, p.x, p.x - Eigen::Vector2d(35, 0), o);
      if (!s.IsSolutionUsable()) continue;
      ++n;
      const double y = s.xb.y() - p.x.y();
      sy2 += y * y;
      const float d = gt.at<float>(r, c);
      if (d <= 0 || occl.at<uint8_t>(r, c) == 0) continue;  // unknown or occluded
      ++valid;
      const double err = std::fabs((p.x.x() - s.xb.x()) - d);
      if (err <= 0.5) ++w05;
      if (err <= 1.0) {
        ++w1;
        sy2_ok += y * y;
        ok[i][k] = 1;
        dy[i][k] = y;
      }
    }
    usable[i] = n;
    all_rms[i] = std::sqrt(sy2 / n);
    ours[i] = std::sqrt(sy2_ok / w1);
    within05[i] = double(w05) / valid;
    within1[i] = double(w1) / valid;
  }
  double common[4] = {0, 0, 0, 0};
  int n_common = 0;
  for (size_t k = 0; k < np; ++k) {
    if (!(ok[0][k] && ok[1][k] && ok[2][k] && ok[3][k])) continue;
    ++n_common;
    for (int i = 0; i < 4; ++i) common[i] += dy[i][k] * dy[i][k];
  }
  for (double& c : common) c = std::sqrt(c / n_common);
  std::printf(
      "Cones residual y-parallax RMS [px] (true 0), bicubic MLSC; %d points usable by all four "
      "cells ('common')\n"
      "  window model   published  ours    common  all     usable  disp|err|<=0.5  <=1px\n",
      n_common);
  for (int i = 0; i < 4; ++i) {
    std::printf(
        "  %2dx%-2d  %-6s   %.2f       %.3f   %.3f   %.3f   %4d    %5.1f %%         %5.1f %%\n",
        2 * cells[i].h + 1, 2 * cells[i].h + 1, LscModelName(cells[i].model), cells[i].published,
        ours[i], common[i], all_rms[i], usable[i], 100.0 * within05[i], 100.0 * within1[i]);
  }
  ASSERT_GE(n_common, 15);
  for (int i = 0; i < 4; ++i) {
    EXPECT_GE(usable[i], 20);
    // Lower than published, on the correct matches and on the common points.
    EXPECT_LT(ours[i], cells[i].published) << i;
    EXPECT_LT(common[i], cells[i].published) << i;
  }
  // The published ordering eq. 1 < eq. 2 holds in each window on the common
  // points. The window ordering (11 x 11 < 5 x 5) does not show on these 21
  // common points (measured eq. 2: 0.136 vs 0.136 px, eq. 1: 0.107 vs 0.114
  // px): the pair's constant y offset (~ -0.08 px) dominates them; see
  // PublishedTableWindowOrderingOnCones for the protocol that separates it.
  EXPECT_LT(common[0], common[1]);
  EXPECT_LT(common[2], common[3]);
  // Disparities against the ground truth (non-occluded, known disparity):
  // 11 x 11 windows, measured eq. 1 75.9 % / 83.9 %, eq. 2 67.5 % / 73.0 %
  // (the shift model fails more on the slanted cones).
  EXPECT_GT(within05[2], 0.7);
  EXPECT_GT(within1[2], 0.8);
  EXPECT_GT(within05[3], 0.6);
  EXPECT_GT(within1[3], 0.65);
  for (int i = 0; i < 4; ++i) EXPECT_GT(within1[i], 0.6) << i;
}

TEST(Lsc, BadInputGivesAClearOutcome) {
  const cv::Mat tex = ToFloat(LoadCones("left.tif"));
  LscOptions o;
  // Window larger than the image.
  o.half_window = 50;
  const cv::Mat small = tex(cv::Rect(100, 100, 40, 40)).clone();
  EXPECT_EQ(MatchLsc(small, small, {20, 20}, {20, 20}, o).status, LscSummary::Status::kOutside);
  // Textureless.
  o.half_window = 5;
  const cv::Mat flat(60, 60, CV_32F, cv::Scalar(120));
  EXPECT_EQ(MatchLsc(flat, flat, {30, 30}, {30, 30}, o).status, LscSummary::Status::kTextureless);
  // Texture in a but a flat b: no fake match.
  const LscSummary s =
      MatchLsc(tex(cv::Rect(100, 100, 60, 60)).clone(), flat, {30, 30}, {30, 30}, o);
  EXPECT_FALSE(s.IsSolutionUsable());
  // Wrong encodings and options.
  EXPECT_THROW(MatchLsc(cv::Mat(60, 60, CV_8U), flat, {30, 30}, {30, 30}, o), InvalidArgument);
  o.half_window = 0;
  EXPECT_THROW(MatchLsc(flat, flat, {30, 30}, {30, 30}, o), ConfigError);
  EXPECT_THROW(LscModelFromName("projective"), InvalidArgument);
}

// The window ordering of the published table on Cones, with a protocol that
// measures the matching, not the pair: (1) the same points in all four
// cells: every interest point (spacing 4 px, up to 3000) that all four
// cells match within 1 px of the ground-truth disparity, outside occlusions;
// (2) the residual y-parallax (the published quantity, true 0) taken about
// one constant for all four cells, the pooled mean over those points: the
// rectified pair has a constant vertical offset of its own (measured
// -0.07 .. -0.09 px in every cell, window and model alike) that a matcher
// cannot remove and that would otherwise dominate the RMS. The raw RMS is
// printed beside it. Two point spacings (4 px asserted, 6 px reported).
TEST(Lsc, PublishedTableWindowOrderingOnCones) {
  const slope_monitor::testing::ConesPair cones = slope_monitor::testing::LoadConesPair();
  const cv::Mat left = ToFloat(cones.left), right = ToFloat(cones.right);
  const cv::Mat &gt = cones.gt, &occl = cones.occl;
  const auto& cells = kPublishedCells;
  for (int spacing : {4, 6}) {
    InterestPointOptions io;
    io.border = 12;
    io.min_distance = spacing;
    io.max_points = 3000;
    const std::vector<InterestPoint> pts = DetectInterestPoints(left, io);
    const size_t np = pts.size();
    std::vector<std::vector<double>> dy(4, std::vector<double>(np, 0.0));
    std::vector<std::vector<char>> ok(4, std::vector<char>(np, 0));
    for (int i = 0; i < 4; ++i) {
      LscOptions o;
      o.model = cells[i].model;
      o.half_window = cells[i].h;
      o.search_radius = 40;  // correlation to 1 px (11 x 11) along the row, then LSC
      o.search_radius_y = 1;
      o.search_half_window = 5;
      o.max_shift = 3.0;
      for (size_t k = 0; k < np; ++k) {
        const InterestPoint& p = pts[k];
        const int c = static_cast<int>(p.x.x()), r = static_cast<int>(p.x.y());
        const LscSummary s = MatchLsc(left, right, p.x, p.x - Eigen::Vector2d(35, 0), o);
        if (!s.IsSolutionUsable()) continue;
        const float d = gt.at<float>(r, c);
        if (d <= 0 || occl.at<uint8_t>(r, c) == 0) continue;
        if (std::fabs((p.x.x() - s.xb.x()) - d) > 1.0) continue;
        ok[i][k] = 1;
        dy[i][k] = s.xb.y() - p.x.y();
      }
    }
    std::vector<size_t> common;
    for (size_t k = 0; k < np; ++k)
      if (ok[0][k] && ok[1][k] && ok[2][k] && ok[3][k]) common.push_back(k);
    ASSERT_GE(common.size(), 50u) << "spacing " << spacing;
    double offset = 0;
    for (int i = 0; i < 4; ++i)
      for (size_t k : common) offset += dy[i][k];
    offset /= 4.0 * common.size();
    double raw[4], rel[4], mean[4];
    for (int i = 0; i < 4; ++i) {
      double s1 = 0, s2 = 0, s2o = 0;
      for (size_t k : common) {
        s1 += dy[i][k];
        s2 += dy[i][k] * dy[i][k];
        s2o += (dy[i][k] - offset) * (dy[i][k] - offset);
      }
      mean[i] = s1 / common.size();
      raw[i] = std::sqrt(s2 / common.size());
      rel[i] = std::sqrt(s2o / common.size());
    }
    std::printf(
        "Cones y-parallax on %zu common points of %zu (spacing %d px), pair offset %.3f px\n"
        "  window model   published  RMS about offset  raw RMS  mean\n",
        common.size(), np, spacing, offset);
    for (int i = 0; i < 4; ++i) {
      std::printf("  %2dx%-2d  %-6s   %.2f       %.3f             %.3f    %.3f\n",
                  2 * cells[i].h + 1, 2 * cells[i].h + 1, LscModelName(cells[i].model),
                  cells[i].published, rel[i], raw[i], mean[i]);
      EXPECT_LT(raw[i], cells[i].published) << i;
    }
    // The published orderings: 11 x 11 < 5 x 5 for each model, eq. 1 < eq. 2
    // in each window. Asserted on the denser set (95 points: 0.069 < 0.083,
    // 0.075 < 0.094, 0.083 < 0.094, 0.069 < 0.075 px). On the sparser set
    // (72 points) they hold too but by 0.000-0.004 px, within the sampling
    // error of an RMS of 72 values (~0.005 px): reported only.
    if (spacing != 4) continue;
    EXPECT_LT(rel[2], rel[0]) << "eq. 1, spacing " << spacing;
    EXPECT_LT(rel[3], rel[1]) << "eq. 2, spacing " << spacing;
    EXPECT_LT(rel[0], rel[1]) << "5x5, spacing " << spacing;
    EXPECT_LT(rel[2], rel[3]) << "11x11, spacing " << spacing;
  }
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
