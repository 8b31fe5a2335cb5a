#include "slope_monitor/core/matching/filters.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace matching {

namespace {

void CheckSigma(double sigma, const char* what) {
  if (!(sigma > 0.0) || !std::isfinite(sigma)) {
    throw InvalidArgument(Message(what, ": sigma must be a finite value > 0, got ", sigma));
  }
}

int KernelRadius(double sigma) {
  return std::max(1, static_cast<int>(std::ceil(kTruncation * sigma)));
}

cv::Mat SepFilter(const cv::Mat& image, const std::vector<float>& kx,
                  const std::vector<float>& ky) {
  cv::Mat out;
  cv::sepFilter2D(image, out, CV_32F, cv::Mat(kx, false), cv::Mat(ky, false), cv::Point(-1, -1),
                  0.0, cv::BORDER_REFLECT_101);
  return out;
}

inline int Clamp(int v, int hi) { return v < 0 ? 0 : (v > hi ? hi : v); }

// Keys' cubic convolution kernel (a = -0.5) and its derivative.
constexpr float kKeysA = -0.5f;
inline float Keys(float d) {
  const float ad = std::fabs(d);
  if (ad <= 1.0f) return ((kKeysA + 2.0f) * ad - (kKeysA + 3.0f)) * ad * ad + 1.0f;
  if (ad < 2.0f) return ((kKeysA * ad - 5.0f * kKeysA) * ad + 8.0f * kKeysA) * ad - 4.0f * kKeysA;
  return 0.0f;
}
inline float KeysDerivative(float d) {
  const float ad = std::fabs(d);
  const float s = d < 0.0f ? -1.0f : 1.0f;
  if (ad <= 1.0f) return s * (3.0f * (kKeysA + 2.0f) * ad * ad - 2.0f * (kKeysA + 3.0f) * ad);
  if (ad < 2.0f) return s * (3.0f * kKeysA * ad * ad - 10.0f * kKeysA * ad + 8.0f * kKeysA);
  return 0.0f;
}

void CheckSampleImage(const cv::Mat& image) {
  if (image.type() != CV_32FC1 || image.empty()) {
    throw InvalidArgument(
        Message("sampling: image must be non-empty CV_32FC1, got type ", image.type()));
  }
}

}  // namespace

Interpolation InterpolationFromName(const std::string& name) {
  if (name == "bilinear") return Interpolation::kBilinear;
  if (name == "bicubic") return Interpolation::kBicubic;
  throw InvalidArgument(
      Message("interpolation '", name, "' unknown (use 'bilinear' or 'bicubic')"));
}

const char* InterpolationName(Interpolation interpolation) {
  return interpolation == Interpolation::kBilinear ? "bilinear" : "bicubic";
}

cv::Mat ToFloat(const cv::Mat& image, const char* what) {
  if (image.empty()) throw InvalidArgument(Message(what, ": image is empty"));
  if (image.channels() != 1) {
    throw InvalidArgument(
        Message(what, ": expected a single-channel image, got ", image.channels(), " channels"));
  }
  const int depth = image.depth();
  if (depth == CV_32F) return image;
  if (depth != CV_8U && depth != CV_16U && depth != CV_64F) {
    throw InvalidArgument(
        Message(what, ": unsupported pixel depth ", depth, " (use 8U, 16U, 32F or 64F)"));
  }
  cv::Mat out;
  image.convertTo(out, CV_32F);
  return out;
}

std::vector<float> GaussianKernel(double sigma) {
  CheckSigma(sigma, "GaussianKernel");
  const int r = KernelRadius(sigma);
  std::vector<double> k(2 * r + 1);
  double sum = 0.0;
  for (int i = -r; i <= r; ++i) {
    k[i + r] = std::exp(-0.5 * i * i / (sigma * sigma));
    sum += k[i + r];
  }
  std::vector<float> out(k.size());
  for (size_t i = 0; i < k.size(); ++i) out[i] = static_cast<float>(k[i] / sum);
  return out;
}

std::vector<float> GaussianSecondDerivativeKernel(double sigma) {
  CheckSigma(sigma, "GaussianSecondDerivativeKernel");
  const int r = KernelRadius(sigma);
  const double s2 = sigma * sigma;
  std::vector<double> g(2 * r + 1);
  double sum_g = 0.0;
  for (int i = -r; i <= r; ++i) {
    g[i + r] = std::exp(-0.5 * i * i / s2);
    sum_g += g[i + r];
  }
  for (double& v : g) v /= sum_g;
  // k = (x^2 / s^4 - c) g with c making the sum zero, then scaled so that
  // sum x^2 k = 2 (second derivative of x^2).
  double m2 = 0.0;
  for (int i = -r; i <= r; ++i) m2 += double(i) * i * g[i + r];
  const double c = m2 / (s2 * s2);
  std::vector<double> k(g.size());
  double moment = 0.0;
  for (int i = -r; i <= r; ++i) {
    k[i + r] = (double(i) * i / (s2 * s2) - c) * g[i + r];
    moment += double(i) * i * k[i + r];
  }
  std::vector<float> out(k.size());
  for (size_t i = 0; i < k.size(); ++i) out[i] = static_cast<float>(k[i] * 2.0 / moment);
  return out;
}

cv::Mat GaussianBlur(const cv::Mat& image, double sigma) {
  const cv::Mat f = ToFloat(image, "GaussianBlur");
  const std::vector<float> g = GaussianKernel(sigma);
  return SepFilter(f, g, g);
}

cv::Mat LaplacianOfGaussian(const cv::Mat& image, double sigma, bool scale_normalised) {
  const cv::Mat f = ToFloat(image, "LaplacianOfGaussian");
  const std::vector<float> g = GaussianKernel(sigma);
  const std::vector<float> g2 = GaussianSecondDerivativeKernel(sigma);
  cv::Mat out = SepFilter(f, g2, g) + SepFilter(f, g, g2);
  if (scale_normalised) out *= -(sigma * sigma);
  return out;
}

double LogSigmaForPeakFrequency(double omega) {
  if (!(omega > 0.0) || !std::isfinite(omega)) {
    throw InvalidArgument(Message("LogSigmaForPeakFrequency: omega must be > 0, got ", omega));
  }
  return std::sqrt(2.0) / omega;
}

Gradients SobelGradients(const cv::Mat& image) {
  const cv::Mat f = ToFloat(image, "SobelGradients");
  Gradients g;
  cv::Sobel(f, g.gx, CV_32F, 1, 0, 3, 1.0 / 8.0, 0.0, cv::BORDER_REFLECT_101);
  cv::Sobel(f, g.gy, CV_32F, 0, 1, 3, 1.0 / 8.0, 0.0, cv::BORDER_REFLECT_101);
  cv::magnitude(g.gx, g.gy, g.magnitude);
  return g;
}

cv::Mat ZeroCrossings(const cv::Mat& signed_image, double min_contrast) {
  const cv::Mat f = ToFloat(signed_image, "ZeroCrossings");
  if (!(min_contrast >= 0.0)) {
    throw InvalidArgument(Message("ZeroCrossings: min_contrast must be >= 0, got ", min_contrast));
  }
  cv::Mat mask(f.size(), CV_8U, cv::Scalar(0));
  const int rows = f.rows, cols = f.cols;
  auto crosses = [min_contrast](float a, float b) {
    const bool opposite =
        (a > 0.0f && b < 0.0f) || (a < 0.0f && b > 0.0f) || (a == 0.0f) != (b == 0.0f);
    return opposite && std::fabs(a - b) >= min_contrast;
  };
  auto mark = [&](int r0, int c0, int r1, int c1) {
    const float a = f.at<float>(r0, c0), b = f.at<float>(r1, c1);
    if (!crosses(a, b)) return;
    int r = r0, c = c0;
    if (std::fabs(b) < std::fabs(a)) {
      r = r1;
      c = c1;
    }
    if (r > 0 && c > 0 && r < rows - 1 && c < cols - 1) mask.at<uint8_t>(r, c) = 255;
  };
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      if (c + 1 < cols) mark(r, c, r, c + 1);
      if (r + 1 < rows) mark(r, c, r + 1, c);
    }
  }
  return mask;
}

bool CanSample(const cv::Mat& image, double x, double y, Interpolation interpolation) {
  const double m = interpolation == Interpolation::kBilinear ? 0.0 : 1.0;
  return x >= m && y >= m && x <= image.cols - 1 - m && y <= image.rows - 1 - m;
}

float SampleBilinearGrad(const cv::Mat& image, double x, double y, float* dx, float* dy) {
  CheckSampleImage(image);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float tx = static_cast<float>(x - x0), ty = static_cast<float>(y - y0);
  const int cm = image.cols - 1, rm = image.rows - 1;
  const int xa = Clamp(x0, cm), xb = Clamp(x0 + 1, cm), ya = Clamp(y0, rm), yb = Clamp(y0 + 1, rm);
  const float* ra = image.ptr<float>(ya);
  const float* rb = image.ptr<float>(yb);
  const float i00 = ra[xa], i10 = ra[xb], i01 = rb[xa], i11 = rb[xb];
  if (dx) *dx = (1.0f - ty) * (i10 - i00) + ty * (i11 - i01);
  if (dy) *dy = (1.0f - tx) * (i01 - i00) + tx * (i11 - i10);
  return (1.0f - ty) * ((1.0f - tx) * i00 + tx * i10) + ty * ((1.0f - tx) * i01 + tx * i11);
}

float SampleBilinear(const cv::Mat& image, double x, double y) {
  return SampleBilinearGrad(image, x, y, nullptr, nullptr);
}

float SampleBicubicGrad(const cv::Mat& image, double x, double y, float* dx, float* dy) {
  CheckSampleImage(image);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float tx = static_cast<float>(x - x0), ty = static_cast<float>(y - y0);
  const int cm = image.cols - 1, rm = image.rows - 1;
  float wx[4], wy[4], dwx[4], dwy[4];
  int xs[4], ys[4];
  for (int i = 0; i < 4; ++i) {
    const float ddx = tx - static_cast<float>(i - 1);
    const float ddy = ty - static_cast<float>(i - 1);
    wx[i] = Keys(ddx);
    wy[i] = Keys(ddy);
    dwx[i] = KeysDerivative(ddx);
    dwy[i] = KeysDerivative(ddy);
    xs[i] = Clamp(x0 + i - 1, cm);
    ys[i] = Clamp(y0 + i - 1, rm);
  }
  float value = 0.0f, gx = 0.0f, gy = 0.0f;
  for (int j = 0; j < 4; ++j) {
    const float* row = image.ptr<float>(ys[j]);
    float rv = 0.0f, rd = 0.0f;
    for (int i = 0; i < 4; ++i) {
      const float v = row[xs[i]];
      rv += wx[i] * v;
      rd += dwx[i] * v;
    }
    value += wy[j] * rv;
    gx += wy[j] * rd;
    gy += dwy[j] * rv;
  }
  if (dx) *dx = gx;
  if (dy) *dy = gy;
  return value;
}

float SampleBicubic(const cv::Mat& image, double x, double y) {
  // The value part of SampleBicubicGrad (same operations in the same order:
  // identical results) without the derivative weights and sums, the LSC's
  // inner loop.
  CheckSampleImage(image);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float tx = static_cast<float>(x - x0), ty = static_cast<float>(y - y0);
  const int cm = image.cols - 1, rm = image.rows - 1;
  float wx[4], wy[4];
  if (x0 >= 1 && y0 >= 1 && x0 + 2 <= cm && y0 + 2 <= rm) {
    // Inside: no clamping, rows read through one pointer (same weights and
    // sums as below).
    for (int i = 0; i < 4; ++i) {
      wx[i] = Keys(tx - static_cast<float>(i - 1));
      wy[i] = Keys(ty - static_cast<float>(i - 1));
    }
    const float* row = image.ptr<float>(y0 - 1) + (x0 - 1);
    const size_t step = image.step1();
    float value = 0.0f;
    for (int j = 0; j < 4; ++j, row += step) {
      float rv = 0.0f;
      for (int i = 0; i < 4; ++i) rv += wx[i] * row[i];
      value += wy[j] * rv;
    }
    return value;
  }
  int xs[4];
  for (int i = 0; i < 4; ++i) {
    wx[i] = Keys(tx - static_cast<float>(i - 1));
    wy[i] = Keys(ty - static_cast<float>(i - 1));
    xs[i] = Clamp(x0 + i - 1, cm);
  }
  float value = 0.0f;
  for (int j = 0; j < 4; ++j) {
    const float* row = image.ptr<float>(Clamp(y0 + j - 1, rm));
    float rv = 0.0f;
    for (int i = 0; i < 4; ++i) rv += wx[i] * row[xs[i]];
    value += wy[j] * rv;
  }
  return value;
}

void SampleWindow(const cv::Mat& image, double x, double y, int half, Interpolation interpolation,
                  double* out) {
  CheckSampleImage(image);
  if (half < 0 || !CanSample(image, x - half, y - half, interpolation) ||
      !CanSample(image, x + half, y + half, interpolation)) {
    throw InvalidArgument(Message("SampleWindow: window of half size ", half, " at (", x, ", ", y,
                                  ") not inside the ", image.cols, " x ", image.rows, " image"));
  }
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const float tx = static_cast<float>(x - x0), ty = static_cast<float>(y - y0);
  const size_t step = image.step1();
  const int w = 2 * half + 1;
  if (interpolation == Interpolation::kBilinear) {
    // At the image's last row or column the weight of the next one is 0.
    const int cm = image.cols - 1, rm = image.rows - 1;
    for (int v = 0; v < w; ++v) {
      const int ya = y0 - half + v, yb = std::min(ya + 1, rm);
      const float* ra = image.ptr<float>(ya);
      const float* rb = image.ptr<float>(yb);
      for (int u = 0; u < w; ++u) {
        const int xa = x0 - half + u, xb = std::min(xa + 1, cm);
        *out++ = (1.0f - ty) * ((1.0f - tx) * ra[xa] + tx * ra[xb]) +
                 ty * ((1.0f - tx) * rb[xa] + tx * rb[xb]);
      }
    }
    return;
  }
  float wx[4], wy[4];
  for (int i = 0; i < 4; ++i) {
    wx[i] = Keys(tx - static_cast<float>(i - 1));
    wy[i] = Keys(ty - static_cast<float>(i - 1));
  }
  const float* origin = image.ptr<float>(y0 - half - 1) + (x0 - half - 1);
  for (int v = 0; v < w; ++v) {
    for (int u = 0; u < w; ++u) {
      const float* row = origin + v * step + u;
      float value = 0.0f;
      for (int j = 0; j < 4; ++j, row += step) {
        float rv = 0.0f;
        for (int i = 0; i < 4; ++i) rv += wx[i] * row[i];
        value += wy[j] * rv;
      }
      *out++ = value;
    }
  }
}

float Sample(const cv::Mat& image, double x, double y, Interpolation interpolation) {
  return interpolation == Interpolation::kBilinear ? SampleBilinear(image, x, y)
                                                   : SampleBicubic(image, x, y);
}

float SampleGrad(const cv::Mat& image, double x, double y, Interpolation interpolation, float* dx,
                 float* dy) {
  return interpolation == Interpolation::kBilinear ? SampleBilinearGrad(image, x, y, dx, dy)
                                                   : SampleBicubicGrad(image, x, y, dx, dy);
}

}  // namespace matching
}  // namespace slope_monitor
