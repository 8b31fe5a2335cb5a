// Coarse-to-fine LoG correlation on Middlebury 2003 "Cones" (test/data/
// stereo_middlebury_cones): error rates against the ground-truth disparity on
// non-occluded pixels. The default options (doc/design.md sizes, per-pixel final
// grid) against bounds measured plus a margin; config/dense_cones.yaml
// against OpenCV's StereoSGBM run in the same process (bench_dense_vs_sgbm
// adds the throughput); the edge window, the background fill and the
// right-to-left matches from the correlation volume on hand-checkable cases.
#include <cmath>
#include <limits>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/correlation.h"
#include "slope_monitor/core/dense/evaluation.h"
#include "slope_monitor/core/dense/options_yaml.h"

#include "../matching/cones_images.h"  // the Middlebury Cones pair (header only)

namespace slope_monitor {
namespace dense {
namespace {

// A smooth random texture (96 x 128, uniform 0..255 from cv::RNG(7),
// Gaussian blur of 1.2 px) and the same shifted by a known 5.4 px (bilinear
// resampling): right(x) = left(x + 5.4), a point at x_left is at
// x_left - 5.4 on the right: disparity +5.4.
constexpr double kShift = 5.4;  // [px]
struct ShiftedTexture {
  cv::Mat left, right;
};
ShiftedTexture SmoothTextureShifted() {
  cv::Mat tex(96, 128, CV_32F);
  cv::RNG rng(7);
  rng.fill(tex, cv::RNG::UNIFORM, 0, 255);
  ShiftedTexture t;
  cv::GaussianBlur(tex, t.left, cv::Size(0, 0), 1.2);
  const cv::Mat m = (cv::Mat_<double>(2, 3) << 1, 0, -kShift, 0, 1, 0);
  cv::warpAffine(t.left, t.right, m, t.left.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  return t;
}

TEST(Cones, ErrorRatesStayUnderTheMeasuredBound) {
  const testing::ConesPair cones = testing::LoadConesPair(cv::IMREAD_GRAYSCALE);
  const cv::Mat &left = cones.left, &right = cones.right, &gt = cones.gt, &occl = cones.occl;
  ASSERT_EQ(gt.type(), CV_32F);
  CorrelationOptions o;
  o.final_grid_spacing = 1;
  o.min_disparity = 0;
  o.max_disparity = 64;
  CorrelationSummary summary;
  const ParallaxGrid grid = MatchRectified(left, right, o, &summary);
  ASSERT_EQ(grid.disparity.size(), left.size());
  const DisparityErrors e = EvaluateDisparity(grid.disparity, gt, occl, {1.0, 2.0});
  std::printf(
      "%s\nCones non-occluded: bad>1 %.4f bad>2 %.4f (estimated only %.4f / %.4f), missing %.4f, "
      "rms %.3f\n",
      summary.BriefReport().c_str(), e.bad_fraction[0], e.bad_fraction[1], e.bad_fraction_valid[0],
      e.bad_fraction_valid[1], static_cast<double>(e.missing) / e.evaluated, e.rms_valid);
  EXPECT_GT(e.evaluated, 140000);
  // Measured (default options): 0.249 / 0.214, estimated only 0.112 / 0.070, missing 0.154.
  EXPECT_LT(e.bad_fraction[0], 0.27);
  EXPECT_LT(e.bad_fraction[1], 0.235);
  EXPECT_LT(e.bad_fraction_valid[0], 0.13);
  EXPECT_LT(e.bad_fraction_valid[1], 0.085);
  EXPECT_LT(static_cast<double>(e.missing) / e.evaluated, 0.18);
}

TEST(Cones, ConesConfigurationIsNoWorseThanSgbm) {
  // config/dense_cones.yaml with its disparity map's holes filled from the
  // background side, against OpenCV's StereoSGBM (stereo_match sample
  // settings, as bench_dense_vs_sgbm) on the same pair in this process.
  const testing::ConesPair cones = testing::LoadConesPair(cv::IMREAD_GRAYSCALE);
  const cv::Mat &left = cones.left, &right = cones.right, &gt = cones.gt, &occl = cones.occl;
  CorrelationOptions o;
  o.final_grid_spacing = 1;
  o.min_disparity = 0;
  o.max_disparity = 64;
  ReadCorrelationOptions(std::string(SM_SOURCE_DIR) + "/config/dense_cones.yaml", &o);
  const ParallaxGrid grid = MatchRectified(left, right, o);
  const cv::Mat filled = FillFromBackground(grid.disparity, left.cols);
  const DisparityErrors raw = EvaluateDisparity(grid.disparity, gt, occl, {1.0, 2.0});
  const DisparityErrors e = EvaluateDisparity(filled, gt, occl, {1.0, 2.0});
  const int block = 5;
  cv::Ptr<cv::StereoSGBM> sgbm =
      cv::StereoSGBM::create(0, 64, block, 8 * block * block, 32 * block * block, 1, 63, 10, 100,
                             32, cv::StereoSGBM::MODE_SGBM);
  cv::Mat raw16, sgbm_disp;
  sgbm->compute(left, right, raw16);
  raw16.convertTo(sgbm_disp, CV_32F, 1.0 / 16.0);
  const DisparityErrors es = EvaluateDisparity(sgbm_disp, gt, occl, {1.0, 2.0}, -0.5f);
  const double density_raw = 1.0 - static_cast<double>(raw.missing) / raw.evaluated;
  std::printf(
      "Cones, config/dense_cones.yaml: before the fill bad>1 %.4f bad>2 %.4f (estimated only %.4f "
      "/ %.4f) "
      "density %.4f; filled bad>1 %.4f bad>2 %.4f; SGBM bad>1 %.4f bad>2 %.4f density %.4f\n",
      raw.bad_fraction[0], raw.bad_fraction[1], raw.bad_fraction_valid[0],
      raw.bad_fraction_valid[1], density_raw, e.bad_fraction[0], e.bad_fraction[1],
      es.bad_fraction[0], es.bad_fraction[1], 1.0 - static_cast<double>(es.missing) / es.evaluated);
  // Measured: filled 0.0902 / 0.0697 against SGBM 0.1357 / 0.1269; before
  // the fill 0.1287 / 0.1147 at density 0.918 (SGBM 0.902).
  EXPECT_EQ(e.missing, 0);
  EXPECT_LE(e.bad_fraction[0], es.bad_fraction[0]);
  EXPECT_LE(e.bad_fraction[1], es.bad_fraction[1]);
  // Also without the fill (holes counted as errors) no worse than SGBM, and as dense.
  EXPECT_LE(raw.bad_fraction[0], es.bad_fraction[0]);
  EXPECT_LE(raw.bad_fraction[1], es.bad_fraction[1]);
  EXPECT_GT(density_raw, 0.91);
}

TEST(Cones, FillFromBackgroundTakesTheFartherSide) {
  const float n = std::numeric_limits<float>::quiet_NaN();
  // Row 0: a hole between 10 (near) and 4 (far) takes 4; row 1: border holes
  // take their only neighbour; row 2: a gap of 3 > max_gap 2 stays; row 3: all missing stays.
  cv::Mat d = (cv::Mat_<float>(4, 6) << 1, 10, n, n, 4, 4,  //
               n, 7, 7, 7, 7, n,                            //
               5, n, n, n, 6, 6,                            //
               n, n, n, n, n, n);
  cv::Mat mask;
  const cv::Mat f = FillFromBackground(d, 2, &mask);
  EXPECT_FLOAT_EQ(f.at<float>(0, 2), 4.0f);
  EXPECT_FLOAT_EQ(f.at<float>(0, 3), 4.0f);
  EXPECT_FLOAT_EQ(f.at<float>(1, 0), 7.0f);
  EXPECT_FLOAT_EQ(f.at<float>(1, 5), 7.0f);
  EXPECT_TRUE(std::isnan(f.at<float>(2, 2)));
  EXPECT_TRUE(std::isnan(f.at<float>(3, 0)));
  EXPECT_EQ(cv::countNonZero(mask), 4);
  EXPECT_FLOAT_EQ(f.at<float>(0, 1), 10.0f);   // valid values untouched
  EXPECT_TRUE(std::isnan(d.at<float>(0, 2)));  // input untouched
  EXPECT_THROW(FillFromBackground(cv::Mat(2, 2, CV_8U), 2), InvalidArgument);
}

TEST(Cones, EdgeWindowReducesFatteningAtADepthStep) {
  // A textured foreground square (parallax 14 px) in front of a textured
  // background (parallax 4 px): the right image is the composite of both
  // shifted by their parallaxes. Truth: the known parallax of each visible
  // left pixel. Near the step the 15 x 15 window straddles both surfaces
  // (fattening, then rejected by the left/right check: holes); the 5 x 5
  // window where the prediction spans the edge must give more correct and
  // fewer wrong-or-missing pixels there.
  const int w = 256, h = 192;
  cv::RNG rng(11);
  cv::Mat bg(h, w + 64, CV_32F), fg(h, w + 64, CV_32F);
  rng.fill(bg, cv::RNG::UNIFORM, 0, 255);
  rng.fill(fg, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(bg, bg, cv::Size(0, 0), 1.0);
  cv::GaussianBlur(fg, fg, cv::Size(0, 0), 1.0);
  const cv::Rect square(96, 56, 80, 80);  // in the left image
  const int d_bg = 4, d_fg = 14;
  cv::Mat left(h, w, CV_32F), right(h, w, CV_32F), truth(h, w, CV_32F);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const bool in_l = square.contains(cv::Point(x, y));
      left.at<float>(y, x) = in_l ? fg.at<float>(y, x + 32) : bg.at<float>(y, x + 32);
      truth.at<float>(y, x) = in_l ? d_fg : d_bg;
      // Right pixel x shows the left point x + d: the square if x + d_fg is in it.
      const bool in_r = square.contains(cv::Point(x + d_fg, y));
      right.at<float>(y, x) =
          in_r ? fg.at<float>(y, x + d_fg + 32) : bg.at<float>(y, x + d_bg + 32);
    }
  CorrelationOptions o;
  o.final_grid_spacing = 1;
  o.max_disparity = 24;
  // Within 12 px of the square's outline, without the background the square
  // hides in the right image (left of the square, d_fg - d_bg px wide):
  // correct (within 1 px of the truth), wrong, missing.
  struct Count {
    int correct = 0, wrong = 0, missing = 0;
  };
  auto count = [&](const CorrelationOptions& opt) {
    const ParallaxGrid g = MatchRectified(left, right, opt);
    Count c;
    const cv::Rect outer(square.x - 12, square.y - 12, square.width + 24, square.height + 24);
    const cv::Rect inner(square.x + 12, square.y + 12, square.width - 24, square.height - 24);
    for (int y = outer.y; y < outer.y + outer.height; ++y)
      for (int x = outer.x; x < outer.x + outer.width; ++x) {
        if (inner.contains(cv::Point(x, y))) continue;
        const bool occluded = y >= square.y && y < square.y + square.height &&
                              x >= square.x - (d_fg - d_bg) && x < square.x;
        if (occluded) continue;
        const float d = g.disparity.at<float>(y, x);
        if (!(d == d))
          ++c.missing;
        else if (std::abs(d - truth.at<float>(y, x)) <= 1.0f)
          ++c.correct;
        else
          ++c.wrong;
      }
    return c;
  };
  const Count c15 = count(o);
  o.edge_window = 5;
  const Count ce = count(o);
  std::printf(
      "near the step: 15x15 correct %d wrong %d missing %d; edge window 5x5 correct %d wrong %d "
      "missing %d\n",
      c15.correct, c15.wrong, c15.missing, ce.correct, ce.wrong, ce.missing);
  EXPECT_GT(ce.correct, c15.correct);
  EXPECT_LT(ce.wrong + ce.missing, c15.wrong + c15.missing);
}

TEST(Cones, LscRefinementSharpensTheSubPixelParallax) {
  // The constant 5.4 px shift of a smooth random texture (as below):
  // least squares on the LoG images against the parabola through the ZNCC
  // peak (measured: 0.0116 px vs 0.0139 px RMS on the same 399 nodes).
  const ShiftedTexture texture = SmoothTextureShifted();
  const cv::Mat &smooth = texture.left, &shifted = texture.right;
  CorrelationOptions o;
  o.levels = 2;
  o.final_grid_spacing = 4;
  o.max_disparity = 12;
  auto rms = [&](const ParallaxGrid& g, int* n) {
    double s2 = 0;
    *n = 0;
    for (int i = 0; i < g.disparity.rows; ++i)
      for (int j = 0; j < g.disparity.cols; ++j)
        if (g.Valid(i, j) && j * 4 > 20 && j * 4 < 108 && i * 4 > 10 && i * 4 < 86) {
          s2 += std::pow(g.disparity.at<float>(i, j) - kShift, 2);
          ++*n;
        }
    return std::sqrt(s2 / std::max(1, *n));
  };
  int n0 = 0, n1 = 0;
  const double rms_parabola = rms(MatchRectified(smooth, shifted, o), &n0);
  o.lsc_iterations = 5;
  const double rms_lsc = rms(MatchRectified(smooth, shifted, o), &n1);
  std::printf(
      "constant 5.4 px shift: parabola RMS %.4f px (%d nodes), LSC RMS %.4f px (%d nodes)\n",
      rms_parabola, n0, rms_lsc, n1);
  ASSERT_GT(n1, 100);
  EXPECT_EQ(n0, n1);
  EXPECT_LT(rms_lsc, 0.9 * rms_parabola);
  EXPECT_LT(rms_lsc, 0.013);
}

TEST(Cones, EvaluationCountsHolesAsErrors) {
  // 2 x 2 reference; one pixel unknown (0), one masked out.
  cv::Mat ref = (cv::Mat_<float>(2, 2) << 10.0f, 0.0f, 5.0f, 7.0f);
  cv::Mat est =
      (cv::Mat_<float>(2, 2) << 10.5f, 3.0f, std::numeric_limits<float>::quiet_NaN(), 1.0f);
  cv::Mat mask = (cv::Mat_<uchar>(2, 2) << 255, 255, 255, 0);
  const DisparityErrors e = EvaluateDisparity(est, ref, mask, {1.0});
  EXPECT_EQ(e.evaluated, 2);
  EXPECT_EQ(e.missing, 1);
  EXPECT_DOUBLE_EQ(e.bad_fraction[0], 0.5);
  EXPECT_DOUBLE_EQ(e.bad_fraction_valid[0], 0.0);
  EXPECT_DOUBLE_EQ(e.rms_valid, 0.5);
}

TEST(Cones, BlackOrMismatchedImagesAreRejected) {
  const cv::Mat black(64, 64, CV_8U, cv::Scalar(0));
  cv::Mat tex(64, 64, CV_8U);
  cv::randu(tex, 0, 255);
  CorrelationOptions o;
  o.levels = 2;
  o.max_disparity = 8;
  try {
    MatchRectified(tex, black, o);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("right image has no texture"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(MatchRectified(tex, tex(cv::Rect(0, 0, 60, 64)).clone(), o), InvalidArgument);
  EXPECT_THROW(
      MatchRectified(tex(cv::Rect(0, 0, 20, 20)).clone(), tex(cv::Rect(0, 0, 20, 20)).clone(), o),
      InvalidArgument);
}

TEST(Cones, ConstantShiftIsRecoveredToSubPixel) {
  // A random texture shifted by a known 5.4 px (SmoothTextureShifted).
  const ShiftedTexture texture = SmoothTextureShifted();
  const cv::Mat &smooth = texture.left, &shifted = texture.right;
  // Both ways of getting the right-to-left matches (second search, or the
  // left search's correlation volume).
  for (const bool full_right : {true, false}) {
    CorrelationOptions o;
    o.levels = 2;
    o.final_grid_spacing = 4;
    o.max_disparity = 12;
    o.full_right_search = full_right;
    CorrelationSummary s;
    const ParallaxGrid g = MatchRectified(smooth, shifted, o, &s);
    double sum = 0;
    int n = 0;
    for (int i = 0; i < g.disparity.rows; ++i)
      for (int j = 0; j < g.disparity.cols; ++j)
        if (g.Valid(i, j) && j * 4 > 20 && j * 4 < 108) {
          EXPECT_NEAR(g.disparity.at<float>(i, j), kShift, 0.25)
              << "full_right_search " << full_right;
          sum += g.disparity.at<float>(i, j);
          ++n;
        }
    ASSERT_GT(n, 100) << s.BriefReport();
    EXPECT_NEAR(sum / n, kShift, 0.1);
  }
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
