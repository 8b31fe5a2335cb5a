// Stage 2a of TargetCentroider::DetectMono: markers of three or more dark
// rings on a light ground (CCTag-style and any other ring count or width
// ratio), found by their nested ellipses. Dark masks at three window sizes
// on one reduced level; every contour of a mask (the parts on the image
// border left out) fitted with an ellipse; ellipses with one centre (within
// the perspective shift) grouped from the largest dark-inside one down.
// Between a group's innermost light-inside edge and its outer edge the
// intensity is sampled on 72 rays: the rings are read from the mean
// profile (count and edges, each ring checked ray by ray where resolved);
// each edge refined at full resolution (the strongest step along 72
// normals, then a least-squares ellipse). The marker's centre is the image
// of the rings' common centre: for two edges, the point their pencil
// degenerates to (the pole of the image of the line at infinity); the
// variance-weighted mean over the pairs of edges. The edges' radii, free of
// perspective, come from cross ratios along lines through that centre; a
// target list's ring radii give the ID.
#include <opencv2/imgproc.hpp>

#include "centroider_stages.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace detail {
namespace {

// Window sizes of the dark masks on the reduced level [px]: a ring is dark
// against the mean of a window a few times its width (thin far rings in
// the smallest, thick near rings in the largest).
constexpr std::array<int, 3> kWindows = {9, 27, 81};
// An edge ellipse: contour points within kMaxFitRms [px] RMS (at least
// kFitRmsShare of its semi-minor axis allowed) and on kMinCoverage of the
// perimeter (a contour cut by the image border or an occluder covers less).
constexpr double kMaxFitRms = 1.0, kFitRmsShare = 0.04, kMinCoverage = 0.5;
// Ellipses of one marker: centres within kCentreShift of the larger's
// semi-major axis (+ 2 px), the same axis ratio within kAxisRatioTolerance
// and, when eccentric, the same orientation within kMaxTilt [deg].
constexpr double kCentreShift = 0.1, kAxisRatioTolerance = 0.2, kMaxTilt = 20.0;
// The refined edge: a step of at least half the profile's step there on
// kMinEdgeShare of the 72 normals (on a blurred thin ring a window between
// neighbouring edges does not reach both levels on every normal).
constexpr double kMinEdgeShare = 0.5;
constexpr int kNormals = 72;
// A marker: kMinRings dark rings at least; every edge's pencil with the
// outer edge giving the common centre within kConcentricTolerance of the
// outer semi-major axis (+ 1 px).
constexpr int kMinRings = 3;
constexpr double kConcentricTolerance = 0.02;
// The innermost light edge within kMaxInnerShare of the outer edge's
// radius; a marker with fewer than kPartialRayShare of its rays in the
// image is not named, with fewer than kMinWholeRayShare it is "partial".
constexpr double kMaxInnerShare = 0.7, kPartialRayShare = 0.25, kMinWholeRayShare = 0.6;
// Edge pairs whose radii are closer than this ratio do not give the centre
// (their pencil is ill-conditioned).
constexpr double kMaxPairRatio = 0.8;

EdgeEllipse EllipseOf(const cv::RotatedRect& r) {
  EdgeEllipse e;
  e.centre = Eigen::Vector2d(r.center.x, r.center.y);
  const double t = r.angle * M_PI / 180.0;
  e.a = 0.5 * r.size.width;
  e.b = 0.5 * r.size.height;
  e.major = Eigen::Vector2d(std::cos(t), std::sin(t));
  if (e.a < e.b) {
    std::swap(e.a, e.b);
    e.major = Eigen::Vector2d(-std::sin(t), std::cos(t));
  }
  return e;
}

// Distance [px] of p from the ellipse, to first order.
double Distance(const EdgeEllipse& e, const Eigen::Vector2d& p) {
  const Eigen::Vector2d d = p - e.centre;
  const Eigen::Vector2d minor(-e.major.y(), e.major.x());
  const double u = d.dot(e.major) / e.a, v = d.dot(minor) / e.b;
  const double r = std::hypot(u, v);
  return r > 1e-9 ? (r - 1.0) * d.norm() / r : e.b;
}

// Fits an ellipse to contour points (full-resolution pixels) and measures
// its RMS distance and angular coverage; false when it is no ellipse.
bool FitEdge(const std::vector<cv::Point2f>& pts, EdgeEllipse* out) {
  if (pts.size() < 12) return false;
  const cv::RotatedRect r = cv::fitEllipseDirect(pts);
  if (!(r.size.width > 1 && r.size.height > 1)) return false;
  EdgeEllipse e = EllipseOf(r);
  double ss = 0;
  std::array<bool, 36> bins{};
  const Eigen::Vector2d minor(-e.major.y(), e.major.x());
  for (const auto& q : pts) {
    const Eigen::Vector2d p(q.x, q.y);
    const double dist = Distance(e, p);
    ss += dist * dist;
    const Eigen::Vector2d d = p - e.centre;
    const double ang = std::atan2(d.dot(minor) / e.b, d.dot(e.major) / e.a);
    bins[std::clamp(static_cast<int>((ang + M_PI) / (2 * M_PI) * 36), 0, 35)] = true;
  }
  e.rms = std::sqrt(ss / pts.size());
  e.coverage = std::count(bins.begin(), bins.end(), true) / 36.0;
  if (e.rms > std::max(kMaxFitRms, kFitRmsShare * e.b) || e.coverage < kMinCoverage) return false;
  *out = e;
  return true;
}

// Which side of e (full-resolution pixels) the mask (reduced by f) marks
// dark: sampled 1.5 reduced pixels in and out on 36 normals; false when
// neither side is dark on most of them.
bool DarkSide(const cv::Mat& mask, int f, EdgeEllipse* e) {
  const Eigen::Vector2d minor(-e->major.y(), e->major.x());
  int in = 0, out = 0;
  auto dark = [&](const Eigen::Vector2d& q) {
    const int x = static_cast<int>(std::lround((q.x() - 0.5 * (f - 1)) / f)),
              y = static_cast<int>(std::lround((q.y() - 0.5 * (f - 1)) / f));
    if (x < 0 || y < 0 || x >= mask.cols || y >= mask.rows) return -1;
    return mask.at<uint8_t>(y, x) ? 1 : 0;
  };
  const double d = 1.5 * f;
  for (int k = 0; k < 36; ++k) {
    const double t = 2 * M_PI * k / 36;
    const Eigen::Vector2d p =
        e->centre + e->a * std::cos(t) * e->major + e->b * std::sin(t) * minor;
    const Eigen::Vector2d n =
        (std::cos(t) / e->a * e->major + std::sin(t) / e->b * minor).normalized();
    const int a = dark(p - d * n), b = dark(p + d * n);
    in += a == 1 && b == 0;
    out += a == 0 && b == 1;
  }
  e->dark_inside = in > out;
  return std::max(in, out) >= 0.3 * 36 && std::min(in, out) <= 0.1 * 36;
}

// The ellipses of one mask's contours. A contour's points on the image
// border are left out: the rest (one run or two) is fitted per run.
void EllipsesOfMask(const cv::Mat& mask, int f, double min_diameter, const cv::Size& full,
                    std::vector<EdgeEllipse>* out) {
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_NONE);
  const double min_len = 0.5 * M_PI * min_diameter / f;
  for (size_t i = 0; i < contours.size(); ++i) {
    const auto& c = contours[i];
    if (c.size() < std::max(12.0, min_len)) continue;
    const cv::Rect box = cv::boundingRect(c);
    if (std::max(box.width, box.height) * f < 0.8 * min_diameter) continue;
    auto on_border = [&](const cv::Point& p) {
      return p.x <= 0 || p.y <= 0 || p.x >= mask.cols - 1 || p.y >= mask.rows - 1;
    };
    std::vector<std::vector<cv::Point2f>> runs(1);
    bool cut = false;
    for (const auto& p : c) {
      if (on_border(p)) {
        cut = true;
        if (!runs.back().empty()) runs.emplace_back();
        continue;
      }
      runs.back().emplace_back(f * p.x + 0.5f * (f - 1), f * p.y + 0.5f * (f - 1));
    }
    // The first and last runs of a cut contour are one arc.
    if (cut && runs.size() > 1 && !on_border(c.front()) && !on_border(c.back())) {
      runs.front().insert(runs.front().begin(), runs.back().begin(), runs.back().end());
      runs.pop_back();
    }
    for (const auto& run : runs) {
      EdgeEllipse e;
      if (!FitEdge(run, &e) || 2 * e.a > 2.0 * std::max(full.width, full.height)) continue;
      if (!DarkSide(mask, f, &e)) continue;
      e.cut = cut;
      out->push_back(e);
    }
  }
}

// Whether the smaller ellipse s may be an edge of the marker whose outer
// edge is l (see kCentreShift).
bool SameMarker(const EdgeEllipse& l, const EdgeEllipse& s) {
  if (s.a >= l.a || (s.centre - l.centre).norm() > kCentreShift * l.a + 2.0) return false;
  const double rl = l.b / l.a, rs = s.b / s.a;
  if (std::abs(rl - rs) > kAxisRatioTolerance) return false;
  if (std::max(rl, rs) > 0.85) return true;
  const double cosang = std::abs(l.major.dot(s.major));
  return cosang >= std::cos(kMaxTilt * M_PI / 180.0);
}

// The strongest step of the expected sign along kNormals normals of e,
// within `inner` and `outer` [px] of it, refitted as an ellipse; false when
// the step is missing on too many normals.
bool RefineEdge(const ImageView& im, const EdgeEllipse& e, double inner, double outer,
                double min_step, EdgeEllipse* out) {
  const Eigen::Vector2d minor(-e.major.y(), e.major.x());
  const double sgn = e.dark_inside ? 1.0 : -1.0;  // brighter outward for a dark inside
  std::vector<cv::Point2f> pts;
  std::vector<double> prof;
  for (int k = 0; k < kNormals; ++k) {
    const double t = 2 * M_PI * k / kNormals;
    const Eigen::Vector2d p = e.centre + e.a * std::cos(t) * e.major + e.b * std::sin(t) * minor;
    const Eigen::Vector2d n =
        (std::cos(t) / e.a * e.major + std::sin(t) / e.b * minor).normalized();
    const Eigen::Vector2d lo = p - inner * n, hi = p + outer * n;
    if (lo.x() < 1 || lo.y() < 1 || hi.x() > im.cols - 2 || hi.y() > im.rows - 2 || p.x() < 1 ||
        p.y() < 1 || p.x() > im.cols - 2 || p.y() > im.rows - 2)
      continue;
    const int m = static_cast<int>(std::ceil(2 * (inner + outer))) + 1;
    prof.resize(m);
    for (int j = 0; j < m; ++j) {
      const Eigen::Vector2d q = lo + (inner + outer) * j / (m - 1) * n;
      prof[j] = sgn * im.Sample(q.x(), q.y());
    }
    if (prof[m - 1] - prof[0] < min_step) continue;
    int best = -1;
    double best_g = 0;
    for (int j = 1; j + 1 < m; ++j) {
      const double g = prof[j + 1] - prof[j - 1];
      if (g > best_g) {
        best_g = g;
        best = j;
      }
    }
    if (best < 1) continue;
    double off = 0;
    if (best >= 2 && best + 2 < m) {
      const double gm = prof[best] - prof[best - 2], gp = prof[best + 2] - prof[best];
      const double den = gm - 2 * best_g + gp;
      if (den < 0) off = std::clamp(0.5 * (gm - gp) / den, -0.5, 0.5);
    }
    const Eigen::Vector2d q = lo + (inner + outer) * (best + off) / (m - 1) * n;
    pts.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
  }
  if (pts.size() < kMinEdgeShare * kNormals) return false;
  EdgeEllipse r;
  if (!FitEdge(pts, &r)) return false;
  // One pass without the points off by more than 3 RMS (a stray step).
  std::vector<cv::Point2f> kept;
  for (const auto& q : pts)
    if (std::abs(Distance(r, Eigen::Vector2d(q.x, q.y))) <= 3 * r.rms + 0.1) kept.push_back(q);
  if (kept.size() < kMinEdgeShare * kNormals || !FitEdge(kept, &r)) return false;
  r.dark_inside = e.dark_inside;
  r.cut = e.cut;
  r.points = static_cast<int>(kept.size());
  *out = r;
  return true;
}

}  // namespace

Eigen::Matrix3d ConicOf(const EdgeEllipse& e) {
  const Eigen::Vector2d minor(-e.major.y(), e.major.x());
  const Eigen::Matrix2d a =
      e.major * e.major.transpose() / (e.a * e.a) + minor * minor.transpose() / (e.b * e.b);
  Eigen::Matrix3d c;
  c.topLeftCorner<2, 2>() = a;
  c.topRightCorner<2, 1>() = -a * e.centre;
  c.bottomLeftCorner<1, 2>() = -(a * e.centre).transpose();
  c(2, 2) = e.centre.dot(a * e.centre) - 1.0;
  return c;
}

bool CommonCentre(const EdgeEllipse& inner, const EdgeEllipse& outer, Eigen::Vector2d* centre) {
  // In coordinates centred on the outer ellipse and scaled by its size.
  const double s = outer.a;
  auto local = [&](EdgeEllipse e) {
    e.centre = (e.centre - outer.centre) / s;
    e.a /= s;
    e.b /= s;
    return ConicOf(e);
  };
  const Eigen::Matrix3d ci = local(inner), co = local(outer);
  Eigen::EigenSolver<Eigen::Matrix3d> es(ci.inverse() * co);
  if (es.info() != Eigen::Success) return false;
  const Eigen::Vector3cd l = es.eigenvalues();
  // The single eigenvalue: the one farthest from the other two's mean.
  int single = 0;
  double far = -1;
  for (int k = 0; k < 3; ++k) {
    const std::complex<double> mean = 0.5 * (l[(k + 1) % 3] + l[(k + 2) % 3]);
    if (std::abs(l[k] - mean) > far) {
      far = std::abs(l[k] - mean);
      single = k;
    }
  }
  const double lambda = l[single].real();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(co - lambda * ci, Eigen::ComputeFullV);
  const Eigen::Vector3d v = svd.matrixV().col(2);
  if (std::abs(v.z()) < 1e-9) return false;
  *centre = outer.centre + s * v.head<2>() / v.z();
  return centre->allFinite();
}

namespace {

// Every edge ellipse of the dark masks, largest first. The level: 12 MP
// photos reduced by 2 (area mean), under 12 MP none.
void FindRingMarkerEdges(const cv::Mat& mono8, double min_contrast, double min_diameter,
                         std::vector<EdgeEllipse>* edges) {
  const double mp = static_cast<double>(mono8.total()) / 1e6;
  const int f = std::max(1, static_cast<int>(std::floor(std::sqrt(mp / 3.0))));
  cv::Mat small = mono8, mean, dark;
  if (f > 1) {
    const cv::Mat whole = mono8(cv::Rect(0, 0, (mono8.cols / f) * f, (mono8.rows / f) * f));
    cv::resize(whole, small, cv::Size(mono8.cols / f, mono8.rows / f), 0, 0, cv::INTER_AREA);
  }
  for (int k : kWindows) {
    cv::blur(small, mean, cv::Size(k, k), cv::Point(-1, -1), cv::BORDER_REPLICATE);
    cv::subtract(mean, small, dark);  // saturating: max(0, local mean - image)
    cv::threshold(dark, dark, 0.4 * min_contrast, 255, cv::THRESH_BINARY);
    EllipsesOfMask(dark, f, min_diameter, mono8.size(), edges);
  }
  std::sort(edges->begin(), edges->end(),
            [](const EdgeEllipse& x, const EdgeEllipse& y) { return x.a > y.a; });
}

// The edges not yet used that may belong to the marker whose outer edge is
// edges[outer] (itself first).
std::vector<int> MarkerMembers(const std::vector<EdgeEllipse>& edges, const std::vector<bool>& used,
                               size_t outer) {
  std::vector<int> members{static_cast<int>(outer)};
  for (size_t j = outer + 1; j < edges.size(); ++j)
    if (!used[j] && SameMarker(edges[outer], edges[j])) members.push_back(static_cast<int>(j));
  return members;
}

// The common centre of the refined edges (outer first) and its covariance: an
// ellipse's centre from n points at RMS distance s has variance ~ 2 s^2 / n
// per axis; the pencil's centre is about (r2^2 c1 - r1^2 c2) / (r2^2 - r1^2)
// (perspective shifts an ellipse's centre by ~ its radius squared).
bool MeasureMarker(const std::vector<EdgeEllipse>& edges, RingMarker* m, std::string* fault) {
  const EdgeEllipse &out = edges.front(), &in = edges.back();
  if (!CommonCentre(in, out, &m->centre)) {
    *fault = "the edges' pencil has no centre";
    return false;
  }
  // Every edge's pencil with the outer edge must give the same centre.
  for (size_t k = 1; k + 1 < edges.size(); ++k) {
    Eigen::Vector2d c;
    if (!CommonCentre(edges[k], out, &c) ||
        (c - m->centre).norm() > kConcentricTolerance * out.a + 1.0) {
      *fault = Message("edge ", k, " of ", edges.size(), " not concentric: centre ",
                       (c - m->centre).norm(), " px off");
      return false;
    }
  }
  // The centre: every pair of edges far enough apart (the smaller within
  // kMaxPairRatio of the larger's radius), weighted by its variance; the
  // pairs share edges, so the mean counts as half as many independent
  // pairs as there are edges. The pairs' scatter about the mean (what the
  // edge model leaves: blur, print, JPEG) is added for as many.
  auto var = [](const EdgeEllipse& e) { return 2.0 * e.rms * e.rms / std::max(e.points, 1); };
  Eigen::Vector2d sum = Eigen::Vector2d::Zero();
  std::vector<std::pair<Eigen::Vector2d, double>> pairs;
  double wsum = 0, best_var = 1e30;
  for (size_t i = 0; i < edges.size(); ++i) {
    for (size_t j = i + 1; j < edges.size(); ++j) {
      const double r1 = edges[j].MeanRadius(), r2 = edges[i].MeanRadius();
      if (r1 > kMaxPairRatio * r2) continue;
      Eigen::Vector2d c;
      if (!CommonCentre(edges[j], edges[i], &c)) continue;
      const double w1 = r2 * r2 / (r2 * r2 - r1 * r1), w2 = r1 * r1 / (r2 * r2 - r1 * r1);
      const double v = w1 * w1 * var(edges[j]) + w2 * w2 * var(edges[i]);
      sum += c / v;
      wsum += 1 / v;
      best_var = std::min(best_var, v);
      pairs.emplace_back(c, 1 / v);
    }
  }
  m->centre = sum / wsum;
  const double n_eff = std::max(1.0, 0.5 * edges.size());
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const auto& [c, w] : pairs)
    scatter += w / wsum * (c - m->centre) * (c - m->centre).transpose();
  m->covariance =
      std::max(1.0 / wsum, best_var / n_eff) * Eigen::Matrix2d::Identity() + scatter / n_eff;
  m->fit_rms = 0;
  for (const auto& e : edges) m->fit_rms = std::max(m->fit_rms, e.rms);
  return true;
}

// The marker between its innermost light edge (t = 0) and its outer edge
// (t = 1), sampled on kNormals rays (each from the inner ellipse's point to
// the outer's at one parametric angle of the outer) at steps of about half a pixel,
// from kProfileIn inside to kProfileBeyond beyond; per ray and the mean. A
// ray counts when it stays in the image to kProfileOut; beyond, a sample
// outside repeats the last one. (Beyond the outer contour: rings whose
// contour was broken by an occluder are still read.)
constexpr double kProfileIn = 0.3, kProfileOut = 0.25, kProfileBeyond = 1.0;
struct RingProfile {
  std::vector<double> t, mean;  // mean over the rays in image
  std::vector<std::vector<double>> rays;
  std::vector<double> scale;  // per ray: pixels per unit of t
  // The outer ellipse's point at parametric angle ang, the inner's in the
  // same direction from its centre (a near circle's axes say nothing of its
  // orientation).
  Eigen::Vector2d Point(const EdgeEllipse& in, const EdgeEllipse& out, double ang, double t) const {
    const Eigen::Vector2d mo(-out.major.y(), out.major.x()), mi(-in.major.y(), in.major.x());
    const Eigen::Vector2d po =
        out.centre + out.a * std::cos(ang) * out.major + out.b * std::sin(ang) * mo;
    const Eigen::Vector2d d = (po - out.centre).normalized();
    const Eigen::Vector2d pi = in.centre + d / std::hypot(d.dot(in.major) / in.a, d.dot(mi) / in.b);
    return pi + t * (po - pi);
  }
};

RingProfile SampleProfile(const ImageView& im, const EdgeEllipse& in, const EdgeEllipse& out) {
  RingProfile p;
  const double span = out.MeanRadius() - in.MeanRadius(), len = 1 + kProfileIn + kProfileBeyond;
  const int n = static_cast<int>(std::ceil(2.0 * span * len)) + 1;
  for (int j = 0; j < n; ++j) p.t.push_back(-kProfileIn + len * j / (n - 1));
  p.mean.assign(n, 0.0);
  int rays = 0;
  for (int k = 0; k < kNormals; ++k) {
    const double ang = 2 * M_PI * k / kNormals;
    std::vector<double> r(n);
    bool inside = true;
    for (int j = 0; j < n; ++j) {
      const Eigen::Vector2d q = p.Point(in, out, ang, p.t[j]);
      if (q.x() >= 0 && q.y() >= 0 && q.x() <= im.cols - 1 && q.y() <= im.rows - 1) {
        r[j] = im.Sample(q.x(), q.y());
      } else {
        inside = inside && p.t[j] > 1 + kProfileOut;
        if (!inside || j == 0) break;
        r[j] = r[j - 1];
      }
    }
    if (!inside) continue;
    for (int j = 0; j < n; ++j) p.mean[j] += r[j];
    p.rays.push_back(std::move(r));
    p.scale.push_back((p.Point(in, out, ang, 1.0) - p.Point(in, out, ang, 0.0)).norm());
    ++rays;
  }
  for (double& v : p.mean) v /= std::max(rays, 1);
  return p;
}

// The extrema of the mean profile between the light centre and the ground
// beyond the outer edge, alternating (light, dark, light, ..., light), each
// step at least `step` [DN]; indices into the profile.
std::vector<int> ProfileExtrema(const std::vector<double>& v, double step) {
  std::vector<int> ext;
  int cand = 0;  // the extremum being followed: a maximum first (the light centre)
  bool seeking_min = true;
  for (int j = 1; j < static_cast<int>(v.size()); ++j) {
    if (seeking_min ? v[j] > v[cand] : v[j] < v[cand]) {
      cand = j;
    } else if (std::abs(v[j] - v[cand]) >= step) {
      ext.push_back(cand);
      cand = j;
      seeking_min = !seeking_min;
    }
  }
  ext.push_back(cand);
  // A maximum after a minimum where its plateau begins (the ground beyond
  // the marker may keep rising slowly).
  for (size_t k = 2; k < ext.size(); k += 2) {
    int j = ext[k - 1];
    while (j < ext[k] && v[j] < v[ext[k]] - 0.25 * step) ++j;
    ext[k] = j;
  }
  return ext;
}

// The rings the profile shows: dark minima between light maxima, each seen
// on kRayShare of the rays (darker than both neighbouring maxima there);
// their edges (steepest point between an extremum and the next) as radii
// in t. False with the fault when fewer than kMinRings rings are seen.
constexpr double kRayShare = 0.7, kStepShare = 0.15, kMinResolved = 3.5, kResolvedBlurs = 4.5;

// The blur sigma [px] of the profile's outer edge (from the last minimum to
// the ground): a blurred step of height h rises by at most h / (sigma
// sqrt(2 pi)) per pixel. (The mean over the rays smears a little more.)
double OuterEdgeBlur(const RingProfile& p, const std::vector<int>& ext) {
  if (ext.size() < 2) return 0.0;
  const int a = ext[ext.size() - 2], b = ext.back();
  double slope = 0.0;
  for (int j = a; j < b; ++j)
    slope = std::max(slope, (p.mean[j + 1] - p.mean[j]) / (p.t[j + 1] - p.t[j]));
  double scale = 0.0;
  for (double s : p.scale) scale += s / p.scale.size();
  return slope > 0 ? (p.mean[b] - p.mean[a]) * scale / (std::sqrt(2 * M_PI) * slope) : 0.0;
}

bool ReadRings(const RingProfile& p, double min_contrast, std::vector<double>* edge_t,
               double* contrast, std::string* fault) {
  const auto [lo, hi] = std::minmax_element(p.mean.begin(), p.mean.end());
  *contrast = *hi - *lo;
  if (*contrast < min_contrast || p.rays.size() < kPartialRayShare * kNormals) {
    *fault = Message("ring contrast ", *contrast, " DN on ", p.rays.size(), " rays");
    return false;
  }
  const std::vector<int> ext = ProfileExtrema(p.mean, kStepShare * *contrast);
  const double resolved = std::max(kMinResolved, kResolvedBlurs * OuterEdgeBlur(p, ext));
  // Each ray averaged with its two neighbours (image noise on faint gaps).
  const size_t nr = p.rays.size();
  std::vector<std::vector<double>> sectors(nr, std::vector<double>(p.mean.size()));
  for (size_t i = 0; i < nr; ++i)
    for (size_t j = 0; j < p.mean.size(); ++j)
      sectors[i][j] = (p.rays[(i + nr - 1) % nr][j] + p.rays[i][j] + p.rays[(i + 1) % nr][j]) / 3.0;
  int rings = 0;
  edge_t->clear();
  for (size_t k = 1; k + 1 < ext.size(); k += 2) {
    // Per ray: the darkest near the minimum under the brightest near each
    // neighbouring maximum (within half the way to the next extremum: the
    // rays' rings are not exactly where the mean's are).
    auto near = [&](const std::vector<double>& r, int k2, bool dark) {
      const int a = k2 > 0 ? (ext[k2 - 1] + ext[k2] + 1) / 2 : ext[k2];
      const int b = k2 + 1 < static_cast<int>(ext.size()) ? (ext[k2] + ext[k2 + 1]) / 2 : ext[k2];
      double v = r[ext[k2]];
      for (int j = a; j <= b; ++j) v = dark ? std::min(v, r[j]) : std::max(v, r[j]);
      return v;
    };
    // Judged only on the rays where the ring and its gaps are resolved: the
    // maxima around it kMinResolved [px] and kResolvedBlurs blur sigmas
    // apart at least (a period of 4.5 sigma keeps 38 % of its contrast).
    int seen = 0, judged = 0;
    for (size_t i = 0; i < nr; ++i) {
      if ((p.t[ext[k + 1]] - p.t[ext[k - 1]]) * p.scale[i] < resolved) continue;
      ++judged;
      const double d = near(sectors[i], k, true);
      seen += d < near(sectors[i], k - 1, false) && d < near(sectors[i], k + 1, false);
    }
    if (judged < kPartialRayShare * kNormals || seen < kRayShare * judged) break;
    ++rings;
    for (int e : {0, 1}) {
      const int a = ext[k - 1 + e], b = ext[k + e];
      int best = a;
      for (int j = a; j < b; ++j)
        if (std::abs(p.mean[j + 1] - p.mean[j]) > std::abs(p.mean[best + 1] - p.mean[best]))
          best = j;
      edge_t->push_back(0.5 * (p.t[best] + p.t[best + 1]));
    }
  }
  if (rings < kMinRings) {
    *fault = Message(rings, " dark rings seen around a light centre (", kMinRings, " at least)");
    return false;
  }
  return true;
}

// The ellipse of the profile at t (between the inner and outer edges): the
// one through its points at t in 36 directions.
EdgeEllipse Between(const RingProfile& p, const EdgeEllipse& in, const EdgeEllipse& out, double t) {
  std::vector<cv::Point2f> pts;
  for (int k = 0; k < 36; ++k) {
    const Eigen::Vector2d q = p.Point(in, out, 2 * M_PI * k / 36, t);
    pts.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
  }
  return EllipseOf(cv::fitEllipseDirect(pts));
}

// The profile's value at t (linear).
double ProfileAt(const RingProfile& p, double t) {
  const double u = (t - p.t.front()) / (p.t.back() - p.t.front()) * (p.t.size() - 1);
  const int j = std::clamp(static_cast<int>(u), 0, static_cast<int>(p.t.size()) - 2);
  const double f = std::clamp(u - j, 0.0, 1.0);
  return (1 - f) * p.mean[j] + f * p.mean[j + 1];
}

// A candidate from its innermost light edge and outer edge: the rings the
// profile shows, each edge refined (the innermost and the outer must be),
// the common centre. m->rings is set once the rings are seen; m->partial
// when they are seen but the marker runs out of the image.
bool MeasureRings(const ImageView& im, const EdgeEllipse& in, const EdgeEllipse& out,
                  const Options& o, RingMarker* m, std::string* fault) {
  const RingProfile p = SampleProfile(im, in, out);
  std::vector<double> edge_t;
  if (p.rays.size() < kPartialRayShare * kNormals ||
      !ReadRings(p, o.min_contrast, &edge_t, &m->contrast, fault))
    return false;
  m->rings = static_cast<int>(edge_t.size() / 2);
  m->centre = out.centre;
  // Measured while most of the outer ring and the whole light centre are
  // in the image; else named.
  if (p.rays.size() < kMinWholeRayShare * kNormals || in.cut) {
    m->partial = true;
    m->edges = {out};
    m->detail = Message(m->rings, " rings seen on ", p.rays.size(), " of ", kNormals,
                        " rays: cut by the image border");
    return true;
  }
  const double span = out.MeanRadius() - in.MeanRadius();
  m->edges.clear();
  for (int k = static_cast<int>(edge_t.size()) - 1; k >= 0; --k) {
    const double t = edge_t[k];
    const double gin = k > 0 ? t - edge_t[k - 1] : t + kProfileIn;
    const double gout = k + 1 < static_cast<int>(edge_t.size()) ? edge_t[k + 1] - t : 1.0;
    const double win = std::max(0.45 * gin * span, 1.5), wout = std::max(0.45 * gout * span, 1.5);
    const double step = std::abs(ProfileAt(p, t + gout * 0.45) - ProfileAt(p, t - gin * 0.45));
    EdgeEllipse e = Between(p, in, out, t), r;
    e.dark_inside = k % 2 == 1;
    const bool end = k == 0 || k + 1 == static_cast<int>(edge_t.size());
    if (RefineEdge(im, e, win, wout, 0.5 * step, &r)) {
      m->edges.push_back(r);
    } else if (end) {
      *fault = Message(k == 0 ? "innermost" : "outer", " edge not refined");
      return false;
    }
  }
  return MeasureMarker(m->edges, m, fault);
}

}  // namespace

void FindRingMarkers(const ImageView& im, const cv::Mat& mono8, const Options& o,
                     std::vector<RingMarker>* markers, std::vector<RingDiscard>* discarded) {
  std::vector<EdgeEllipse> edges;
  FindRingMarkerEdges(mono8, o.min_contrast, o.circle_min_diameter, &edges);
  std::vector<bool> used(edges.size(), false);
  for (size_t i = 0; i < edges.size(); ++i) {
    if (used[i] || !edges[i].dark_inside) continue;
    const std::vector<int> members = MarkerMembers(edges, used, i);
    const EdgeEllipse* in = nullptr;
    for (int m : members)
      if (!edges[m].dark_inside) in = &edges[m];
    if (!in || in->MeanRadius() > kMaxInnerShare * edges[i].MeanRadius()) continue;
    RingMarker m;
    std::string fault;
    if (!MeasureRings(im, *in, edges[i], o, &m, &fault)) {
      if (m.rings >= kMinRings) discarded->push_back({edges[i].centre, fault});
      continue;
    }
    for (int k : members) used[k] = true;
    markers->push_back(m);
  }
}

namespace {

// The radii of the edges over the outer edge's, free of perspective: on a
// line through the image c of the centre, the cross ratio of c, the line's
// vanishing point (on the polar of c, the image of the line at infinity)
// and the points of two edges is the ratio of the two circles' radii.
// Mean over kRadiiRays directions.
constexpr int kRadiiRays = 36;
std::vector<double> EdgeRadii(const std::vector<EdgeEllipse>& edges, const Eigen::Vector2d& c) {
  const Eigen::Vector3d ch(c.x(), c.y(), 1.0);
  const Eigen::Vector3d l = ConicOf(edges.front()) * ch;
  std::vector<double> sum(edges.size(), 0.0);
  for (int k = 0; k < kRadiiRays; ++k) {
    const double t = 2 * M_PI * (k + 0.5) / kRadiiRays;
    const Eigen::Vector2d d(std::cos(t), std::sin(t));
    std::vector<double> s(edges.size());
    for (size_t i = 0; i < edges.size(); ++i) {
      const Eigen::Matrix3d ci = ConicOf(edges[i]);
      const Eigen::Matrix2d a = ci.topLeftCorner<2, 2>();
      const Eigen::Vector2d q = c - edges[i].centre;
      const double qa = d.dot(a * d), qb = d.dot(a * q), qc = q.dot(a * q) - 1.0;
      s[i] = (-qb + std::sqrt(std::max(qb * qb - qa * qc, 0.0))) / qa;
    }
    const double so = s.back(), den = l.head<2>().dot(d);
    const double sv = std::abs(den) > 1e-12 ? -l.dot(ch) / den : 1e300;
    for (size_t i = 0; i < edges.size(); ++i)
      sum[i] += std::abs(sv) > 1e299 ? s[i] / so : s[i] * (so - sv) / ((s[i] - sv) * so);
  }
  for (double& v : sum) v /= kRadiiRays;
  return sum;
}

// The listed ring marker whose edge radii (inner to outer, over the outer)
// the measured ones match: every radius within kRingIdTolerance, and no
// other listed marker within kRingIdTolerance of that; nullptr otherwise.
constexpr double kRingIdTolerance = 0.02;
const io::TargetSpec* ReadRingId(const std::vector<double>& radii, const io::TargetList& list) {
  const io::TargetSpec* best = nullptr;
  double best_d = 1e9, second_d = 1e9;
  for (const auto& t : list.targets()) {
    if (t.family != "circle" || t.rings.size() != radii.size()) continue;
    double d = 0.0;
    for (size_t k = 0; k < radii.size(); ++k) d = std::max(d, std::abs(radii[k] - t.rings[k]));
    if (d < best_d) {
      second_d = best_d;
      best_d = d;
      best = &t;
    } else {
      second_d = std::min(second_d, d);
    }
  }
  return best && best_d <= kRingIdTolerance && second_d > best_d + kRingIdTolerance ? best
                                                                                    : nullptr;
}

// An ID read twice in one image is read on neither.
void DropTwiceReadIds(size_t first, Result* res) {
  std::vector<Observation>& obs = res->observations;
  for (size_t i = first; i < obs.size(); ++i) {
    bool twice = false;
    for (size_t j = first; j < obs.size(); ++j) twice = twice || (j != i && obs[j].id == obs[i].id);
    if (obs[i].id < 0 || !twice) continue;
    for (size_t j = i; j < obs.size(); ++j) {
      if (obs[j].id != obs[i].id || j == i) continue;
      obs[j].id = -1;
      obs[j].role.reset();
      res->summary.num_unknown++;
    }
    obs[i].id = -1;
    obs[i].role.reset();
    res->summary.num_unknown++;
  }
}

}  // namespace

void AddRingMarkers(const cv::Mat& mono8, const io::TargetList& list, Frame* frame,
                    std::vector<RingMarker>* markers) {
  std::vector<RingDiscard> discarded;
  FindRingMarkers(frame->im, mono8, frame->options, markers, &discarded);
  for (const auto& d : discarded) frame->Discard(d.where, RejectReason::kDesign, d.detail);
  const size_t first = frame->res.observations.size();
  for (const RingMarker& m : *markers) {
    const EdgeEllipse &out = m.edges.front(), &in = m.edges.back();
    if (m.partial) {
      frame->Reject("circle", -1, m.centre, RejectReason::kPartial, m.detail);
      frame->res.rejections.back().radius_px = out.a;
      continue;
    }
    Observation o;
    o.family = "circle";
    o.design = CircleDesign::kConcentric;
    o.method = CentreMethod::kRingCentre;
    o.centre = o.gray_centroid = m.centre;
    o.covariance = m.covariance;
    o.size_px = in.a + in.b;
    o.ring_ratio = out.MeanRadius() / in.MeanRadius();
    o.rings = m.rings;
    o.contrast = m.contrast;
    o.fit_residual = m.fit_rms;
    o.quality = std::clamp(m.contrast / 100.0, 0.0, 1.0);
    if (static_cast<int>(m.edges.size()) == 2 * m.rings) {
      std::vector<EdgeEllipse> inner_first(m.edges.rbegin(), m.edges.rend());
      o.ring_radii = EdgeRadii(inner_first, m.centre);
      if (const io::TargetSpec* spec = ReadRingId(o.ring_radii, list)) {
        o.id = spec->id;
        o.role = spec->role;
      }
    }
    frame->res.observations.push_back(o);
    frame->res.summary.num_circles++;
    if (!o.role) frame->res.summary.num_unknown++;
  }
  DropTwiceReadIds(first, &frame->res);
}

bool InsideRingMarker(const std::vector<RingMarker>& markers, const Eigen::Vector2d& p) {
  for (const RingMarker& m : markers) {
    const EdgeEllipse& e = m.edges.front();
    const Eigen::Vector2d d = p - e.centre, minor(-e.major.y(), e.major.x());
    if (std::hypot(d.dot(e.major) / e.a, d.dot(minor) / e.b) <= 1.0) return true;
  }
  return false;
}

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
