#include "slope_monitor/core/matching/interest_points.h"

#include <algorithm>
#include <cmath>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace matching {

void InterestPointOptions::Check() const {
  auto fail = [](const char* key, auto value, const char* range) {
    throw ConfigError(
        Message("interest point option '", key, "' = ", value, " out of range ", range));
  };
  if (!(log_sigma > 0)) fail("log_sigma", log_sigma, "(0, inf)");
  if (!(zero_crossing_contrast >= 0))
    fail("zero_crossing_contrast", zero_crossing_contrast, "[0, inf)");
  if (!(max_corner_angle_deg > 0 && max_corner_angle_deg < 180)) {
    fail("max_corner_angle_deg", max_corner_angle_deg, "(0, 180)");
  }
  if (gradient_window < 3 || gradient_window > 51 || gradient_window % 2 == 0) {
    fail("gradient_window", gradient_window, "odd in [3, 51]");
  }
  if (!(min_gradient >= 0)) fail("min_gradient", min_gradient, "[0, inf)");
  if (min_distance < 1) fail("min_distance", min_distance, "[1, inf)");
  if (max_points < 1) fail("max_points", max_points, "[1, inf)");
  if (cells < 0 || cells > 100) fail("cells", cells, "[0, 100]");
  if (border < 0) fail("border", border, "[0, inf)");
}

bool IsEdgeCorner(const cv::Mat& edges, int col, int row, double max_corner_angle_deg) {
  static const int kDx[8] = {1, 1, 0, -1, -1, -1, 0, 1};
  static const int kDy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
  int count = 0;
  int nb[8];
  for (int i = 0; i < 8; ++i) {
    const int c = col + kDx[i], r = row + kDy[i];
    if (c < 0 || r < 0 || c >= edges.cols || r >= edges.rows) continue;
    if (edges.at<uint8_t>(r, c)) nb[count++] = i;
  }
  if (count >= 3) return true;
  if (count < 2) return false;
  const double ax = kDx[nb[0]], ay = kDy[nb[0]], bx = kDx[nb[1]], by = kDy[nb[1]];
  const double cosang = (ax * bx + ay * by) / std::sqrt((ax * ax + ay * ay) * (bx * bx + by * by));
  const double angle = std::acos(std::max(-1.0, std::min(1.0, cosang))) * 180.0 / M_PI;
  return angle <= max_corner_angle_deg + 1e-9;
}

std::vector<InterestPoint> DetectInterestPoints(const cv::Mat& image,
                                                const InterestPointOptions& options) {
  options.Check();
  const cv::Mat f = ToFloat(image, "DetectInterestPoints");
  const cv::Mat log = LaplacianOfGaussian(f, options.log_sigma);
  cv::Scalar mean, stddev;
  cv::meanStdDev(log, mean, stddev);
  const double rms = std::sqrt(mean[0] * mean[0] + stddev[0] * stddev[0]);
  std::vector<InterestPoint> out;
  if (rms <= 1e-6) return out;  // textureless
  const cv::Mat edges = ZeroCrossings(log, options.zero_crossing_contrast * rms);
  const Gradients grad = SobelGradients(f);
  const int hw = options.gradient_window / 2;
  const int b = std::max(options.border, 1);
  cv::Mat taken(f.size(), CV_8U, cv::Scalar(0));
  std::vector<InterestPoint> cand;
  for (int r = 1; r < f.rows - 1; ++r) {
    const uint8_t* er = edges.ptr<uint8_t>(r);
    for (int c = 1; c < f.cols - 1; ++c) {
      if (!er[c] || !IsEdgeCorner(edges, c, r, options.max_corner_angle_deg)) continue;
      // Sobel maximum in the window around the corner.
      float best = -1.0f;
      int bc = c, br = r;
      for (int y = std::max(b, r - hw); y <= std::min(f.rows - 1 - b, r + hw); ++y) {
        const float* gm = grad.magnitude.ptr<float>(y);
        for (int x = std::max(b, c - hw); x <= std::min(f.cols - 1 - b, c + hw); ++x) {
          if (gm[x] > best) {
            best = gm[x];
            bc = x;
            br = y;
          }
        }
      }
      if (best < options.min_gradient || best < 0) continue;
      if (taken.at<uint8_t>(br, bc)) continue;
      taken.at<uint8_t>(br, bc) = 1;
      InterestPoint p;
      p.x = Eigen::Vector2d(bc, br);
      p.strength = best;
      cand.push_back(p);
    }
  }
  std::stable_sort(cand.begin(), cand.end(), [](const InterestPoint& a, const InterestPoint& b) {
    return a.strength > b.strength;
  });
  // Greedy spacing on a coarse grid of cells of size min_distance.
  const int d = options.min_distance;
  const int gc = f.cols / d + 1, gr = f.rows / d + 1;
  std::vector<std::vector<int>> grid(static_cast<size_t>(gc) * gr);
  const double d2 = double(d) * d;
  // Spread (cells > 0): a cell of the image keeps at most `quota` points in
  // the first pass; the points over quota fill what is left, strongest first.
  const int cells = options.cells;
  const int quota =
      cells > 0 ? (options.max_points + cells * cells - 1) / (cells * cells) : options.max_points;
  std::vector<int> per_cell(cells > 0 ? static_cast<size_t>(cells) * cells : 1, 0);
  const auto cell_of = [&](const InterestPoint& p) {
    if (cells <= 0) return 0;
    const int x = std::min(cells - 1, static_cast<int>(p.x.x()) * cells / f.cols);
    const int y = std::min(cells - 1, static_cast<int>(p.x.y()) * cells / f.rows);
    return y * cells + x;
  };
  std::vector<const InterestPoint*> over_quota;
  const auto take = [&](const InterestPoint& p, bool first_pass) {
    const int cx = static_cast<int>(p.x.x()) / d, cy = static_cast<int>(p.x.y()) / d;
    for (int y = std::max(0, cy - 1); y <= std::min(gr - 1, cy + 1); ++y)
      for (int x = std::max(0, cx - 1); x <= std::min(gc - 1, cx + 1); ++x)
        for (int k : grid[static_cast<size_t>(y) * gc + x])
          if ((out[k].x - p.x).squaredNorm() < d2) return;
    if (first_pass && per_cell[cell_of(p)] >= quota) {
      over_quota.push_back(&p);
      return;
    }
    ++per_cell[cell_of(p)];
    grid[static_cast<size_t>(cy) * gc + cx].push_back(static_cast<int>(out.size()));
    out.push_back(p);
  };
  for (const InterestPoint& p : cand) {
    if (static_cast<int>(out.size()) >= options.max_points) break;
    take(p, true);
  }
  for (const InterestPoint* p : over_quota) {
    if (static_cast<int>(out.size()) >= options.max_points) break;
    take(*p, false);
  }
  if (cells > 0)
    std::stable_sort(out.begin(), out.end(), [](const InterestPoint& a, const InterestPoint& b) {
      return a.strength > b.strength;
    });
  return out;
}

}  // namespace matching
}  // namespace slope_monitor
