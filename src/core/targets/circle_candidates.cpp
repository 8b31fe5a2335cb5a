// Stage 2 of TargetCentroider::DetectMono: circle candidates. Bright blobs
// with a dark surround on one reduced level (every design has a light
// centre), then each blob's ellipse from the full-resolution pixels above
// the midpoint of its disc and surround levels.
#include <opencv2/imgproc.hpp>

#include "centroider_stages.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace detail {

// One pyramid level: the image reduced by f (area mean) so that the smallest
// disc is still >= 4 px across there; one local-contrast threshold per scale
// (box mean, saturating difference, threshold) and one connected-components
// pass. Everything after works on small ROIs of the full-resolution image.
// Buffers are the caller's (no per-frame allocation).
void FindBrightComponents(const cv::Mat& mono8, CandidateBuffers* b, Frame* frame) {
  const double dmin = frame->options.circle_min_diameter, dmax = frame->options.circle_max_diameter;
  const int f = std::clamp(static_cast<int>(std::floor(dmin / 4.0)), 1, 4);
  b->f = f;
  cv::Mat small;
  if (f > 1) {
    const cv::Mat whole = mono8(cv::Rect(0, 0, (mono8.cols / f) * f, (mono8.rows / f) * f));
    cv::resize(whole, b->small, cv::Size(mono8.cols / f, mono8.rows / f), 0, 0, cv::INTER_AREA);
    small = b->small;
  } else {
    small = mono8;
  }
  b->bright.create(small.size(), CV_8U);
  b->bright.setTo(0);
  // Window sizes from 3 dmin to 1.5 dmax, at most a factor 4 apart.
  const double kmin = 3 * dmin, kmax = std::max(kmin, 1.5 * dmax);
  const int nscales = 1 + static_cast<int>(std::ceil(std::log(kmax / kmin) / std::log(4.0) - 1e-9));
  const int kcap = std::max(3, 2 * ((std::min(small.cols, small.rows) - 1) / 2) + 1);
  for (int i = 0; i < nscales; ++i) {
    const double k =
        nscales == 1 ? kmin : kmin * std::pow(kmax / kmin, static_cast<double>(i) / (nscales - 1));
    const int ks = std::clamp(2 * static_cast<int>(k / f / 2) + 1, 3, kcap);
    cv::blur(small, b->thr, cv::Size(ks, ks), cv::Point(-1, -1), cv::BORDER_REPLICATE);
    cv::subtract(small, b->thr, b->thr);  // saturating: max(0, image - local mean)
    cv::threshold(b->thr, b->thr, 0.4 * frame->options.min_contrast, 255, cv::THRESH_BINARY);
    cv::bitwise_or(b->bright, b->thr, b->bright);
  }
  // Tags are not circles: mask them out.
  for (const auto& q : frame->tag_quads) {
    std::vector<cv::Point> poly;
    Eigen::Vector2d c = 0.25 * (q[0] + q[1] + q[2] + q[3]);
    for (const auto& p : q) {
      const Eigen::Vector2d g = (c + 1.3 * (p - c) - Eigen::Vector2d::Constant(0.5 * (f - 1))) / f;
      poly.emplace_back(static_cast<int>(std::lround(g.x())), static_cast<int>(std::lround(g.y())));
    }
    cv::fillConvexPoly(b->bright, poly, cv::Scalar(0));
  }
  b->n = cv::connectedComponentsWithStats(b->bright, b->labels, b->stats, b->centroids, 8, CV_32S);
}

namespace {

// The moments of the light centre at full resolution: the pixels at or above
// `thr` within 1.3 coarse radii that are 8-connected to the one nearest the
// coarse centre. Connected only: a concentric marker's light ring or the
// light ground beyond a thin ring may come within 1.3 coarse radii (under
// perspective, or when the reduced level joined them) and would widen the
// blob.
void LightCentreMoments(const ImageView& im, const Blob& coarse, double thr, const cv::Rect& roi,
                        double* n, double* sx, double* sy, double* sxx, double* sxy, double* syy) {
  const Eigen::Matrix2d cshape = coarse.Shape();
  // 1: above the threshold within 1.3 radii, 2: reached.
  std::vector<uint8_t> mask(static_cast<size_t>(roi.area()), 0);
  int seed = -1;
  double seed_d = 1e30;
  for (int y = 0; y < roi.height; ++y) {
    for (int x = 0; x < roi.width; ++x) {
      const Eigen::Vector2d d(roi.x + x - coarse.centre.x(), roi.y + y - coarse.centre.y());
      const double r2 = d.dot(cshape * d);
      if (r2 > 1.69 || im.At(roi.x + x, roi.y + y) < thr) continue;
      mask[y * roi.width + x] = 1;
      if (r2 < seed_d) {
        seed_d = r2;
        seed = y * roi.width + x;
      }
    }
  }
  if (seed < 0) return;
  std::vector<int> stack{seed};
  mask[seed] = 2;
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    const int x = i % roi.width, y = i / roi.width;
    const double gx = roi.x + x, gy = roi.y + y;
    *n += 1;
    *sx += gx;
    *sy += gy;
    *sxx += gx * gx;
    *sxy += gx * gy;
    *syy += gy * gy;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = x + dx, yy = y + dy;
        if (xx < 0 || yy < 0 || xx >= roi.width || yy >= roi.height) continue;
        uint8_t& m = mask[yy * roi.width + xx];
        if (m != 1) continue;
        m = 2;
        stack.push_back(yy * roi.width + xx);
      }
    }
  }
}

}  // namespace

bool CandidateBlob(const CandidateBuffers& b, int label, Frame* frame, Blob* out) {
  const double dmin = frame->options.circle_min_diameter, dmax = frame->options.circle_max_diameter;
  const int f = b.f, l = label;
  auto to_full = [f](double xs) { return f * xs + 0.5 * (f - 1); };
  const double amin = M_PI / 4 * dmin * dmin * 0.4 / (f * f),
               amax = M_PI / 4 * dmax * dmax * 1.5 / (f * f);
  const ImageView& im = frame->im;
  std::vector<double> inner, vals;
  const int area = b.stats.at<int>(l, cv::CC_STAT_AREA);
  if (area < amin || area > amax) return false;
  const int bx = b.stats.at<int>(l, cv::CC_STAT_LEFT), by = b.stats.at<int>(l, cv::CC_STAT_TOP);
  const int bw = b.stats.at<int>(l, cv::CC_STAT_WIDTH), bh = b.stats.at<int>(l, cv::CC_STAT_HEIGHT);
  if (f * std::max(bw, bh) > 1.3 * dmax + 2 * f) return false;
  // Coarse ellipse from the component's moments on the reduced level.
  double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, cnt = 0;
  for (int y = by; y < by + bh; ++y) {
    const int* lr = b.labels.ptr<int>(y);
    for (int x = bx; x < bx + bw; ++x) {
      if (lr[x] != l) continue;
      sx += x;
      sy += y;
      sxx += double(x) * x;
      sxy += double(x) * y;
      syy += double(y) * y;
      ++cnt;
    }
  }
  Blob coarse;
  if (!BlobFromMoments(cnt, sx, sy, sxx, sxy, syy, &coarse)) return false;
  // Not disc-like (a ring of bright background around a dark target, a
  // streak): the component fills its moment ellipse badly.
  const double coarse_fill = cnt / (M_PI * coarse.a * coarse.b);
  coarse.centre = Eigen::Vector2d(to_full(coarse.centre.x()), to_full(coarse.centre.y()));
  if (coarse_fill < 0.6 || coarse_fill > 1.6) {
    frame->Discard(coarse.centre, RejectReason::kNotDisc,
                   Message("bright blob fills ", coarse_fill, " of its moment ellipse"));
    return false;
  }
  coarse.a = std::max(f * coarse.a, 1.0);
  coarse.b = std::max(f * coarse.b, 1.0);
  // Full resolution, ROI only: disc level (median within half the coarse
  // radius), dark level (10th percentile of the ROI), then the shape of
  // the pixels above the midpoint within 1.3 coarse radii.
  const double roi_r = 1.5 * coarse.a + 1.0;
  const int rx0 = std::max(0, static_cast<int>(std::floor(coarse.centre.x() - roi_r)));
  const int rx1 = std::min(im.cols - 1, static_cast<int>(std::ceil(coarse.centre.x() + roi_r)));
  const int ry0 = std::max(0, static_cast<int>(std::floor(coarse.centre.y() - roi_r)));
  const int ry1 = std::min(im.rows - 1, static_cast<int>(std::ceil(coarse.centre.y() + roi_r)));
  const Eigen::Matrix2d cshape = coarse.Shape();
  vals.clear();
  inner.clear();
  for (int y = ry0; y <= ry1; ++y) {
    for (int x = rx0; x <= rx1; ++x) {
      const double v = im.At(x, y);
      vals.push_back(v);
      const Eigen::Vector2d d(x - coarse.centre.x(), y - coarse.centre.y());
      if (d.dot(cshape * d) <= 0.25) inner.push_back(v);
    }
  }
  if (inner.empty()) {
    inner.push_back(im.Sample(coarse.centre.x(), coarse.centre.y()));
  }
  const double thr0 = 0.5 * (Percentile(inner, 0.5) + Percentile(vals, 0.1));
  sx = sy = sxx = sxy = syy = cnt = 0;
  LightCentreMoments(im, coarse, thr0, cv::Rect(rx0, ry0, rx1 - rx0 + 1, ry1 - ry0 + 1), &cnt, &sx,
                     &sy, &sxx, &sxy, &syy);
  Blob blob;
  if (!BlobFromMoments(cnt, sx, sy, sxx, sxy, syy, &blob)) {
    frame->Discard(coarse.centre, RejectReason::kNotDisc,
                   "no bright pixels above the disc/surround midpoint");
    return false;
  }
  const double fill = cnt / (M_PI * blob.a * blob.b);
  if (fill < 0.8 || fill > 1.2) {
    frame->Discard(blob.centre, RejectReason::kNotDisc,
                   Message("thresholded blob fills ", fill, " of its moment ellipse"));
    return false;
  }
  // (The measured diameter counts within 20 % under the minimum and 5 % over
  // the maximum: a target of the limits' size is found.)
  if (2 * blob.a < 0.8 * dmin || 2 * blob.a > 1.05 * dmax) {
    frame->Discard(blob.centre, RejectReason::kSize,
                   Message("diameter ", 2 * blob.a, " px outside [", dmin, ", ", dmax, "]"));
    return false;
  }
  if (1.0 - blob.b / blob.a > frame->options.circle_max_eccentricity) {
    frame->Discard(blob.centre, RejectReason::kNotDisc,
                   Message("eccentricity ", 1.0 - blob.b / blob.a));
    return false;
  }
  *out = blob;
  return true;
}

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
