#include "slope_monitor/core/dense/correlation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace dense {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

inline bool Finite(float v) { return v == v; }

void Require(bool ok, const char* key, const std::string& what) {
  if (!ok) throw ConfigError(Message("dense correlation option '", key, "' ", what));
}

// Result of one search direction on one level: dense per-pixel parallax.
struct DenseResult {
  cv::Mat disparity;    // CV_32F level px, NaN invalid
  cv::Mat correlation;  // CV_32F
};

// ZNCC search of `left` against `right` for parallaxes base(x) + k, k in
// [k_min, k_max] (base: per-pixel integer prediction, CV_32S, or empty = 0).
// Masks: CV_8U 1 = content.
DenseResult Search(const cv::Mat& left, const cv::Mat& right, const cv::Mat& base, int k_min, int k_max,
                   int window, double min_correlation, const cv::Mat& mask_left, const cv::Mat& mask_right) {
  const int w = left.cols, h = left.rows;
  const cv::Size box(window, window);
  cv::Mat mean_l, mean_ll;
  cv::boxFilter(left, mean_l, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_REFLECT_101);
  cv::boxFilter(left.mul(left), mean_ll, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_REFLECT_101);
  cv::Mat bad_left;  // fraction of window pixels without content
  cv::Mat inv_left = 1.0f - mask_left;
  cv::boxFilter(inv_left, bad_left, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_CONSTANT);

  const int n = k_max - k_min + 1;
  std::vector<cv::Mat> scores(n);
  cv::Mat warped(h, w, CV_32F), warped_inv(h, w, CV_32F);
  cv::Mat mean_r, mean_rr, mean_lr, bad_right;
  for (int ki = 0; ki < n; ++ki) {
    const int k = k_min + ki;
    for (int y = 0; y < h; ++y) {
      const float* r = right.ptr<float>(y);
      const uchar* mr = mask_right.ptr<uchar>(y);
      const int* b = base.empty() ? nullptr : base.ptr<int>(y);
      float* o = warped.ptr<float>(y);
      float* oi = warped_inv.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        const int xr = x - (b ? b[x] : 0) - k;
        if (xr >= 0 && xr < w) {
          o[x] = r[xr];
          oi[x] = mr[xr] ? 0.0f : 1.0f;
        } else {
          o[x] = 0.0f;
          oi[x] = 1.0f;
        }
      }
    }
    cv::boxFilter(warped, mean_r, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_REFLECT_101);
    cv::boxFilter(warped.mul(warped), mean_rr, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_REFLECT_101);
    cv::boxFilter(warped.mul(left), mean_lr, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_REFLECT_101);
    cv::boxFilter(warped_inv, bad_right, CV_32F, box, cv::Point(-1, -1), true, cv::BORDER_CONSTANT);
    cv::Mat& s = scores[ki];
    s.create(h, w, CV_32F);
    for (int y = 0; y < h; ++y) {
      const float* ml = mean_l.ptr<float>(y);
      const float* mll = mean_ll.ptr<float>(y);
      const float* mr = mean_r.ptr<float>(y);
      const float* mrr = mean_rr.ptr<float>(y);
      const float* mlr = mean_lr.ptr<float>(y);
      const float* bl = bad_left.ptr<float>(y);
      const float* br = bad_right.ptr<float>(y);
      float* so = s.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        const float vl = mll[x] - ml[x] * ml[x];
        const float vr = mrr[x] - mr[x] * mr[x];
        const float den = vl * vr;
        if (bl[x] > 1e-4f || br[x] > 1e-4f || !(den > 1e-12f)) {
          so[x] = -2.0f;
        } else {
          so[x] = (mlr[x] - ml[x] * mr[x]) / std::sqrt(den);
        }
      }
    }
  }

  DenseResult out;
  out.disparity.create(h, w, CV_32F);
  out.correlation.create(h, w, CV_32F);
  for (int y = 0; y < h; ++y) {
    const int* b = base.empty() ? nullptr : base.ptr<int>(y);
    float* d = out.disparity.ptr<float>(y);
    float* c = out.correlation.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      int best = -1;
      float best_s = -2.0f;
      for (int ki = 0; ki < n; ++ki) {
        const float v = scores[ki].at<float>(y, x);
        if (v > best_s) {
          best_s = v;
          best = ki;
        }
      }
      if (best <= 0 || best >= n - 1 || best_s < min_correlation) {
        d[x] = kNaN;
        c[x] = kNaN;
        continue;
      }
      const float sm = scores[best - 1].at<float>(y, x), sp = scores[best + 1].at<float>(y, x);
      float delta = 0.0f;
      const float curv = sm - 2.0f * best_s + sp;
      if (sm > -2.0f && sp > -2.0f && curv < 0.0f) delta = std::clamp(0.5f * (sm - sp) / curv, -0.5f, 0.5f);
      d[x] = static_cast<float>((b ? b[x] : 0) + k_min + best) + delta;
      c[x] = best_s;
    }
  }
  return out;
}

// Grid of nodes (i, j) at level pixel (j * g, i * g).
cv::Mat SampleGrid(const cv::Mat& dense_map, int g) {
  const int ni = (dense_map.rows - 1) / g + 1, nj = (dense_map.cols - 1) / g + 1;
  cv::Mat grid(ni, nj, CV_32F);
  for (int i = 0; i < ni; ++i)
    for (int j = 0; j < nj; ++j) grid.at<float>(i, j) = dense_map.at<float>(i * g, j * g);
  return grid;
}

void MedianFilter(cv::Mat* grid) {
  cv::Mat out = grid->clone();
  float v[9];
  for (int i = 0; i < grid->rows; ++i)
    for (int j = 0; j < grid->cols; ++j) {
      if (!Finite(grid->at<float>(i, j))) continue;
      int n = 0;
      for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
          const int a = i + di, b = j + dj;
          if (a < 0 || b < 0 || a >= grid->rows || b >= grid->cols) continue;
          const float x = grid->at<float>(a, b);
          if (Finite(x)) v[n++] = x;
        }
      std::nth_element(v, v + n / 2, v + n);
      float m = v[n / 2];
      if (n % 2 == 0) m = 0.5f * (m + *std::max_element(v, v + n / 2));
      out.at<float>(i, j) = m;
    }
  *grid = out;
}

// Along each line the matched position x - d must not decrease. Returns the
// number of nodes invalidated.
int OrderCheck(cv::Mat* grid, int g, double tolerance) {
  int rejected = 0;
  std::vector<int> kill;
  for (int i = 0; i < grid->rows; ++i) {
    float* row = grid->ptr<float>(i);
    kill.clear();
    int prev = -1;
    for (int j = 0; j < grid->cols; ++j) {
      if (!Finite(row[j])) continue;
      if (prev >= 0) {
        const double xp = prev * g - row[prev], xc = j * g - row[j];
        if (xc < xp - tolerance) {
          kill.push_back(prev);
          kill.push_back(j);
        }
      }
      prev = j;
    }
    for (int j : kill)
      if (Finite(row[j])) {
        row[j] = kNaN;
        ++rejected;
      }
  }
  return rejected;
}

// Linear look-up of a grid line at fractional node position u.
float LookupLine(const float* row, int cols, double u) {
  if (u < 0 || u > cols - 1) return kNaN;
  const int j0 = std::min(static_cast<int>(u), cols - 1);
  const int j1 = std::min(j0 + 1, cols - 1);
  const float a = row[j0], b = row[j1];
  const double t = u - j0;
  if (Finite(a) && Finite(b)) return static_cast<float>((1 - t) * a + t * b);
  if (Finite(a) && t < 0.5) return a;
  if (Finite(b) && t >= 0.5) return b;
  return kNaN;
}

// Holes interpolated along lines, then along columns, then a constant: used
// only to predict the next level.
cv::Mat FillForPrediction(const cv::Mat& grid, float fallback) {
  cv::Mat out = grid.clone();
  auto fill_line = [](std::vector<float>& v) {
    int last = -1;
    const int n = static_cast<int>(v.size());
    for (int j = 0; j < n; ++j) {
      if (!Finite(v[j])) continue;
      if (last < 0) {
        for (int k = 0; k < j; ++k) v[k] = v[j];
      } else {
        for (int k = last + 1; k < j; ++k) v[k] = v[last] + (v[j] - v[last]) * (k - last) / float(j - last);
      }
      last = j;
    }
    if (last >= 0)
      for (int k = last + 1; k < n; ++k) v[k] = v[last];
    return last >= 0;
  };
  std::vector<char> row_ok(out.rows, 0);
  std::vector<float> line;
  for (int i = 0; i < out.rows; ++i) {
    line.assign(out.ptr<float>(i), out.ptr<float>(i) + out.cols);
    row_ok[i] = fill_line(line);
    if (row_ok[i]) std::copy(line.begin(), line.end(), out.ptr<float>(i));
  }
  for (int j = 0; j < out.cols; ++j) {
    line.resize(out.rows);
    for (int i = 0; i < out.rows; ++i) line[i] = row_ok[i] ? out.at<float>(i, j) : kNaN;
    if (!fill_line(line)) std::fill(line.begin(), line.end(), fallback);
    for (int i = 0; i < out.rows; ++i) out.at<float>(i, j) = line[i];
  }
  return out;
}

// Per-pixel integer base parallax of a level (size) from a filled grid of the
// previous level (spacing g in previous-level px): bilinear, times 2.
cv::Mat PredictBase(const cv::Mat& filled_grid, int g, cv::Size size) {
  cv::Mat base(size, CV_32S);
  for (int y = 0; y < size.height; ++y) {
    const double gi = std::clamp(0.5 * y / g, 0.0, filled_grid.rows - 1.0);
    const int i0 = std::min(static_cast<int>(gi), filled_grid.rows - 1), i1 = std::min(i0 + 1, filled_grid.rows - 1);
    const double ti = gi - i0;
    int* b = base.ptr<int>(y);
    for (int x = 0; x < size.width; ++x) {
      const double gj = std::clamp(0.5 * x / g, 0.0, filled_grid.cols - 1.0);
      const int j0 = std::min(static_cast<int>(gj), filled_grid.cols - 1), j1 = std::min(j0 + 1, filled_grid.cols - 1);
      const double tj = gj - j0;
      const double v = (1 - ti) * ((1 - tj) * filled_grid.at<float>(i0, j0) + tj * filled_grid.at<float>(i0, j1)) +
                       ti * ((1 - tj) * filled_grid.at<float>(i1, j0) + tj * filled_grid.at<float>(i1, j1));
      b[x] = static_cast<int>(std::lround(2.0 * v));
    }
  }
  return base;
}

cv::Mat MaskOrOnes(const cv::Mat& m, cv::Size size, const char* what) {
  if (m.empty()) return cv::Mat(size, CV_8U, cv::Scalar(1));
  if (m.size() != size || m.type() != CV_8U)
    throw InvalidArgument(Message("MatchRectified: ", what, " must be CV_8U of the image size"));
  cv::Mat out;
  cv::compare(m, 0, out, cv::CMP_GT);
  return out / 255;
}

cv::Mat Downsample(const cv::Mat& image, int scale) {
  if (scale == 1) return image.clone();
  cv::Mat out;
  cv::resize(image, out, cv::Size(image.cols / scale, image.rows / scale), 0, 0, cv::INTER_AREA);
  return out;
}

cv::Mat DownsampleMask(const cv::Mat& mask, int scale) {
  if (scale == 1) return mask.clone();
  // A level pixel has content only when all full-resolution pixels under it have.
  cv::Mat f, small;
  mask.convertTo(f, CV_32F);
  cv::resize(f, small, cv::Size(mask.cols / scale, mask.rows / scale), 0, 0, cv::INTER_AREA);
  cv::Mat out;
  cv::compare(small, 0.999, out, cv::CMP_GE);
  return out / 255;
}

}  // namespace

void CorrelationOptions::Check() const {
  Require(levels >= 1 && levels <= 5, "levels", Message("= ", levels, " must be in [1, 5]"));
  Require(peak_frequency > 0 && peak_frequency <= 3, "peak_frequency",
          Message("= ", peak_frequency, " rad/px must be in (0, 3]"));
  Require(grid_spacing >= 1 && grid_spacing <= 64, "grid_spacing", Message("= ", grid_spacing, " must be in [1, 64]"));
  Require(final_grid_spacing >= 1 && final_grid_spacing <= 64, "final_grid_spacing",
          Message("= ", final_grid_spacing, " must be in [1, 64]"));
  Require(window >= 3 && window <= 51 && window % 2 == 1, "window", Message("= ", window, " must be odd in [3, 51]"));
  Require(search_radius >= 1 && search_radius <= 16, "search_radius",
          Message("= ", search_radius, " must be in [1, 16]"));
  Require(std::isfinite(min_disparity) && std::isfinite(max_disparity) && max_disparity > min_disparity,
          "max_disparity", Message("= ", max_disparity, " must be finite and > min_disparity = ", min_disparity));
  Require(min_correlation >= -1 && min_correlation < 1, "min_correlation",
          Message("= ", min_correlation, " must be in [-1, 1)"));
  Require(lr_tolerance > 0, "lr_tolerance", Message("= ", lr_tolerance, " must be > 0"));
  Require(order_tolerance >= 0, "order_tolerance", Message("= ", order_tolerance, " must be >= 0"));
}

std::string CorrelationSummary::BriefReport() const {
  std::ostringstream s;
  s << "dense correlation: " << levels << " levels, " << valid_nodes << "/" << nodes << " nodes valid ("
    << 100.0 * ValidFraction() << "%), rejected: correlation " << rejected_correlation << ", order "
    << rejected_order << ", left/right " << rejected_left_right << ", " << seconds << " s";
  return s.str();
}

ParallaxGrid MatchRectified(const cv::Mat& left_in, const cv::Mat& right_in, const CorrelationOptions& options,
                            CorrelationSummary* summary, const cv::Mat& valid_left, const cv::Mat& valid_right) {
  const auto t0 = std::chrono::steady_clock::now();
  options.Check();
  if (left_in.empty() || right_in.empty()) throw InvalidArgument("MatchRectified: empty image");
  if (left_in.size() != right_in.size())
    throw InvalidArgument(Message("MatchRectified: image sizes differ (", left_in.cols, "x", left_in.rows, " vs ",
                                  right_in.cols, "x", right_in.rows, ")"));
  const cv::Mat left = matching::ToFloat(left_in, "left image");
  const cv::Mat right = matching::ToFloat(right_in, "right image");
  const int coarse = 1 << (options.levels - 1);
  if (left.cols / coarse < options.window || left.rows / coarse < options.window)
    throw InvalidArgument(Message("MatchRectified: image ", left.cols, "x", left.rows, " too small for ",
                                  options.levels, " levels and a ", options.window, " px window"));
  for (const cv::Mat* im : {&left, &right}) {
    cv::Scalar mean, sd;
    cv::meanStdDev(*im, mean, sd);
    if (!(sd[0] > 1e-3))
      throw InvalidArgument(Message("MatchRectified: the ", im == &left ? "left" : "right",
                                    " image has no texture (constant value ", mean[0], ", e.g. all black)"));
  }
  const cv::Mat mask_l = MaskOrOnes(valid_left, left.size(), "valid_left");
  const cv::Mat mask_r = MaskOrOnes(valid_right, right.size(), "valid_right");

  CorrelationSummary sum;
  sum.levels = options.levels;
  cv::Mat pred_left, pred_right;  // filled grids of the previous level
  int prev_g = 0;
  cv::Mat final_grid, final_corr;
  const int half = options.window / 2;
  (void)half;
  for (int k = 0; k < options.levels; ++k) {
    const int scale = 1 << (options.levels - 1 - k);
    const bool last = (k == options.levels - 1);
    const int g = last ? options.final_grid_spacing : options.grid_spacing;
    const double sigma = matching::LogSigmaForPeakFrequency(options.peak_frequency);
    const cv::Mat l = matching::LaplacianOfGaussian(Downsample(left, scale), sigma);
    const cv::Mat r = matching::LaplacianOfGaussian(Downsample(right, scale), sigma);
    const cv::Mat ml = DownsampleMask(mask_l, scale), mr = DownsampleMask(mask_r, scale);
    cv::Mat lf, rf, mlf, mrf;
    cv::flip(r, lf, 1);
    cv::flip(l, rf, 1);
    cv::flip(mr, mlf, 1);
    cv::flip(ml, mrf, 1);

    int k_min, k_max;
    cv::Mat base_l, base_r;
    if (pred_left.empty()) {
      k_min = static_cast<int>(std::floor(options.min_disparity / scale)) - 1;
      k_max = static_cast<int>(std::ceil(options.max_disparity / scale)) + 1;
    } else {
      k_min = -options.search_radius - 1;
      k_max = options.search_radius + 1;
      base_l = PredictBase(pred_left, prev_g, l.size());
      cv::Mat br = PredictBase(pred_right, prev_g, l.size());
      cv::flip(br, base_r, 1);
    }
    // The extra +-1 lets the parabola use both neighbours of a maximum at the
    // edge of the nominal range; a maximum on the extended edge is rejected.
    const DenseResult res_l =
        Search(l, r, base_l, k_min, k_max, options.window, options.min_correlation, ml, mr);
    cv::Mat grid_l = SampleGrid(res_l.disparity, g);
    cv::Mat corr_l = SampleGrid(res_l.correlation, g);
    const int nodes = grid_l.rows * grid_l.cols;
    const int found = cv::countNonZero(grid_l == grid_l);
    cv::Mat grid_r;
    if (options.two_way) {
      DenseResult res_r = Search(lf, rf, base_r, k_min, k_max, options.window, options.min_correlation, mlf, mrf);
      cv::Mat dr;
      cv::flip(res_r.disparity, dr, 1);
      // Mirrored nodes fall on (W-1-x); sample the unmirrored map on the grid.
      grid_r = SampleGrid(dr, g);
    }
    if (options.median_filter) {
      MedianFilter(&grid_l);
      if (!grid_r.empty()) MedianFilter(&grid_r);
    }
    int rejected_order = 0;
    if (options.order_check) {
      rejected_order += OrderCheck(&grid_l, g, options.order_tolerance);
      if (!grid_r.empty()) {
        // For the right grid the matched left position x + d must not decrease.
        cv::Mat neg = -grid_r;
        rejected_order += OrderCheck(&neg, g, options.order_tolerance);
        grid_r = -neg;
      }
    }
    int rejected_lr = 0;
    cv::Mat averaged = grid_l.clone();
    if (!grid_r.empty()) {
      for (int i = 0; i < grid_l.rows; ++i) {
        const float* rr = grid_r.ptr<float>(i);
        for (int j = 0; j < grid_l.cols; ++j) {
          const float dl = grid_l.at<float>(i, j);
          if (!Finite(dl)) continue;
          const float drv = LookupLine(rr, grid_r.cols, (j * g - dl) / g);
          if (Finite(drv) && std::abs(drv - dl) <= options.lr_tolerance) {
            averaged.at<float>(i, j) = 0.5f * (dl + drv);
          } else {
            averaged.at<float>(i, j) = kNaN;
            ++rejected_lr;
          }
        }
      }
    }
    if (last) {
      sum.nodes = nodes;
      sum.rejected_correlation = nodes - found;
      sum.rejected_order = rejected_order;
      sum.rejected_left_right = rejected_lr;
      sum.valid_nodes = cv::countNonZero(averaged == averaged);
      final_grid = averaged;
      final_corr = corr_l;
      for (int i = 0; i < final_grid.rows; ++i)
        for (int j = 0; j < final_grid.cols; ++j)
          if (!Finite(final_grid.at<float>(i, j))) final_corr.at<float>(i, j) = kNaN;
    } else {
      const float fallback = static_cast<float>(0.5 * (options.min_disparity + options.max_disparity) / scale);
      pred_left = FillForPrediction(averaged, fallback);
      pred_right = grid_r.empty() ? pred_left : FillForPrediction(grid_r, fallback);
      prev_g = g;
      // The next level's nodes are spaced g of ITS pixels; prediction uses
      // this level's grid (spacing g here = 2 g there).
    }
  }
  ParallaxGrid out;
  out.spacing = options.final_grid_spacing;
  out.disparity = final_grid;
  out.correlation = final_corr;
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return out;
}

}  // namespace dense
}  // namespace slope_monitor
