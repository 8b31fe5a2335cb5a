// Filters checked against hand-computable values: constants, ramps,
// quadratics, a cosine at the LoG's peak frequency, a step edge.
#include "slope_monitor/core/matching/filters.h"

#include <cmath>
#include <numeric>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace matching {
namespace {

cv::Mat Ramp(int rows, int cols, double a, double b, double c0) {
  cv::Mat m(rows, cols, CV_32F);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) m.at<float>(r, c) = static_cast<float>(a * c + b * r + c0);
  return m;
}

TEST(Filters, KernelsHaveTheirMoments) {
  for (double s : {0.7, 1.0, 2.0, 3.5}) {
    const auto g = GaussianKernel(s);
    const auto g2 = GaussianSecondDerivativeKernel(s);
    ASSERT_EQ(g.size(), g2.size());
    const int r = static_cast<int>(g.size() / 2);
    double sg = 0, sg2 = 0, m2 = 0;
    for (int i = -r; i <= r; ++i) {
      sg += g[i + r];
      sg2 += g2[i + r];
      m2 += double(i) * i * g2[i + r];
    }
    EXPECT_NEAR(sg, 1.0, 1e-6);
    EXPECT_NEAR(sg2, 0.0, 1e-6);
    EXPECT_NEAR(m2, 2.0, 1e-5);
  }
  EXPECT_THROW(GaussianKernel(0.0), InvalidArgument);
  EXPECT_THROW(GaussianKernel(-1.0), InvalidArgument);
}

TEST(Filters, GaussianKeepsConstantsAndRamps) {
  const cv::Mat ramp = Ramp(40, 50, 0.5, -0.25, 10.0);
  const cv::Mat b = GaussianBlur(ramp, 2.0);
  // Interior (away from the reflected border) is unchanged by a symmetric kernel.
  for (int r = 10; r < 30; ++r)
    for (int c = 10; c < 40; ++c) EXPECT_NEAR(b.at<float>(r, c), ramp.at<float>(r, c), 1e-4);
}

TEST(Filters, LogOfQuadraticIsItsLaplacian) {
  // I = x^2 + 3 y^2 -> Laplacian = 2 + 6 = 8; scale-normalised: -s^2 * 8.
  cv::Mat q(60, 60, CV_32F);
  for (int r = 0; r < 60; ++r)
    for (int c = 0; c < 60; ++c)
      q.at<float>(r, c) = float((c - 30) * (c - 30) + 3 * (r - 30) * (r - 30));
  const double s = 2.0;
  const cv::Mat plain = LaplacianOfGaussian(q, s, false);
  const cv::Mat norm = LaplacianOfGaussian(q, s, true);
  EXPECT_NEAR(plain.at<float>(30, 30), 8.0, 1e-2);
  EXPECT_NEAR(plain.at<float>(25, 33), 8.0, 1e-2);
  EXPECT_NEAR(norm.at<float>(30, 30), -8.0 * s * s, 4e-2);
  // A constant gives zero.
  const cv::Mat k(30, 30, CV_8U, cv::Scalar(77));
  const cv::Mat lk = LaplacianOfGaussian(k, 1.5);
  double mn, mx;
  cv::minMaxLoc(lk, &mn, &mx);
  EXPECT_LT(std::max(std::fabs(mn), std::fabs(mx)), 1e-3);
}

TEST(Filters, LogGainAtPeakFrequencyIsTwoOverE) {
  for (double omega : {1.0, 0.5}) {
    const double s = LogSigmaForPeakFrequency(omega);
    EXPECT_NEAR(s, std::sqrt(2.0) / omega, 1e-12);
    cv::Mat cosine(80, 160, CV_32F);
    for (int r = 0; r < 80; ++r)
      for (int c = 0; c < 160; ++c) cosine.at<float>(r, c) = float(std::cos(omega * c));
    const cv::Mat l = LaplacianOfGaussian(cosine, s);
    // Gain at the peak: 2/e; the sampled kernel differs by a few per cent at omega = 1.
    const int c0 = 80;
    const double gain = l.at<float>(40, c0) / std::cos(omega * c0);
    EXPECT_NEAR(gain, 2.0 / std::exp(1.0), 0.03) << "omega " << omega;
    // Off-peak gain is lower.
    cv::Mat slow(80, 160, CV_32F);
    for (int r = 0; r < 80; ++r)
      for (int c = 0; c < 160; ++c) slow.at<float>(r, c) = float(std::cos(0.3 * omega * c));
    const cv::Mat ls = LaplacianOfGaussian(slow, s);
    EXPECT_LT(std::fabs(ls.at<float>(40, c0) / std::cos(0.3 * omega * c0)), gain);
  }
}

TEST(Filters, SobelOfRampIsItsSlope) {
  const Gradients g = SobelGradients(Ramp(20, 20, 3.0, -4.0, 1.0));
  EXPECT_NEAR(g.gx.at<float>(10, 10), 3.0, 1e-5);
  EXPECT_NEAR(g.gy.at<float>(10, 10), -4.0, 1e-5);
  EXPECT_NEAR(g.magnitude.at<float>(10, 10), 5.0, 1e-5);
}

TEST(Filters, ZeroCrossingsOfAStepFollowTheEdge) {
  cv::Mat step(40, 40, CV_32F, cv::Scalar(10.0f));
  step.colRange(20, 40).setTo(110.0f);  // edge between columns 19 and 20
  const cv::Mat l = LaplacianOfGaussian(step, 2.0);
  const cv::Mat z = ZeroCrossings(l, 1.0);
  for (int r = 5; r < 35; ++r) {
    int count = 0, col = -1;
    for (int c = 1; c < 39; ++c)
      if (z.at<uint8_t>(r, c)) {
        ++count;
        col = c;
      }
    EXPECT_EQ(count, 1) << "row " << r;
    EXPECT_TRUE(col == 19 || col == 20) << "row " << r << " col " << col;
  }
  // A high contrast threshold removes it.
  EXPECT_EQ(cv::countNonZero(ZeroCrossings(l, 1e6)), 0);
}

TEST(Filters, BilinearIsExactOnRampsBicubicOnQuadratics) {
  const cv::Mat ramp = Ramp(20, 30, 0.7, -1.3, 5.0);
  cv::Mat quad(20, 30, CV_32F);
  for (int r = 0; r < 20; ++r)
    for (int c = 0; c < 30; ++c)
      quad.at<float>(r, c) = float(0.1 * c * c - 0.05 * r * r + 0.02 * r * c);
  for (double x : {3.0, 5.25, 10.5, 17.9}) {
    for (double y : {2.0, 4.6, 11.3}) {
      float dx, dy;
      EXPECT_NEAR(SampleBilinearGrad(ramp, x, y, &dx, &dy), 0.7 * x - 1.3 * y + 5.0, 1e-4);
      EXPECT_NEAR(dx, 0.7, 1e-4);
      EXPECT_NEAR(dy, -1.3, 1e-4);
      EXPECT_NEAR(SampleBicubicGrad(quad, x, y, &dx, &dy),
                  0.1 * x * x - 0.05 * y * y + 0.02 * x * y, 1e-3);
      EXPECT_NEAR(dx, 0.2 * x + 0.02 * y, 1e-3);
      EXPECT_NEAR(dy, -0.1 * y + 0.02 * x, 1e-3);
      EXPECT_NEAR(Sample(ramp, x, y, Interpolation::kBicubic), 0.7 * x - 1.3 * y + 5.0, 1e-4);
    }
  }
  EXPECT_TRUE(CanSample(ramp, 0.0, 0.0, Interpolation::kBilinear));
  EXPECT_FALSE(CanSample(ramp, 0.5, 0.5, Interpolation::kBicubic));
  EXPECT_FALSE(CanSample(ramp, 29.5, 3.0, Interpolation::kBilinear));
  EXPECT_EQ(InterpolationFromName("bicubic"), Interpolation::kBicubic);
  EXPECT_THROW(InterpolationFromName("nearest"), InvalidArgument);
}

// The window sampler (one set of weights for the window) gives each pixel the
// point sampler's value, on a quadratic (bicubic exact) and on noise, up to
// the last bits of the float sub-pixel offset; at the image border it refuses
// the window, naming it.
TEST(Filters, SampleWindowEqualsThePointSampler) {
  cv::Mat quad(40, 50, CV_32F), noise(40, 50, CV_32F);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0.0, 255.0);
  for (int r = 0; r < 40; ++r)
    for (int c = 0; c < 50; ++c)
      quad.at<float>(r, c) = float(0.1 * c * c - 0.05 * r * r + 0.02 * r * c);
  const int h = 5, w = 2 * h + 1;
  std::vector<double> out(w * w);
  for (const Interpolation interp : {Interpolation::kBicubic, Interpolation::kBilinear}) {
    for (const cv::Mat* image : {&quad, &noise}) {
      for (const auto& [x, y] :
           std::vector<std::pair<double, double>>{{20.0, 17.0}, {21.37, 13.81}, {7.5, 30.25}}) {
        SampleWindow(*image, x, y, h, interp, out.data());
        for (int v = -h, k = 0; v <= h; ++v)
          for (int u = -h; u <= h; ++u, ++k)
            EXPECT_NEAR(out[k], Sample(*image, x + u, y + v, interp), 1e-3)
                << "(" << x << ", " << y << ") + (" << u << ", " << v << ")";
      }
    }
    // Hand value: the quadratic at (21.37 + 2, 13.81 - 1).
    SampleWindow(quad, 21.37, 13.81, h, Interpolation::kBicubic, out.data());
    const double x = 23.37, y = 12.81;
    EXPECT_NEAR(out[(h - 1) * w + (h + 2)], 0.1 * x * x - 0.05 * y * y + 0.02 * x * y, 1e-3);
  }
  // Bicubic needs one pixel more around the window than bilinear.
  EXPECT_THROW(SampleWindow(quad, 5.5, 20.0, h, Interpolation::kBicubic, out.data()),
               InvalidArgument);
  EXPECT_NO_THROW(SampleWindow(quad, 5.5, 20.0, h, Interpolation::kBilinear, out.data()));
  EXPECT_NO_THROW(SampleWindow(quad, 44.0, 20.0, h, Interpolation::kBilinear, out.data()));
  EXPECT_THROW(SampleWindow(quad, 44.5, 20.0, h, Interpolation::kBilinear, out.data()),
               InvalidArgument);
  EXPECT_THROW(
      SampleWindow(cv::Mat(40, 50, CV_8U), 20.0, 20.0, h, Interpolation::kBilinear, out.data()),
      InvalidArgument);
}

TEST(Filters, BadInputIsNamed) {
  EXPECT_THROW(GaussianBlur(cv::Mat(), 1.0), InvalidArgument);
  EXPECT_THROW(GaussianBlur(cv::Mat(5, 5, CV_8UC3), 1.0), InvalidArgument);
  EXPECT_THROW(SampleBilinear(cv::Mat(5, 5, CV_8U), 1.0, 1.0), InvalidArgument);
  EXPECT_THROW(ZeroCrossings(cv::Mat(5, 5, CV_32F, cv::Scalar(0)), -1.0), InvalidArgument);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
