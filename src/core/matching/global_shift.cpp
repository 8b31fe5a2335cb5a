#include "slope_monitor/core/matching/global_shift.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace matching {

void GlobalShiftOptions::Check() const {
  if (max_size < 32 || max_size > 4096) {
    throw ConfigError(
        Message("GlobalShiftOptions.max_size must be in [32, 4096] px, got ", max_size));
  }
  if (!(min_response >= 0.0 && min_response <= 1.0)) {
    throw ConfigError(
        Message("GlobalShiftOptions.min_response must be in [0, 1], got ", min_response));
  }
  if (refine_factor < 1 || refine_factor > 16) {
    throw ConfigError(
        Message("GlobalShiftOptions.refine_factor must be in [1, 16], got ", refine_factor));
  }
  if (!(min_overlap_correlation >= -1.0 && min_overlap_correlation <= 1.0)) {
    throw ConfigError(Message("GlobalShiftOptions.min_overlap_correlation must be in [-1, 1], got ",
                              min_overlap_correlation));
  }
  if (candidates < 1 || candidates > 100) {
    throw ConfigError(
        Message("GlobalShiftOptions.candidates must be in [1, 100], got ", candidates));
  }
  if (!(taper > 0.0 && taper <= 0.5))
    throw ConfigError(Message("GlobalShiftOptions.taper must be in (0, 0.5], got ", taper));
  if (!(min_overlap_fraction >= 0.0 && min_overlap_fraction < 1.0)) {
    throw ConfigError(Message("GlobalShiftOptions.min_overlap_fraction must be in [0, 1), got ",
                              min_overlap_fraction));
  }
  if (min_overlap < 8)
    throw ConfigError(Message("GlobalShiftOptions.min_overlap must be >= 8 px, got ", min_overlap));
}

namespace {

cv::Mat Downsample(const cv::Mat& f, int factor) {
  if (factor == 1) return f;
  cv::Mat out;
  cv::resize(f, out, cv::Size(f.cols / factor, f.rows / factor), 0, 0, cv::INTER_AREA);
  return out;
}

// Phase correlation with a Hanning window: shift of b relative to a (b(x) =
// a(x - d) gives d) in the pixels of the given images.
cv::Point2d Correlate(const cv::Mat& a, const cv::Mat& b, double* response) {
  cv::Mat window;
  cv::createHanningWindow(window, a.size(), CV_32F);
  // Zero-mean copies, so that the window does not correlate with itself.
  cv::Mat za = a - cv::mean(a)[0], zb = b - cv::mean(b)[0];
  return cv::phaseCorrelate(za, zb, window, response);
}

// Tukey window: 1 inside, a Hanning-shaped (raised cosine) fall to 0 over
// the outer `taper` of each side.
cv::Mat TukeyWindow(cv::Size size, double taper) {
  auto profile = [taper](int n) {
    std::vector<float> w(n, 1.0f);
    const int m = std::max(1, static_cast<int>(taper * n));
    for (int i = 0; i < m && i < n; ++i) {
      const float v = static_cast<float>(0.5 * (1.0 - std::cos(M_PI * (i + 0.5) / m)));
      w[i] = std::min(w[i], v);
      w[n - 1 - i] = std::min(w[n - 1 - i], v);
    }
    return w;
  };
  const std::vector<float> wx = profile(size.width), wy = profile(size.height);
  cv::Mat w(size, CV_32F);
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c) w.at<float>(r, c) = wx[c] * wy[r];
  return w;
}

// Phase-correlation surface of a and b (Tukey window, zero-mean copies):
// the inverse DFT of the normalised cross-power spectrum B conj(A), whose
// peak lies at d where b(x) = a(x - d) (cyclic: d modulo the size).
// Returns its `count` highest local maxima (sub-pixel by the 3 x 3 centroid),
// highest first; *surface_peak_value their values.
struct Peak {
  Eigen::Vector2d d;
  double value;
};
std::vector<Peak> CorrelationPeaks(const cv::Mat& a, const cv::Mat& b, double taper, int count) {
  const cv::Mat w = TukeyWindow(a.size(), taper);
  cv::Mat za = (a - cv::mean(a)[0]).mul(w), zb = (b - cv::mean(b)[0]).mul(w);
  cv::Mat fa, fb, cross;
  cv::dft(za, fa, cv::DFT_COMPLEX_OUTPUT);
  cv::dft(zb, fb, cv::DFT_COMPLEX_OUTPUT);
  cv::mulSpectrums(fb, fa, cross, 0, true);
  std::vector<cv::Mat> ri;
  cv::split(cross, ri);
  cv::Mat mag;
  cv::magnitude(ri[0], ri[1], mag);
  mag += 1e-12;
  ri[0] /= mag;
  ri[1] /= mag;
  cv::merge(ri, cross);
  cv::Mat surface;
  cv::idft(cross, surface, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  std::vector<Peak> peaks;
  cv::Mat work = surface.clone();
  const int rows = surface.rows, cols = surface.cols;
  for (int k = 0; k < count; ++k) {
    double value = 0;
    cv::Point p;
    cv::minMaxLoc(work, nullptr, &value, nullptr, &p);
    if (!(value > 0)) break;
    double sw = 0, sx = 0, sy = 0;
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const float v =
            std::max(0.0f, surface.at<float>((p.y + dy + rows) % rows, (p.x + dx + cols) % cols));
        sw += v;
        sx += v * dx;
        sy += v * dy;
      }
    Eigen::Vector2d d(p.x + sx / sw, p.y + sy / sw);
    // To (-size/2, size/2].
    if (d.x() > cols / 2.0) d.x() -= cols;
    if (d.y() > rows / 2.0) d.y() -= rows;
    peaks.push_back({d, value});
    // Suppress the neighbourhood (cyclic) before the next maximum.
    for (int dy = -3; dy <= 3; ++dy)
      for (int dx = -3; dx <= 3; ++dx)
        work.at<float>((p.y + dy + rows) % rows, (p.x + dx + cols) % cols) = 0.0f;
  }
  return peaks;
}

// NCC of the parts of a and b that overlap under the integer shift (sx, sy)
// (xb = xa + s); -2 when they overlap by less than min_overlap in an axis or
// less than min_fraction of the area.
double OverlapNcc(const cv::Mat& a, const cv::Mat& b, int sx, int sy, int min_overlap,
                  double min_fraction) {
  const int ow = a.cols - std::abs(sx), oh = a.rows - std::abs(sy);
  if (ow < min_overlap || oh < min_overlap) return -2.0;
  if (double(ow) * oh < min_fraction * a.cols * a.rows) return -2.0;
  const cv::Rect ra(std::max(0, -sx), std::max(0, -sy), ow, oh);
  const cv::Rect rb(std::max(0, sx), std::max(0, sy), ow, oh);
  cv::Mat r;
  cv::matchTemplate(a(ra), b(rb), r, cv::TM_CCOEFF_NORMED);
  return r.at<float>(0, 0);
}

}  // namespace

GlobalShiftResult EstimateGlobalShift(const cv::Mat& image_a, const cv::Mat& image_b,
                                      const GlobalShiftOptions& options) {
  options.Check();
  if (image_a.empty() || image_b.empty())
    throw InvalidArgument("EstimateGlobalShift: an input image is empty");
  if (image_a.size() != image_b.size()) {
    throw InvalidArgument(Message("EstimateGlobalShift: images differ in size (a ", image_a.cols,
                                  "x", image_a.rows, ", b ", image_b.cols, "x", image_b.rows, ")"));
  }
  const cv::Mat fa = ToFloat(image_a, "EstimateGlobalShift image a");
  const cv::Mat fb = ToFloat(image_b, "EstimateGlobalShift image b");
  GlobalShiftResult r;
  const int longer = std::max(fa.cols, fa.rows);
  r.factor = std::max(1, (longer + options.max_size - 1) / options.max_size);
  const cv::Mat ca = Downsample(fa, r.factor), cb = Downsample(fb, r.factor);
  if (ca.cols < 8 || ca.rows < 8) {
    r.reason = "image too small";
    return r;
  }
  // Phase correlation is cyclic, and with overlaps below ~50 % (photos two
  // apart, neighbouring strips) the true peak need not be the highest: each
  // of the highest peaks, at d and d - size in each axis, is checked by the
  // NCC of the overlapping parts, and the best-correlating candidate wins.
  const std::vector<Peak> peaks = CorrelationPeaks(ca, cb, options.taper, options.candidates);
  Eigen::Vector2d best = Eigen::Vector2d::Zero();
  double best_ncc = -3.0;
  const int min_coarse = std::max(8, options.min_overlap / r.factor);
  for (const Peak& peak : peaks) {
    for (int kx = -1; kx <= 1; ++kx) {
      for (int ky = -1; ky <= 1; ++ky) {
        const double cx = peak.d.x() + kx * ca.cols, cy = peak.d.y() + ky * ca.rows;
        if (std::fabs(cx) >= ca.cols || std::fabs(cy) >= ca.rows) continue;
        const double ncc =
            OverlapNcc(ca, cb, static_cast<int>(std::lround(cx)), static_cast<int>(std::lround(cy)),
                       min_coarse, options.min_overlap_fraction);
        if (ncc > best_ncc) {
          best_ncc = ncc;
          best = Eigen::Vector2d(cx, cy);
          r.response = peak.value;
        }
      }
    }
  }
  r.shift = best * r.factor;
  r.overlap_correlation = best_ncc;
  if (!std::isfinite(r.response) || !best.allFinite() || r.response < options.min_response) {
    r.reason = Message("phase-correlation peak ", r.response, " below min_response ",
                       options.min_response);
    return r;
  }
  if (!(best_ncc >= options.min_overlap_correlation)) {
    r.reason = Message("overlap correlation ", best_ncc, " below min_overlap_correlation ",
                       options.min_overlap_correlation);
    return r;
  }
  const int sx = static_cast<int>(std::lround(r.shift.x())),
            sy = static_cast<int>(std::lround(r.shift.y()));
  const int ow = fa.cols - std::abs(sx), oh = fa.rows - std::abs(sy);
  if (ow < options.min_overlap || oh < options.min_overlap) {
    r.reason =
        Message("overlap ", ow, "x", oh, " px smaller than min_overlap ", options.min_overlap);
    return r;
  }
  r.usable = true;
  if (!options.refine) return r;
  // Overlap: a point xa of a at xa + s in b.
  const cv::Rect ra(std::max(0, -sx), std::max(0, -sy), ow, oh);
  const cv::Rect rb(std::max(0, sx), std::max(0, sy), ow, oh);
  // Small overlaps are refined at a finer scale (at least 64 px each axis).
  int f = options.refine_factor;
  while (f > 1 && (ow / f < 64 || oh / f < 64)) --f;
  if (ow / f < 16 || oh / f < 16) return r;
  double response = 0;
  const cv::Point2d fine = Correlate(Downsample(fa(ra), f), Downsample(fb(rb), f), &response);
  const Eigen::Vector2d residual = Eigen::Vector2d(fine.x, fine.y) * f;
  // The residual of a correct coarse shift is within a coarse pixel or two.
  if (std::isfinite(response) && residual.allFinite() &&
      residual.cwiseAbs().maxCoeff() <= 2.0 * r.factor) {
    r.shift = Eigen::Vector2d(sx, sy) + residual;
    r.refined = true;
  }
  return r;
}

}  // namespace matching
}  // namespace slope_monitor
