// Stage 1 of TargetCentroider::DetectMono: AprilTags. libapriltag finds and
// decodes the quads; each tag's four outer edges are re-measured with a
// blurred-step model, and the refined corners replace the detector's where
// the model explains the pixels (target_centroider.h).
#include <mutex>

#include <apriltag/apriltag.h>

#include "centroider_stages.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace detail {
namespace {

// A straight edge: n(theta) . (p - origin) = rho, white (level w) on the
// side of +n, black (level b) on the other, blurred by sigma.
// Parameters: theta, rho, b, w, sigma.
struct EdgeFit {
  Eigen::Vector2d origin;
  double theta = 0, rho = 0, b = 0, w = 0, sigma = 0.5;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();  // of (theta, rho)
  double rms = 0;
  int n = 0;
  bool ok = false;
  Eigen::Vector2d Normal() const { return {std::cos(theta), std::sin(theta)}; }
};

struct Line {  // n . p = c in image coordinates
  Eigen::Vector2d n;
  double c;
};

Line ToLine(const EdgeFit& e, double dtheta = 0, double drho = 0) {
  const double th = e.theta + dtheta;
  Line l;
  l.n = Eigen::Vector2d(std::cos(th), std::sin(th));
  l.c = e.rho + drho + l.n.dot(e.origin);
  return l;
}

bool Intersect(const Line& a, const Line& b, Eigen::Vector2d* p) {
  Eigen::Matrix2d m;
  m << a.n.transpose(), b.n.transpose();
  const double det = m.determinant();
  if (std::abs(det) < 1e-9) return false;
  *p = m.inverse() * Eigen::Vector2d(a.c, b.c);
  return true;
}

bool IntersectSegments(const Eigen::Vector2d& a0, const Eigen::Vector2d& a1,
                       const Eigen::Vector2d& b0, const Eigen::Vector2d& b1, Eigen::Vector2d* p) {
  const Eigen::Vector2d da = a1 - a0, db = b1 - b0;
  const double den = da.x() * db.y() - da.y() * db.x();
  if (std::abs(den) < 1e-12) return false;
  const Eigen::Vector2d w = b0 - a0;
  const double t = (w.x() * db.y() - w.y() * db.x()) / den;
  *p = a0 + t * da;
  return true;
}

// Calls f(x, y) for every pixel centre within the rectangle |t.(p - o)| <= hl,
// |n.(p - o)| <= hw (t, n unit and orthogonal), clipped to the image.
template <typename F>
void ForEachPixelInRect(const Eigen::Vector2d& o, const Eigen::Vector2d& t,
                        const Eigen::Vector2d& n, double hl, double hw, int cols, int rows, F f) {
  const double ext = std::abs(t.y()) * hl + std::abs(n.y()) * hw;
  const int ya = std::max(0, static_cast<int>(std::ceil(o.y() - ext)));
  const int yb = std::min(rows - 1, static_cast<int>(std::floor(o.y() + ext)));
  for (int y = ya; y <= yb; ++y) {
    const double dy = y - o.y();
    double lo = -1e18, hi = 1e18;
    bool empty = false;
    for (const auto& [u, h] : {std::make_pair(t, hl), std::make_pair(n, hw)}) {
      if (std::abs(u.x()) > 1e-12) {
        double a = (-h - u.y() * dy) / u.x(), b = (h - u.y() * dy) / u.x();
        if (a > b) std::swap(a, b);
        lo = std::max(lo, a);
        hi = std::min(hi, b);
      } else if (std::abs(u.y() * dy) > h) {
        empty = true;
      }
    }
    if (empty || lo > hi) continue;
    const int xa = std::max(0, static_cast<int>(std::ceil(o.x() + lo)));
    const int xb = std::min(cols - 1, static_cast<int>(std::floor(o.x() + hi)));
    for (int x = xa; x <= xb; ++x) f(x, y);
  }
}

// ---------------------------------------------------------------------------
// Tag edges.
// ---------------------------------------------------------------------------

// The blurred straight step edge: parameters theta, rho, b, w, sigma.
struct EdgeModel {
  double c = 1, s = 0, fa = 1, fb = 0;  // normal and pixel footprint at the current theta
  void Prepare(const Eigen::Matrix<double, 5, 1>& x) {
    c = std::cos(x[0]);
    s = std::sin(x[0]);
    Footprint(c, s, &fa, &fb);
  }
  double operator()(const Eigen::Matrix<double, 5, 1>& x, const Eigen::Vector2d& p,
                    Eigen::Matrix<double, 5, 1>* g) const {
    const double d = c * p.x() + s * p.y() - x[1];
    const double sigma = std::max(x[4], kMinBlur);
    const Profile pr = EdgeProfile(d, fa, fb, sigma);
    const double k = x[3] - x[2];
    // The footprint's dependence on theta is left out of the Jacobian (second
    // order); the model itself is exact at every theta.
    (*g)[0] = k * pr.dd * (-s * p.x() + c * p.y());
    (*g)[1] = -k * pr.dd;
    (*g)[2] = 1.0 - pr.v;
    (*g)[3] = pr.v;
    (*g)[4] = x[4] > kMinBlur ? k * pr.ds : 0.0;
    return x[2] + k * pr.v;
  }
};

// The share of the tag's white surround (the quiet zone, one cell wide
// around the black border) that is darker than halfway between the border's
// black and white levels: a branch, crown or trunk in front of the plate. The
// ring is sampled through the homography of the four outer corners (order
// bottom-left, bottom-right, top-right, top-left; unit square (0,0) (1,0)
// (1,1) (0,1)), at 0.3, 0.55 and 0.8 cell outside the black border; only the
// offsets at least `clear` px [the edge blur's reach] away from both the
// black border and the quiet zone's outer rim count (a small tag's quiet zone
// a few px wide, blurred, has no such offset: nothing to judge, 0 returned).
// Samples outside the image do not count.
double DarkSurroundFraction(const ImageView& im, const std::array<Eigen::Vector2d, 4>& corners,
                            int cells, double cell_px, double clear, double black, double white) {
  Eigen::Matrix<double, 8, 8> a;
  Eigen::Matrix<double, 8, 1> rhs;
  const double uv[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
  for (Eigen::Index k = 0; k < 4; ++k) {
    const double u = uv[k][0], v = uv[k][1], x = corners[k].x(), y = corners[k].y();
    a.row(2 * k) << u, v, 1, 0, 0, 0, -u * x, -v * x;
    a.row(2 * k + 1) << 0, 0, 0, u, v, 1, -u * y, -v * y;
    rhs(2 * k) = x;
    rhs(2 * k + 1) = y;
  }
  const Eigen::Matrix<double, 8, 1> h = a.fullPivLu().solve(rhs);
  if (!h.allFinite()) return 0.0;
  auto map = [&](double u, double v) {
    const double w = h(6) * u + h(7) * v + 1.0;
    return Eigen::Vector2d((h(0) * u + h(1) * v + h(2)) / w, (h(3) * u + h(4) * v + h(5)) / w);
  };
  const double cell = 1.0 / std::max(cells, 1);
  const double threshold = black + 0.5 * (white - black);
  int n = 0, dark = 0;
  const int kAlong = 48;
  for (const double off : {0.3, 0.55, 0.8}) {
    if (off * cell_px < clear || (1.0 - off) * cell_px < clear) continue;
    const double lo = -off * cell, hi = 1.0 + off * cell;
    for (int i = 0; i <= kAlong; ++i) {
      const double f = lo + (hi - lo) * i / kAlong;
      for (const Eigen::Vector2d& q : {Eigen::Vector2d(f, lo), Eigen::Vector2d(f, hi),
                                       Eigen::Vector2d(lo, f), Eigen::Vector2d(hi, f)}) {
        const Eigen::Vector2d p = map(q.x(), q.y());
        if (p.x() < 0 || p.y() < 0 || p.x() > im.cols - 1 || p.y() > im.rows - 1) continue;
        ++n;
        if (im.Sample(p.x(), p.y()) < threshold) ++dark;
      }
    }
  }
  return n > 0 ? static_cast<double>(dark) / n : 0.0;
}

// Fits the edge from corner a to corner b (image coordinates); `inside` is a
// point inside the tag (the black side); `cell` the tag's cell size [px].
EdgeFit FitEdge(const ImageView& im, const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                const Eigen::Vector2d& inside, double cell, int width_at_border, double noise_floor,
                Pixels* buffer) {
  EdgeFit e;
  const double len = (b - a).norm();
  if (len < 4) return e;
  const Eigen::Vector2d t = (b - a) / len;
  Eigen::Vector2d n(-t.y(), t.x());
  if (n.dot(inside - a) > 0) n = -n;  // n points out of the tag (to the white side)
  e.origin = 0.5 * (a + b);
  e.theta = std::atan2(n.y(), n.x());
  // Border thickness across this edge: the distance to the tag centre is
  // half the border width, so one cell is 2 d / width_at_border.
  const double cell_across = std::min(cell, 2.0 * std::abs(n.dot(inside - a)) / width_at_border);
  const double band = std::clamp(cell_across - 0.6, 1.0, 3.5);
  const double end_gap = std::min(band + 0.5, 0.3 * len);
  Pixels& px = *buffer;
  px.clear();
  std::vector<double> wv, bv;
  ForEachPixelInRect(e.origin, t, n, 0.5 * len - end_gap, band, im.cols, im.rows,
                     [&](int x, int y) {
                       const Eigen::Vector2d p(x - e.origin.x(), y - e.origin.y());
                       const double v = im.At(x, y);
                       px.p.push_back(p);
                       px.v.push_back(v);
                       const double d = n.dot(p);
                       if (d > 0.7) wv.push_back(v);
                       if (d < -0.7) bv.push_back(v);
                     });
  // A border under ~1.5 px (small or oblique tag): the band may hold no
  // clearly white or black pixel; start the levels from the extremes.
  if (px.p.size() >= 8 && wv.empty()) wv.push_back(*std::max_element(px.v.begin(), px.v.end()));
  if (px.p.size() >= 8 && bv.empty()) bv.push_back(*std::min_element(px.v.begin(), px.v.end()));
  if (px.p.size() < 8 || wv.empty() || bv.empty()) return e;
  // Levels: medians of the clearly white / black sides.
  auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  Eigen::Matrix<double, 5, 1> x0;
  x0 << e.theta, 0.0, median(bv), median(wv), 0.4;
  EdgeModel model;
  const LmResult<5> fit = FitModel<5>(px, x0, model, 20);
  if (!fit.ok) return e;
  e.theta = fit.x[0];
  e.rho = fit.x[1];
  e.b = fit.x[2];
  e.w = fit.x[3];
  e.sigma = std::max(fit.x[4], kMinBlur);
  e.rms = fit.rms;
  e.n = static_cast<int>(px.p.size());
  const double noise = NoiseOf(fit.rms, noise_floor);
  // Covariance of (theta, rho, b, w) with the blur held at its estimate (the
  // blur is nearly unobservable on a sharp, pixel-aligned edge).
  const Eigen::Matrix4d jtj = fit.jtj.block<4, 4>(0, 0);
  const Eigen::Matrix4d cov = noise * noise * jtj.inverse();
  e.cov = cov.block<2, 2>(0, 0);
  e.ok = cov.allFinite() && std::abs(e.rho) < band && e.w - e.b > 0;
  return e;
}

// Corners (libapriltag order) from the four edge lines; edge i joins corner i
// and corner i+1, so corner i is edge (i+3)%4 x edge i.
bool CornersFromEdges(const std::array<Line, 4>& lines, std::array<Eigen::Vector2d, 4>* corners) {
  for (int i = 0; i < 4; ++i) {
    if (!Intersect(lines[(i + 3) % 4], lines[i], &(*corners)[i])) return false;
  }
  return true;
}

bool CentreFromCorners(const std::array<Eigen::Vector2d, 4>& c, Eigen::Vector2d* centre) {
  return IntersectSegments(c[0], c[2], c[1], c[3], centre);
}

// Covariance of the tag centre (diagonal intersection) from the covariances
// of the four line fits (numeric Jacobian).
Eigen::Matrix2d CentreCovariance(const std::array<EdgeFit, 4>& edges,
                                 const std::array<Line, 4>& lines) {
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (int k = 0; k < 4; ++k) {
    Eigen::Matrix2d jac;
    for (int j = 0; j < 2; ++j) {
      const double h = 1e-6;
      std::array<Line, 4> lp = lines, lm = lines;
      lp[k] = ToLine(edges[k], j == 0 ? h : 0, j == 1 ? h : 0);
      lm[k] = ToLine(edges[k], j == 0 ? -h : 0, j == 1 ? -h : 0);
      std::array<Eigen::Vector2d, 4> cp, cm;
      Eigen::Vector2d xp = Eigen::Vector2d::Zero(), xm = Eigen::Vector2d::Zero();
      CornersFromEdges(lp, &cp);
      CornersFromEdges(lm, &cm);
      CentreFromCorners(cp, &xp);
      CentreFromCorners(cm, &xm);
      jac.col(j) = (xp - xm) / (2 * h);
    }
    cov += jac * edges[k].cov * jac.transpose();
  }
  return cov;
}

// ---------------------------------------------------------------------------
// Circles.

// The detector's corners as published when the edge model cannot do better:
// the covariance then follows the decode contrast (decision margin, about the
// black/white difference in DN) and the tag size: an edge of L px at noise s
// and contrast C places a line to ~ s / C / sqrt(L).
void PublishDetectorCorners(const apriltag_detection_t* det, Observation o,
                            const Eigen::Matrix2d& extra_cov, Frame* f) {
  const double contrast_proxy = std::max(static_cast<double>(det->decision_margin), 1.0);
  const double sigma =
      std::max(f->noise_floor, 2.0) / contrast_proxy * std::sqrt(8.0 / std::max(o.size_px, 1.0));
  o.method = CentreMethod::kDetector;
  o.centre = o.detector_centre;
  o.covariance = Eigen::Matrix2d::Identity() * sigma * sigma + extra_cov;
  if (o.quality <= 0.0) o.quality = 0.5 * std::clamp(det->decision_margin / 100.0, 0.0, 1.0);
  f->res.observations.push_back(o);
  f->res.summary.num_tags++;
  if (!o.role) f->res.summary.num_unknown++;
}

// A decoded tag as an observation with the detector's corners (OpenCV's
// pixel convention), its role and size.
Observation TagFromDetection(const apriltag_detection_t* det, const io::TargetList& targets) {
  Observation o;
  o.id = det->id;
  o.family = det->family->name;
  o.decision_margin = det->decision_margin;
  o.hamming = det->hamming;
  o.has_corners = true;
  for (int k = 0; k < 4; ++k) {
    o.corners[k] =
        Eigen::Vector2d(det->p[k][0] - kAprilTagPixelOffset, det->p[k][1] - kAprilTagPixelOffset);
  }
  o.detector_centre =
      Eigen::Vector2d(det->c[0] - kAprilTagPixelOffset, det->c[1] - kAprilTagPixelOffset);
  o.centre = o.detector_centre;
  if (const io::TargetSpec* spec = targets.Find(o.family, det->id)) o.role = spec->role;
  double edge_sum = 0;
  for (int k = 0; k < 4; ++k) edge_sum += (o.corners[(k + 1) % 4] - o.corners[k]).norm();
  o.size_px = edge_sum / 4;
  return o;
}

// The edge-model fits of a tag's four edges (pixels of a narrow band along
// each edge only) and what they say: the worst residual / contrast, the
// largest blur, the smallest contrast.
struct TagEdges {
  std::array<EdgeFit, 4> edges;
  bool ok = true;
  double worst_rel = 0, blur = 0, contrast = 1e9;
};

TagEdges FitTagEdges(const apriltag_detection_t* det, const Observation& o, double cell,
                     Pixels* buffer, const Frame& f) {
  TagEdges t;
  for (int k = 0; k < 4; ++k) {
    t.edges[k] = FitEdge(f.im, o.corners[k], o.corners[(k + 1) % 4], o.centre, cell,
                         det->family->width_at_border, f.noise_floor, buffer);
    if (!t.edges[k].ok) {
      t.ok = false;
      break;
    }
    const double c = t.edges[k].w - t.edges[k].b;
    t.contrast = std::min(t.contrast, c);
    t.worst_rel = std::max(t.worst_rel, t.edges[k].rms / std::max(c, 1e-9));
    t.blur = std::max(t.blur, t.edges[k].sigma);
  }
  return t;
}

// Samples of the white surround along the edges at or above the saturation
// level: (saturated, total).
std::pair<int, int> SaturatedSurround(const Observation& o, const TagEdges& t, double cell,
                                      const Frame& f) {
  int sat = 0, tot = 0;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d a = o.corners[k], b = o.corners[(k + 1) % 4];
    const Eigen::Vector2d nrm = t.edges[k].Normal();
    for (int j = 1; j < 16; ++j) {
      const Eigen::Vector2d p = a + (b - a) * (j / 16.0) + nrm * (0.5 * cell);
      ++tot;
      if (f.im.Sample(p.x(), p.y()) >= f.options.saturation_level) ++sat;
    }
  }
  return {sat, tot};
}

// Something in front of part of the plate bends the edge fits without
// raising their residual much (the occluder sits in the white surround, next
// to the band): the share of the whole surround that is dark.
double OccludedShare(const apriltag_detection_t* det, const TagEdges& t,
                     const std::array<Line, 4>& lines, double cell, const Frame& f) {
  std::array<Eigen::Vector2d, 4> outer;
  double black = 0.0, white = 0.0;
  for (int k = 0; k < 4; ++k) {
    black += 0.25 * t.edges[k].b;
    white += 0.25 * t.edges[k].w;
  }
  if (!CornersFromEdges(lines, &outer)) return 0.0;
  return DarkSurroundFraction(f.im, outer, det->family->width_at_border, cell, 1.5 * t.blur + 0.5,
                              black, white);
}

// One decoded tag: rejected, published with the detector's corners, or with
// the edge model's.
void MeasureTag(const apriltag_detection_t* det, const io::TargetList& targets, Pixels* buffer,
                Frame* f) {
  const Options& opt = f->options;
  Observation o = TagFromDetection(det, targets);
  f->tag_quads.push_back(o.corners);
  if (det->decision_margin < opt.min_decision_margin) {
    f->Reject(o.family, det->id, o.centre, RejectReason::kWeakDecode,
              Message("decision margin ", det->decision_margin, " < ", opt.min_decision_margin));
    return;
  }
  bool at_border = false;
  for (const auto& c : o.corners) at_border = at_border || f->NearBorder(c, 1.0);
  if (at_border) {
    f->Reject(o.family, det->id, o.centre, RejectReason::kBorder,
              "a corner within the border margin");
    return;
  }
  const double cell = o.size_px / det->family->width_at_border;
  const TagEdges t = FitTagEdges(det, o, cell, buffer, *f);
  if (!t.ok) {
    // The tag was decoded: its quad stands; no edge model to check it by.
    PublishDetectorCorners(det, o, Eigen::Matrix2d::Zero(), f);
    return;
  }
  o.contrast = t.contrast;
  o.edge_blur = t.blur;
  o.fit_residual = t.worst_rel;
  const auto [sat, tot] = SaturatedSurround(o, t, cell, *f);
  if (t.contrast < opt.min_contrast) {
    f->Reject(o.family, det->id, o.centre, RejectReason::kLowContrast,
              Message("edge contrast ", t.contrast, " DN"));
    return;
  }
  if (sat > opt.max_saturated_fraction * tot) {
    f->Reject(o.family, det->id, o.centre, RejectReason::kSaturated,
              Message(100 * sat / tot, "% of the white border saturated"));
    return;
  }
  // An edge the model does not explain (blurred beyond max_edge_blur, a
  // residual over max_residual: a neighbouring tag or texture in the band,
  // JPEG blocks): the decoded quad stands, with the detector's corners.
  if (t.blur > opt.max_edge_blur || t.worst_rel > opt.max_residual) {
    o.quality = 0.0;
    PublishDetectorCorners(det, o, Eigen::Matrix2d::Zero(), f);
    return;
  }
  std::array<Line, 4> lines;
  for (int k = 0; k < 4; ++k) lines[k] = ToLine(t.edges[k]);
  const double dark = OccludedShare(det, t, lines, cell, *f);
  if (dark > opt.max_dark_surround) {
    f->Reject(o.family, det->id, o.centre, RejectReason::kPartial,
              Message(std::lround(100.0 * dark), "% of the white surround dark (occluded)"));
    return;
  }
  o.quality = std::clamp(det->decision_margin / 100.0, 0.0, 1.0) *
              std::clamp(1.0 - t.worst_rel / opt.max_residual, 0.0, 1.0);
  std::array<Eigen::Vector2d, 4> corners;
  Eigen::Vector2d centre;
  if (!CornersFromEdges(lines, &corners) || !CentreFromCorners(corners, &centre) ||
      (centre - o.detector_centre).norm() > 0.25 * o.size_px) {
    PublishDetectorCorners(det, o, Eigen::Matrix2d::Zero(), f);  // the lines make no quad
    return;
  }
  const Eigen::Matrix2d cov = CentreCovariance(t.edges, lines);
  for (const auto& e : t.edges) f->residuals.push_back(e.rms);
  // Per tag: the refined corners replace the detector's only where the edge
  // model explains the pixels (residual) and places the centre precisely
  // (covariance). Otherwise the detector's corners stand, with the
  // disagreement of the two added to their covariance.
  const double sigma_max = std::sqrt(
      std::max(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(1), 0.0));
  if (!opt.refine_tags || t.worst_rel > opt.tag_refine_max_residual ||
      !(sigma_max <= opt.tag_refine_max_sigma)) {
    const Eigen::Vector2d d = centre - o.detector_centre;
    PublishDetectorCorners(
        det, o, opt.refine_tags ? Eigen::Matrix2d(d * d.transpose()) : Eigen::Matrix2d(cov), f);
    return;
  }
  o.method = CentreMethod::kEdgeModel;
  o.corners = corners;
  o.centre = centre;
  o.covariance = cov;
  f->res.observations.push_back(o);
  f->res.summary.num_tags++;
  if (!o.role) f->res.summary.num_unknown++;
}

}  // namespace

void DetectTags(apriltag_detector* td, const cv::Mat& mono8, const io::TargetList& targets,
                Pixels* buffer, Frame* frame) {
  image_u8_t header{mono8.cols, mono8.rows, static_cast<int32_t>(mono8.step[0]),
                    const_cast<uint8_t*>(mono8.ptr<uint8_t>(0))};
  zarray_t* dets = apriltag_detector_detect(td, &header);
  for (int i = 0; i < zarray_size(dets); ++i) {
    apriltag_detection_t* det;
    zarray_get(dets, i, &det);
    MeasureTag(det, targets, buffer, frame);
  }
  apriltag_detections_destroy(dets);
}

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
