#include "slope_monitor/core/matching/hex_raster.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace matching {

HexRaster HexRaster::FromImage(const cv::Mat& image, HexSampling sampling, double scale) {
  const cv::Mat f = ToFloat(image, "HexRaster::FromImage");
  if (!(scale > 0) || !std::isfinite(scale)) {
    throw InvalidArgument(Message("HexRaster::FromImage: scale must be > 0, got ", scale));
  }
  HexRaster h;
  h.scale_ = scale;
  h.dy_ = 0.5 * scale;
  h.dx_ = scale / std::sqrt(3.0);
  const int rows = static_cast<int>(std::floor(f.rows / h.dy_ - 0.5 + 1e-9)) + 1;
  const int cols = static_cast<int>(std::floor((f.cols - 1) / h.dx_ - 0.5 + 1e-9)) + 1;
  if (rows < 1 || cols < 1) throw InvalidArgument("HexRaster::FromImage: image too small");
  h.values_.create(rows, cols, CV_32F);
  for (int i = 0; i < rows; ++i) {
    float* out = h.values_.ptr<float>(i);
    for (int k = 0; k < cols; ++k) {
      const Eigen::Vector2d c = h.Centre(i, k);
      const double x = std::min(std::max(c.x(), 0.0), f.cols - 1.0);
      const double y = std::min(std::max(c.y(), 0.0), f.rows - 1.0);
      if (sampling == HexSampling::kNearest) {
        out[k] = f.at<float>(static_cast<int>(std::lround(y)), static_cast<int>(std::lround(x)));
      } else {
        out[k] = SampleBilinear(f, x, y);
      }
    }
  }
  return h;
}

Eigen::Vector2d HexRaster::Centre(int i, int k) const {
  return Eigen::Vector2d((k + 0.5 * (i & 1)) * dx_, (i + 0.5) * dy_ - 0.5);
}

void HexRaster::NearestCell(const Eigen::Vector2d& x, int* i, int* k) const {
  const int i0 = static_cast<int>(std::floor((x.y() + 0.5) / dy_ - 0.5));
  double best = 1e300;
  for (int ii = i0 - 1; ii <= i0 + 2; ++ii) {
    const int kk = static_cast<int>(std::lround(x.x() / dx_ - 0.5 * (ii & 1)));
    const double d = (Centre(ii, kk) - x).squaredNorm();
    if (d < best) {
      best = d;
      *i = ii;
      *k = kk;
    }
  }
}

void HexRaster::Neighbour(int i, int k, int d, int* ni, int* nk) {
  const int odd = i & 1;
  switch (d) {
    case 0:
      *ni = i;
      *nk = k + 1;
      return;
    case 1:
      *ni = i - 1;
      *nk = k + odd;
      return;
    case 2:
      *ni = i - 1;
      *nk = k - 1 + odd;
      return;
    case 3:
      *ni = i;
      *nk = k - 1;
      return;
    case 4:
      *ni = i + 1;
      *nk = k - 1 + odd;
      return;
    default:
      *ni = i + 1;
      *nk = k + odd;
      return;
  }
}

bool HexRaster::Descriptor(int i, int k, int length, std::vector<float>* descriptor) const {
  descriptor->resize(6 * length + 1);
  if (!Contains(i, k)) return false;
  (*descriptor)[0] = value(i, k);
  for (int d = 0; d < 6; ++d) {
    int ci = i, ck = k;
    for (int s = 0; s < length; ++s) {
      Neighbour(ci, ck, d, &ci, &ck);
      if (!Contains(ci, ck)) return false;
      (*descriptor)[1 + d * length + s] = value(ci, ck);
    }
  }
  double mean = 0;
  for (float v : *descriptor) mean += v;
  mean /= descriptor->size();
  double norm = 0;
  for (float& v : *descriptor) {
    v -= static_cast<float>(mean);
    norm += double(v) * v;
  }
  if (norm <= 1e-6 * descriptor->size()) return false;
  const float inv = static_cast<float>(1.0 / std::sqrt(norm));
  for (float& v : *descriptor) v *= inv;
  return true;
}

HexPyramid::HexPyramid(const cv::Mat& image, int levels, HexSampling sampling) {
  if (levels < 1 || levels > 8)
    throw InvalidArgument(Message("HexPyramid: levels must be in [1, 8], got ", levels));
  const cv::Mat f = ToFloat(image, "HexPyramid");
  for (int l = 0; l < levels; ++l) {
    const double s = std::pow(2.0, l);
    const cv::Mat src = l == 0 ? f : GaussianBlur(f, 0.5 * s);
    levels_.push_back(HexRaster::FromImage(src, sampling, s));
  }
}

}  // namespace matching
}  // namespace slope_monitor
