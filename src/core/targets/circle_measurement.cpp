// Stage 5 of TargetCentroider::DetectMono: measuring a circle candidate.
// The surround and the design first (what the candidate is), then the
// gray-weighted centroid of doc/design.md and its refinement by a least-squares
// fit of a blurred elliptical disc (centre, shape, the two levels, blur) to
// the pixels around the light centre's edge, with the covariance of the
// fit; with a pose the perspective bias of the centre is removed.
#include "centroider_stages.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace detail {
namespace {

// Ellipse intensity model: parameters cx, cy, A11, A12, A22 (shape matrix,
// (p-c)^T A (p-c) = 1 on the edge), ring level, disc level, blur sigma.
using EllipseParams = Eigen::Matrix<double, 8, 1>;

// An unlisted light centre with only a dark surround for evidence (dot,
// disc_in_ring; auto) is a disc when its edge blur sigma is at most this
// share of its radius. Measured: the renders' dots and discs 4-75 px in
// radius show 0.007-0.06; the specks of light taken for them on the drone
// and room photos (uav_real_caliterra, uav_real_copr, targets_real_cctag)
// 0.20-0.42. (The ring designs' rings are evidence of their own: the real
// ring board's markers show up to 0.15.)
constexpr double kMaxSpeckBlurShare = 0.15;

// Signed distance (inside positive) of p from the ellipse, to first order
// (1 - r) / |grad r| with r = sqrt((p-c)^T A (p-c)), and its outward normal
// A (p - c) / |A (p - c)| (the pixel footprint's direction).
struct EllipseModel {
  void Prepare(const EllipseParams&) {}
  // With dx = p - c, g = A dx, q = dx^T g, r = sqrt(q), G = |g|, the distance
  // is d = (r - q) / G; its derivatives w.r.t. c and A are analytic:
  //   dd = dq (1/(2r) - 1) / G - d dG / G,  dG = g^T dg / G.
  double operator()(const EllipseParams& x, const Eigen::Vector2d& p, EllipseParams* g) const {
    const double dx = p.x() - x[0], dy = p.y() - x[1];
    const double ax = x[2] * dx + x[3] * dy, ay = x[3] * dx + x[4] * dy;
    const double q = std::max(dx * ax + dy * ay, 1e-12);
    const double r = std::sqrt(q);
    const double gl = std::max(std::sqrt(ax * ax + ay * ay), 1e-12);
    const double igl = 1.0 / gl;
    const double d = (r - q) * igl;
    double fa, fb;
    Footprint(ax * igl, ay * igl, &fa, &fb);
    const double sigma = std::max(x[7], kMinBlur);
    const Profile pr = EdgeProfile(d, fa, fb, sigma);
    const double k = x[6] - x[5];
    const double kq = (0.5 / r - 1.0) * igl, kg = -d * igl * igl;  // dd = kq dq + kg (g^T dg)
    const double s = k * pr.dd;
    (*g)[0] = s * (kq * (-2 * ax) + kg * (-(ax * x[2] + ay * x[3])));
    (*g)[1] = s * (kq * (-2 * ay) + kg * (-(ax * x[3] + ay * x[4])));
    (*g)[2] = s * (kq * dx * dx + kg * ax * dx);
    (*g)[3] = s * (kq * 2 * dx * dy + kg * (ax * dy + ay * dx));
    (*g)[4] = s * (kq * dy * dy + kg * ay * dy);
    (*g)[5] = 1.0 - pr.v;
    (*g)[6] = pr.v;
    (*g)[7] = x[7] > kMinBlur ? k * pr.ds : 0.0;
    return x[5] + k * pr.v;
  }
};

Eigen::Vector3d FitConicCentre(const std::vector<Eigen::Vector2d>& pts, Eigen::Vector2d* centre) {
  // Algebraic conic fit ax^2 + bxy + cy^2 + dx + ey + f = 0 on normalised points.
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : pts) mean += p;
  mean /= pts.size();
  double scale = 0;
  for (const auto& p : pts) scale += (p - mean).norm();
  scale = pts.size() / std::max(scale, 1e-12);
  Eigen::MatrixXd m(pts.size(), 6);
  for (size_t i = 0; i < pts.size(); ++i) {
    const Eigen::Vector2d q = (pts[i] - mean) * scale;
    m.row(i) << q.x() * q.x(), q.x() * q.y(), q.y() * q.y(), q.x(), q.y(), 1.0;
  }
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(m, Eigen::ComputeFullV);
  const Eigen::VectorXd v = svd.matrixV().col(5);
  Eigen::Matrix2d a;
  a << 2 * v[0], v[1], v[1], 2 * v[2];
  const Eigen::Vector2d c = a.fullPivLu().solve(Eigen::Vector2d(-v[3], -v[4]));
  *centre = c / scale + mean;
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

// The mean of 16 sectors of an annulus (3 angles x the 3 radii given, in
// radii of the blob) around a blob.
std::vector<double> SectorMeans(const ImageView& im, const Blob& blob,
                                const std::array<double, 3>& radii) {
  std::vector<double> sectors;
  for (int k = 0; k < 16; ++k) {
    double sum = 0;
    int n = 0;
    for (int j = 0; j < 3; ++j) {
      const double ang = 2 * M_PI * (k + j / 3.0) / 16;
      for (double s : radii) {
        const Eigen::Vector2d p = blob.At(ang, s);
        sum += im.Sample(p.x(), p.y());
        ++n;
      }
    }
    sectors.push_back(sum / n);
  }
  return sectors;
}

// Samples of the light centre (32 angles at 0.2, 0.45, 0.65 radii).
std::vector<double> CentreSamples(const ImageView& im, const Blob& blob) {
  std::vector<double> inner;
  for (int k = 0; k < 32; ++k) {
    const double ang = 2 * M_PI * k / 32;
    for (double s : {0.2, 0.45, 0.65}) {
      const Eigen::Vector2d p = blob.At(ang, s);
      inner.push_back(im.Sample(p.x(), p.y()));
    }
  }
  return inner;
}

// The plain gray-weighted centroid (doc/design.md) over the disc and the inner
// ring: pixels under the midpoint of the two levels set to 0.
Eigen::Vector2d GrayCentroidOfDisc(const ImageView& im, const Blob& blob, double disc,
                                   double ring) {
  const Eigen::Matrix2d shape = blob.Shape();
  const double thr = 0.5 * (disc + ring);
  double sq = 0, cx = 0, cy = 0;
  const double rr = 1.3;
  const int x0 = static_cast<int>(std::floor(blob.centre.x() - rr * blob.a)),
            x1 = static_cast<int>(std::ceil(blob.centre.x() + rr * blob.a));
  const int y0 = static_cast<int>(std::floor(blob.centre.y() - rr * blob.a)),
            y1 = static_cast<int>(std::ceil(blob.centre.y() + rr * blob.a));
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Eigen::Vector2d d(x - blob.centre.x(), y - blob.centre.y());
      if (d.dot(shape * d) > rr * rr) continue;
      const double v = im.At(x, y);
      const double q = v >= thr ? v : 0.0;
      sq += q;
      cx += q * x;
      cy += q * y;
    }
  }
  return sq > 0 ? Eigen::Vector2d(cx / sq, cy / sq) : blob.centre;
}

// The pixels of a band of half width `band` [px] around the blob's edge,
// centred on `centre`.
void EdgeBandPixels(const ImageView& im, const Blob& blob, const Eigen::Vector2d& centre,
                    double band, Pixels* px) {
  const Eigen::Matrix2d shape = blob.Shape();
  px->clear();
  const double rout = 1.0 + band / blob.b, rin = std::max(0.0, 1.0 - band / blob.b);
  const int xa = static_cast<int>(std::floor(blob.centre.x() - blob.a - band - 1)),
            xb = static_cast<int>(std::ceil(blob.centre.x() + blob.a + band + 1));
  const int ya = static_cast<int>(std::floor(blob.centre.y() - blob.a - band - 1)),
            yb = static_cast<int>(std::ceil(blob.centre.y() + blob.a + band + 1));
  for (int y = std::max(0, ya); y <= std::min(im.rows - 1, yb); ++y) {
    for (int x = std::max(0, xa); x <= std::min(im.cols - 1, xb); ++x) {
      const Eigen::Vector2d d(x - centre.x(), y - centre.y());
      const double r2 = d.dot(shape * d);
      if (r2 > rout * rout || r2 < rin * rin) continue;
      px->p.emplace_back(x, y);
      px->v.push_back(im.At(x, y));
    }
  }
}

// Where a candidate that fails goes: a listed circle expected here is a
// target that cannot be measured (a rejection); an unlisted candidate that
// shows a design's evidence is a marker (marker_radius > 0) and a rejection
// too; any other is not a target (discarded, debug output only).
struct Verdict {
  Frame* frame;
  const io::TargetSpec* spec;
  Eigen::Vector2d where;
  double marker_radius = 0.0;
  void Fail(RejectReason reason, const std::string& detail) const {
    if (spec || marker_radius > 0.0) {
      frame->Reject("circle", spec ? spec->id : -1, where, reason, detail);
      frame->res.rejections.back().radius_px = marker_radius;
    } else {
      frame->Discard(where, reason, detail);
    }
  }
};

// The light centre and its dark surround: their levels, the design, and
// whether the surround is whole and the centre not saturated. False (with
// the verdict given) when the candidate is not a measurable target.
struct Surround {
  double disc = 0, ring = 0, contrast = 0;
  DesignSeen seen;
};

bool JudgeSurround(const Blob& blob, const ExpectedCircle* expected, Verdict* verdict,
                   Surround* out) {
  const Frame& f = *verdict->frame;
  const Options& opt = f.options;
  const ImageView& im = f.im;
  // Surround: 16 sectors of the annulus 1.3..1.6 radii must be dark.
  const std::vector<double> inner_samples = CentreSamples(im, blob);
  std::vector<double> inner = inner_samples;
  std::vector<double> sectors = SectorMeans(im, blob, {1.3, 1.45, 1.6});
  const double disc = Percentile(inner, 0.5);
  double ring = Percentile(sectors, 0.5);
  double contrast = disc - ring;
  // (The darkest quarter of the sectors: a coded ring's light segments may
  // lift the median.)
  std::vector<double> sorted_sectors = sectors;
  if (disc - Percentile(sorted_sectors, 0.25) < opt.min_contrast) {  // bright texture
    verdict->frame->Discard(blob.centre, RejectReason::kLowContrast,
                            Message("disc/ring contrast ", contrast, " DN"));
    return false;
  }
  double worst_sector = *std::max_element(sectors.begin(), sectors.end());
  // The design: where the dark part around the light centre ends.
  DesignSeen& seen = out->seen;
  std::string design_fault;
  if (!SeeDesign(im, blob, disc, ring, opt, &seen, &design_fault)) {
    verdict->Fail(RejectReason::kDesign, design_fault);
    return false;
  }
  // (A dot's evidence is weaker, a dark ground only: an unlisted dot that
  // cannot be measured is not called a marker.)
  if (seen.design != CircleDesign::kDot) verdict->marker_radius = blob.a * seen.outer;
  if (seen.design == CircleDesign::kRing || seen.design == CircleDesign::kConcentric) {
    // The centre's own dark ring may end before 1.3 radii (a thin inner
    // ring, a code band): the surround is judged within it.
    const double w = seen.first - 1.0;
    sectors = SectorMeans(im, blob, {1.0 + 0.45 * w, 1.0 + 0.55 * w, 1.0 + 0.65 * w});
    ring = Percentile(sectors, 0.5);
    contrast = disc - ring;
    worst_sector = *std::max_element(sectors.begin(), sectors.end());
  }
  // With a pose: the listed target's projected size.
  if (expected && expected->major_px > 0.0) {
    const double rel = blob.a / expected->major_px - 1.0;
    if (std::abs(rel) > opt.circle_size_tolerance) {
      verdict->Fail(RejectReason::kSize,
                    Message("semi-major axis ", blob.a, " px, circle/", expected->spec->id,
                            " projects to ", expected->major_px, " px"));
      return false;
    }
  }
  if (worst_sector > disc - 0.5 * contrast) {
    verdict->Fail(RejectReason::kPartial, "dark ring interrupted (occluded or partial target)");
    return false;
  }
  int sat = 0;
  for (double v : inner_samples) sat += v >= opt.saturation_level;
  if (sat > opt.max_saturated_fraction * inner_samples.size()) {
    verdict->Fail(
        RejectReason::kSaturated,
        Message(100 * sat / static_cast<int>(inner_samples.size()), "% of the disc saturated"));
    return false;
  }
  out->disc = disc;
  out->ring = ring;
  out->contrast = contrast;
  return true;
}

}  // namespace

void MeasureCircle(const Blob& blob, const ExpectedCircle* expected, const ViewGeometry* view,
                   Pixels* buffer, Frame* frame) {
  const Options& opt = frame->options;
  const ImageView& im = frame->im;
  const io::TargetSpec* spec = expected ? expected->spec : nullptr;
  Verdict verdict{frame, spec, blob.centre};
  if (frame->NearBorder(blob.centre, 1.7 * blob.a)) {
    verdict.Fail(RejectReason::kBorder, "disc and its ring reach the image border");
    return;
  }
  Surround s;
  if (!JudgeSurround(blob, expected, &verdict, &s)) return;
  Observation o;
  o.family = "circle";
  o.id = spec ? spec->id : -1;
  o.ring_ratio = s.seen.outer;
  o.design = s.seen.design;
  if (spec) o.role = spec->role;
  o.contrast = s.contrast;
  const Eigen::Matrix2d shape = blob.Shape();
  o.gray_centroid = GrayCentroidOfDisc(im, blob, s.disc, s.ring);
  o.centre = o.gray_centroid;
  o.size_px = blob.a + blob.b;
  // Intensity-model ellipse fit on the pixels of a band around the edge.
  const double rmean = 0.5 * (blob.a + blob.b);
  const double band = std::clamp(0.25 * rmean, 1.5, 4.0);
  EllipseParams x0;
  x0 << o.gray_centroid.x(), o.gray_centroid.y(), shape(0, 0), shape(0, 1), shape(1, 1), s.ring,
      s.disc, 0.4;
  EdgeBandPixels(im, blob, o.gray_centroid, band, buffer);
  EllipseModel model;
  const LmResult<8> fit = FitModel<8>(*buffer, x0, model, 30);
  if (!fit.ok || (fit.x.head<2>() - o.gray_centroid).norm() > 0.25 * rmean) {
    verdict.marker_radius = 0.0;  // unlisted: no model, no marker
    verdict.Fail(RejectReason::kFitFailed, "ellipse model fit did not converge");
    return;
  }
  const double fit_contrast = fit.x[6] - fit.x[5];
  const double rel = fit.rms / std::max(fit_contrast, 1e-9);
  o.fit_residual = rel;
  o.edge_blur = std::max(fit.x[7], kMinBlur);
  if (o.edge_blur > opt.max_edge_blur) {
    verdict.Fail(RejectReason::kBlurred, Message("edge blur sigma ", o.edge_blur, " px"));
    return;
  }
  // Unlisted, auto, a dark surround only: a light speck on a dark ground is
  // everywhere (glints, sky through a canopy); a printed or retro-reflective
  // disc is resolved, its radius several times its edge blur (a point of
  // light looks like a disc about 2 blur sigmas across). While the list
  // holds circles, an unidentified one (no pose for this image) stays: the
  // adjuster names such circles later.
  const bool surround_only =
      (s.seen.design == CircleDesign::kDot || s.seen.design == CircleDesign::kDiscInRing) &&
      !frame->listed_circles;
  if (surround_only && !spec && opt.circle_design == CircleDesign::kAuto &&
      o.edge_blur > kMaxSpeckBlurShare * rmean) {
    verdict.marker_radius = 0.0;  // no marker: discarded
    verdict.Fail(RejectReason::kDesign, Message(CircleDesignName(s.seen.design), " of radius ",
                                                rmean, " px, edge blur sigma ", o.edge_blur,
                                                " px: a speck of light, not a disc"));
    return;
  }
  if (rel > opt.max_residual) {
    verdict.marker_radius = 0.0;  // unlisted: the model does not explain it, no marker
    verdict.Fail(RejectReason::kPartial, Message("ellipse fit residual ", rel, " of the contrast"));
    return;
  }
  if (rel > opt.circle_max_residual) {
    verdict.Fail(RejectReason::kResidual, Message("ellipse fit residual ", rel,
                                                  " of the contrast > ", opt.circle_max_residual));
    return;
  }
  const double noise = NoiseOf(fit.rms, frame->noise_floor);
  const Eigen::Matrix<double, 7, 7> cov = noise * noise * fit.jtj.block<7, 7>(0, 0).inverse();
  frame->residuals.push_back(fit.rms);
  o.method = CentreMethod::kGrayCentroid;
  if (opt.refine_circles) {
    o.centre = fit.x.head<2>();
    o.method = CentreMethod::kEllipseModel;
  }
  o.covariance = cov.block<2, 2>(0, 0);
  if (!o.covariance.allFinite()) {
    verdict.Fail(RejectReason::kFitFailed, "singular ellipse fit");
    return;
  }
  if (opt.correct_perspective && view && spec && spec->position && spec->normal) {
    o.perspective_correction =
        CirclePerspectiveBias(*view, *spec->position, *spec->normal, spec->size);
    o.centre -= o.perspective_correction;
    o.perspective_corrected = true;
  }
  o.quality = std::clamp(fit_contrast / 100.0, 0.0, 1.0) *
              std::clamp(1.0 - rel / opt.max_residual, 0.0, 1.0);
  frame->res.observations.push_back(o);
  frame->res.summary.num_circles++;
  if (!o.role) frame->res.summary.num_unknown++;
}

}  // namespace detail

Eigen::Vector2d CirclePerspectiveBias(const ViewGeometry& view,
                                      const Eigen::Vector3d& centre_in_site,
                                      const Eigen::Vector3d& normal_in_site, double diameter) {
  Eigen::Vector3d n = normal_in_site.normalized();
  Eigen::Vector3d u = n.unitOrthogonal();
  Eigen::Vector3d v = n.cross(u);
  Eigen::Vector2d projected_centre;
  if (!view.camera.Project(view.pose, centre_in_site, &projected_centre))
    return Eigen::Vector2d::Zero();
  std::vector<Eigen::Vector2d> pts;
  const int k = 72;
  for (int i = 0; i < k; ++i) {
    const double a = 2 * M_PI * i / k;
    Eigen::Vector2d px;
    if (!view.camera.Project(
            view.pose, centre_in_site + 0.5 * diameter * (std::cos(a) * u + std::sin(a) * v), &px))
      return Eigen::Vector2d::Zero();
    pts.push_back(px);
  }
  Eigen::Vector2d ellipse_centre;
  detail::FitConicCentre(pts, &ellipse_centre);
  return ellipse_centre - projected_centre;
}

}  // namespace targets
}  // namespace slope_monitor
