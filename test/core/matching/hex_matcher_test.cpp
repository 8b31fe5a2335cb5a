// Hexagonal raster geometry (hand-checkable), and the hexagonal matcher on
// real texture with known warps, across "epochs" with a moving part, on the
// real rectified Cones pair with an epipolar prior (ground-truth disparity),
// and on bad input.
#include "slope_monitor/core/matching/hex_matcher.h"

#include <cmath>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

#include "cones_images.h"  // the Middlebury Cones pair (header only)

namespace slope_monitor {
namespace matching {
namespace {

using slope_monitor::testing::LoadCones;

TEST(HexRaster, GeometryAndSampling) {
  cv::Mat img(30, 40, CV_32F);
  for (int r = 0; r < 30; ++r)
    for (int c = 0; c < 40; ++c) img.at<float>(r, c) = float(1000 * r + c);
  const HexRaster h = HexRaster::FromImage(img, HexSampling::kNearest);
  EXPECT_EQ(h.rows(), 60);  // 2n rows from n
  EXPECT_NEAR(h.dx(), 1.0 / std::sqrt(3.0), 1e-12);
  // Six neighbours at the same distance.
  for (int i : {10, 11}) {
    for (int d = 0; d < 6; ++d) {
      int ni, nk;
      HexRaster::Neighbour(i, 20, d, &ni, &nk);
      EXPECT_NEAR((h.Centre(ni, nk) - h.Centre(i, 20)).norm(), 1.0 / std::sqrt(3.0), 1e-12)
          << i << " " << d;
    }
  }
  // Nearest: the value of the pixel whose centre holds the hexagon's centre.
  for (int i = 0; i < h.rows(); ++i)
    for (int k = 0; k < h.cols(); ++k) {
      const Eigen::Vector2d c = h.Centre(i, k);
      const int r = std::min(29, std::max(0, int(std::lround(c.y())))),
                col = int(std::lround(c.x()));
      ASSERT_EQ(h.value(i, k), img.at<float>(r, col)) << i << " " << k;
      int ii, kk;
      h.NearestCell(c, &ii, &kk);
      ASSERT_EQ(ii, i);
      ASSERT_EQ(kk, k);
    }
  // Hex rows 2j and 2j + 1 both lie in square row j.
  EXPECT_EQ(std::lround(h.Centre(14, 3).y()), 7);
  EXPECT_EQ(std::lround(h.Centre(15, 3).y()), 7);
  // Interpolated: exact on a ramp.
  const HexRaster hi = HexRaster::FromImage(img, HexSampling::kInterpolated);
  const Eigen::Vector2d c = hi.Centre(21, 13);
  EXPECT_NEAR(hi.value(21, 13), 1000 * c.y() + c.x(), 1e-2);
  // Descriptor: unit norm, zero mean; flat -> none.
  std::vector<float> d;
  ASSERT_TRUE(hi.Descriptor(30, 30, 4, &d));
  double s = 0, n = 0;
  for (float v : d) {
    s += v;
    n += v * v;
  }
  EXPECT_NEAR(s, 0.0, 1e-4);
  EXPECT_NEAR(n, 1.0, 1e-4);
  const HexRaster flat =
      HexRaster::FromImage(cv::Mat(20, 20, CV_8U, cv::Scalar(3)), HexSampling::kNearest);
  EXPECT_FALSE(flat.Descriptor(20, 10, 3, &d));
  const HexPyramid p(img, 3, HexSampling::kNearest);
  EXPECT_EQ(p.levels(), 3);
  EXPECT_NEAR(p.level(2).dx(), 4.0 / std::sqrt(3.0), 1e-12);
}

cv::Mat ShiftImage(const cv::Mat& f, const Eigen::Vector2d& t,
                   const cv::Rect& moving_roi = cv::Rect(),
                   const Eigen::Vector2d& t_moving = Eigen::Vector2d::Zero()) {
  cv::Mat out(f.size(), CV_32F);
  for (int r = 0; r < f.rows; ++r)
    for (int c = 0; c < f.cols; ++c) {
      const bool mv = moving_roi.contains(cv::Point(c, r));
      const Eigen::Vector2d s = mv ? t_moving : t;
      out.at<float>(r, c) = SampleBicubic(f, c - s.x(), r - s.y());
    }
  return out;
}

// One grey level of Gaussian noise.
cv::Mat Noisy(const cv::Mat& f, unsigned seed) {
  return slope_monitor::testing::AddNoise(f, 1.0, seed);
}

TEST(HexMatcher, FindsKnownShiftOnRealTexture) {
  const cv::Mat left = GaussianBlur(ToFloat(LoadCones("left.tif")), 0.7);
  const Eigen::Vector2d t(7.3, -4.6);
  const cv::Mat a = Noisy(left, 1), b = Noisy(ShiftImage(left, t), 2);
  HexMatcherOptions o;
  const HexMatcher matcher(o);
  MatchPrior prior;  // no shift known: search +-24 px
  const HexMatchResult r = matcher.Match(a, b, prior);
  int correct = 0, gross = 0;
  double s2 = 0;
  for (const HexMatch& m : r.matches) {
    const double e = (m.xb - m.xa - t).norm();
    if (e < 0.2) ++correct;
    if (e > 1.0) ++gross;
    s2 += e * e;
  }
  std::printf(
      "shift (7.3, -4.6): %d candidates, %d matches, %d within 0.2 px, RMS %.3f px, %.2f s\n",
      r.summary.candidates, r.summary.matched, correct, std::sqrt(s2 / r.summary.matched),
      r.summary.seconds);
  for (const auto& kv : r.summary.rejects)
    std::printf("  reject %s: %d\n", kv.first.c_str(), kv.second);
  EXPECT_GT(r.summary.matched, 50);
  EXPECT_GE(correct, 0.93 * r.summary.matched);
  EXPECT_LE(gross, 0.01 * r.summary.matched);
}

TEST(HexMatcher, EpochsWithAMovingArea) {
  const cv::Mat left = GaussianBlur(ToFloat(LoadCones("left.tif")), 0.7);
  const Eigen::Vector2d stable(3.2, 1.4), moving(3.2 + 14.5, 1.4 + 9.0);
  const cv::Rect roi(150, 120, 160, 150);
  const cv::Mat a = Noisy(left, 3), b = Noisy(ShiftImage(left, stable, roi, moving), 4);
  HexMatcherOptions o;
  const HexMatcher matcher(o);
  MatchPrior prior;
  prior.radius = 8.0;          // stable ground: small search around the global shift
  prior.moving_radius = 30.0;  // the landslide: wider
  prior.estimate_global_shift = true;
  prior.moving = [&](const Eigen::Vector2d& x) {
    return x.x() > roi.x - 20 && x.x() < roi.x + roi.width + 20 && x.y() > roi.y - 20 &&
           x.y() < roi.y + roi.height + 20;
  };
  const HexMatchResult r = matcher.Match(a, b, prior);
  EXPECT_LT((r.summary.global_shift - stable).norm(), 0.2);
  int in_moving = 0, correct_moving = 0, correct = 0;
  for (const HexMatch& m : r.matches) {
    const bool mv = roi.contains(cv::Point(int(m.xa.x() + 6), int(m.xa.y() + 6))) &&
                    roi.contains(cv::Point(int(m.xa.x() - 6), int(m.xa.y() - 6)));
    const Eigen::Vector2d truth = mv ? moving : stable;
    const bool ok = (m.xb - m.xa - truth).norm() < 0.2;
    correct += ok;
    if (mv) {
      ++in_moving;
      correct_moving += ok;
    }
  }
  std::printf("epochs: %d matches (%d correct), %d inside the moving area (%d correct)\n",
              r.summary.matched, correct, in_moving, correct_moving);
  EXPECT_GT(in_moving, 15);
  EXPECT_GE(correct_moving, 0.95 * in_moving);
}

TEST(HexMatcher, ConesWithEpipolarPriorAgainstGroundTruth) {
  const cv::Mat left = LoadCones("left.tif"), right = LoadCones("right.tif");
  const cv::Mat gt = LoadCones("disp_left_gt.tif"), occl = LoadCones("occl.png");
  HexMatcherOptions o;
  o.lsc.model = LscModel::kShift;
  const HexMatcher matcher(o);
  MatchPrior prior;
  prior.shift = Eigen::Vector2d(-35, 0);  // disparities 0..~60 px
  prior.radius = 36;
  prior.has_epipolar = true;
  prior.fundamental << 0, 0, 0, 0, 0, -1, 0, 1, 0;  // rectified: yb = ya
  prior.epipolar_band = 1.5;
  const HexMatchResult r = matcher.Match(left, right, prior);
  int valid = 0, w05 = 0, w1 = 0;
  for (const HexMatch& m : r.matches) {
    const int c = int(m.xa.x()), rr = int(m.xa.y());
    const float d = gt.at<float>(rr, c);
    if (d <= 0 || occl.at<uint8_t>(rr, c) == 0) continue;
    ++valid;
    const double e = std::fabs(m.xa.x() - m.xb.x() - d);
    w05 += e <= 0.5;
    w1 += e <= 1.0;
  }
  std::printf(
      "Cones hex+LSC: %d matches, %d non-occluded with truth: %.1f %% within 0.5 px, %.1f %% "
      "within 1 px\n",
      r.summary.matched, valid, 100.0 * w05 / valid, 100.0 * w1 / valid);
  for (const auto& kv : r.summary.rejects)
    std::printf("  reject %s: %d\n", kv.first.c_str(), kv.second);
  EXPECT_GT(valid, 50);
  // Measured 87.2 % within 0.5 px, 91.5 % within 1 px (bicubic eq. 1).
  EXPECT_GT(double(w05) / valid, 0.8);
  EXPECT_GT(double(w1) / valid, 0.85);
}

// Quality control on an occluder: image b is image a shifted by a known
// amount t, except for an object in front (a square of texture taken from
// the right image) that sways by another (4, 3) px between the images and
// whose texture changes by a quarter (blended with a second piece, like
// leaves in the wind; with half of it changed the descriptor search finds
// no candidates on the object at all, which is the easy case). Truth: matches whose xa lies on the
// object in a, or whose true position xa + t lies on the object in b (background hidden), are
// unmatchable and must not have normal quality; windows reaching the object
// must not be wrong with normal quality; the rest keeps its matches. With
// quality.reject the flagged matches are dropped.
TEST(HexMatcher, QualityControlFlagsASwayingOccluder) {
  const cv::Mat left = GaussianBlur(ToFloat(LoadCones("left.tif")), 0.7);
  const cv::Mat right = GaussianBlur(ToFloat(LoadCones("right.tif")), 0.7);
  const Eigen::Vector2d t(7.3, -4.6);
  const cv::Rect in_a(180, 140, 80, 80), in_b(180 + 7 + 4, 140 - 5 + 3, 80, 80);
  const cv::Mat piece = right(cv::Rect(120, 120, 80, 80)).t();
  const cv::Mat other = right(cv::Rect(280, 220, 80, 80)).t();
  cv::Mat a_clean = left.clone(), b_clean = ShiftImage(left, t);
  piece.copyTo(a_clean(in_a));
  cv::Mat changed = 0.75 * piece + 0.25 * other;
  changed.copyTo(b_clean(in_b));
  const cv::Mat a = Noisy(a_clean, 1), b = Noisy(b_clean, 2);
  HexMatcherOptions o;
  const HexMatcher matcher(o);
  const HexMatchResult r = matcher.Match(a, b, MatchPrior());
  const int h = o.lsc.half_window;
  auto in = [](const cv::Rect& rc, const Eigen::Vector2d& x, int margin) {
    return x.x() >= rc.x - margin && x.y() >= rc.y - margin && x.x() <= rc.br().x - 1 + margin &&
           x.y() <= rc.br().y - 1 + margin;
  };
  int on = 0, on_normal = 0, near = 0, near_normal_wrong = 0, clear = 0, clear_normal = 0,
      clear_normal_correct = 0;
  for (const HexMatch& m : r.matches) {
    const Eigen::Vector2d xt = m.xa + t;
    const double e = (m.xb - xt).norm();
    if (in(in_a, m.xa, 0) || in(in_b, xt, 0)) {
      ++on;
      if (!m.IsLowQuality()) ++on_normal;
    } else if (in(in_a, m.xa, h + 1) || in(in_b, xt, h + 1)) {
      ++near;
      if (!m.IsLowQuality() && e > 0.5) ++near_normal_wrong;
    } else {
      ++clear;
      if (!m.IsLowQuality()) {
        ++clear_normal;
        if (e < 0.2) ++clear_normal_correct;
      }
    }
  }
  std::printf("swaying occluder: %d matches (%d low quality", r.summary.matched,
              r.summary.low_quality);
  for (const auto& kv : r.summary.flags) std::printf(", %s %d", kv.first.c_str(), kv.second);
  for (const auto& kv : r.summary.rejects)
    std::printf("; reject %s %d", kv.first.c_str(), kv.second);
  std::printf(
      ")\n  on the object or hidden by it %d (%d normal quality), window reaching it %d (%d normal "
      "quality "
      "> 0.5 px off), clear %d (%d normal quality, %d of them within 0.2 px)\n",
      on, on_normal, near, near_normal_wrong, clear, clear_normal, clear_normal_correct);
  EXPECT_GT(on, 3);  // the matcher does find candidates on the object
  EXPECT_EQ(on_normal, 0);
  EXPECT_EQ(near_normal_wrong, 0);
  EXPECT_GT(clear, 100);
  EXPECT_GE(clear_normal, 0.9 * clear);
  EXPECT_GE(clear_normal_correct, 0.97 * clear_normal);
  // Flagged matches carry quality <= kLowQuality, the others more.
  for (const HexMatch& m : r.matches) {
    if (m.IsLowQuality()) {
      EXPECT_LE(m.quality, kLowQuality);
    } else {
      EXPECT_GT(m.quality, kLowQuality);
    }
  }
  // quality.reject: the same matches without the flagged ones.
  HexMatcherOptions rej = o;
  rej.quality.reject = true;
  const HexMatchResult rr = HexMatcher(rej).Match(a, b, MatchPrior());
  EXPECT_EQ(rr.summary.matched, r.summary.matched - r.summary.low_quality);
  if (r.summary.low_quality > 0) {
    EXPECT_EQ(rr.summary.rejects.at("low_quality"), r.summary.low_quality);
  }
  for (const HexMatch& m : rr.matches) EXPECT_FALSE(m.IsLowQuality());
}

TEST(HexMatcher, BadInput) {
  const HexMatcher matcher{HexMatcherOptions()};
  const cv::Mat a(60, 80, CV_8U, cv::Scalar(5));
  EXPECT_THROW(matcher.Match(a, cv::Mat(60, 81, CV_8U), MatchPrior()), InvalidArgument);
  EXPECT_THROW(matcher.Match(a, cv::Mat(60, 80, CV_16U), MatchPrior()), InvalidArgument);
  EXPECT_THROW(matcher.Match(a, cv::Mat(60, 80, CV_8UC3), MatchPrior()), InvalidArgument);
  // Textureless: no matches, no crash.
  const HexMatchResult r = matcher.Match(a, a, MatchPrior());
  EXPECT_EQ(r.summary.matched, 0);
  EXPECT_FALSE(r.summary.IsSolutionUsable());
  HexMatcherOptions bad;
  bad.max_ratio = 0;
  EXPECT_THROW(HexMatcher{bad}, ConfigError);
  HexMatcherOptions bad_quality;
  bad_quality.quality.max_residual_ratio = 0.5;  // must be > 1
  try {
    HexMatcher{bad_quality};
    ADD_FAILURE() << "quality.max_residual_ratio 0.5 accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("quality.max_residual_ratio"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
