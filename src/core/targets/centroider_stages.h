// Internal to the targets module (not installed): what the centroider's
// stage files share. The stages of TargetCentroider::DetectMono, in order:
//   tag_detection.cpp         libapriltag's quads, then our edge-model refinement
//   ring_markers.cpp          markers of three or more rings, by their nested ellipses
//   circle_candidates.cpp     bright blobs with a dark surround, their ellipse
//   circle_identification.cpp listed circles projected, a candidate's ID, one target per marker
//   circle_design.cpp         which design the rays from a candidate show
//   circle_measurement.cpp    surround, gray-weighted centroid, ellipse-model refinement
// Each stage writes into one Frame (the per-image result and its rules).
// Pixel convention: OpenCV's (target_centroider.h).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include "slope_monitor/core/targets/target_centroider.h"

struct apriltag_detector;

namespace slope_monitor {
namespace targets {
namespace detail {

constexpr double kInvSqrt2Pi = 0.3989422804014327;
constexpr double kInvSqrt2 = 0.7071067811865476;
// libapriltag puts the centre of the top-left pixel at (0.5, 0.5).
constexpr double kAprilTagPixelOffset = 0.5;
// Smallest optical blur sigma of the edge models [px] (the pixel's own area
// is modelled separately, see EdgeProfile).
constexpr double kMinBlur = 0.1;

// The value of a blurred, pixel-integrated step edge and its derivatives
// with respect to the signed distance d and the blur sigma.
struct Profile {
  double v = 0, dd = 0, ds = 0;
};

// The fraction of a square pixel that is on the bright side of a straight
// step edge blurred by a Gaussian of std sigma: the pixel's centre is at
// signed distance d from the edge (bright side positive). The unit pixel
// projects on the edge normal (nx, ny) as the sum of two uniform variables of
// widths a = max(|nx|, |ny|) and b = min(|nx|, |ny|) (the footprint), so the
// value is the mean of Phi((d - a u1 - b u2) / sigma) over u1, u2 in
// [-1/2, 1/2], in closed form through the antiderivatives of Phi:
//   I1(u) = u Phi(u) + phi(u),  I2(u) = ((u^2 + 1) Phi(u) + u phi(u)) / 2,
// with I2' = I1, I1' = Phi, and the sigma derivatives
//   d/dsigma [sigma I1((d+c)/sigma)] = phi,  d/dsigma [sigma^2 I2(...)] = sigma Phi.
// Derivatives are analytic: one exp per corner of the footprint.
// Phi(u) and phi(u) with one exp: erfc by Abramowitz & Stegun 7.1.26
// (absolute error <= 1.5e-7, far below the noise of any image), whose
// exp(-x^2) at x = |u|/sqrt(2) is also the Gaussian density's.
inline void PhiAndDensity(double u, double* Phi, double* phi) {
  const double x = std::abs(u) * kInvSqrt2;
  const double e = std::exp(-x * x);
  const double t = 1.0 / (1.0 + 0.3275911 * x);
  const double q = t *
                   (0.254829592 +
                    t * (-0.284496736 + t * (1.421413741 + t * (-1.453152027 + t * 1.061405429)))) *
                   e;
  *Phi = u >= 0 ? 1.0 - 0.5 * q : 0.5 * q;
  *phi = kInvSqrt2Pi * e;
}

inline Profile EdgeProfile(double d, double a, double b, double sigma) {
  const double is = 1.0 / sigma;
  Profile out;
  if (b < 0.05) {
    double sgn = 1.0;
    for (double c : {0.5 * a, -0.5 * a}) {
      const double u = (d + c) * is;
      double Phi, phi;
      PhiAndDensity(u, &Phi, &phi);
      out.v += sgn * (u * Phi + phi);
      out.dd += sgn * Phi;
      out.ds += sgn * phi;
      sgn = -sgn;
    }
    out.v *= sigma / a;
    out.dd /= a;
    out.ds /= a;
    return out;
  }
  const double ha = 0.5 * a, hb = 0.5 * b;
  const double cs[4] = {ha + hb, ha - hb, -ha + hb, -ha - hb};
  const double sg[4] = {1.0, -1.0, -1.0, 1.0};
  double s2 = 0, s1 = 0, s0 = 0;
  for (int k = 0; k < 4; ++k) {
    const double u = (d + cs[k]) * is;
    double Phi, phi;
    PhiAndDensity(u, &Phi, &phi);
    s2 += sg[k] * (0.5 * ((u * u + 1.0) * Phi + u * phi));
    s1 += sg[k] * (u * Phi + phi);
    s0 += sg[k] * Phi;
  }
  const double iab = 1.0 / (a * b);
  out.v = sigma * sigma * iab * s2;
  out.dd = sigma * iab * s1;
  out.ds = sigma * iab * s0;
  return out;
}

// The pixel footprint widths (a >= b) of a unit pixel on the normal (nx, ny).
inline void Footprint(double nx, double ny, double* a, double* b) {
  *a = std::abs(nx);
  *b = std::abs(ny);
  if (*a < *b) std::swap(*a, *b);
}

// Read access to the measurement image: CV_8UC1 (8-bit inputs, no copy) or
// CV_32FC1 (deeper inputs on the 8-bit scale).
class ImageView {
 public:
  explicit ImageView(const cv::Mat& m)
      : m_(m), is8_(m.depth() == CV_8U), cols(m.cols), rows(m.rows) {}
  float At(int x, int y) const { return is8_ ? m_.ptr<uint8_t>(y)[x] : m_.ptr<float>(y)[x]; }
  // Bilinear sample (clamped to the image).
  double Sample(double x, double y) const {
    const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, cols - 2);
    const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, rows - 2);
    const double fx = std::clamp(x - x0, 0.0, 1.0), fy = std::clamp(y - y0, 0.0, 1.0);
    return (1 - fy) * ((1 - fx) * At(x0, y0) + fx * At(x0 + 1, y0)) +
           fy * ((1 - fx) * At(x0, y0 + 1) + fx * At(x0 + 1, y0 + 1));
  }
  const cv::Mat& mat() const { return m_; }

 private:
  const cv::Mat& m_;
  bool is8_;

 public:
  const int cols, rows;
};

// Pixels of a region as (x, y, value).
struct Pixels {
  std::vector<Eigen::Vector2d> p;
  std::vector<double> v;
  void clear() {
    p.clear();
    v.clear();
  }
};

// A small dense Levenberg-Marquardt for the intensity models below. The model
// has Prepare(x) (per-evaluation constants) and operator()(x, p, &g)
// returning the predicted value and its gradient w.r.t. the parameters. One
// model evaluation (value and Jacobian) per iteration: a trial step's
// Jacobian becomes the next iteration's when the step is accepted.
template <int N>
struct LmResult {
  Eigen::Matrix<double, N, 1> x;
  Eigen::Matrix<double, N, N> jtj;
  double rms = 0.0;
  int iterations = 0;
  bool ok = false;
};

template <int N, typename Model>
LmResult<N> FitModel(const Pixels& px, Eigen::Matrix<double, N, 1> x, Model& model, int max_iter) {
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  LmResult<N> out;
  const size_t n = px.p.size();
  if (n < static_cast<size_t>(2 * N)) return out;
  auto eval = [&](const Vec& xx, Mat* jtj, Vec* jtr) {
    model.Prepare(xx);
    double c = 0.0;
    jtj->setZero();
    jtr->setZero();
    Vec g;
    for (size_t i = 0; i < n; ++i) {
      const double r = model(xx, px.p[i], &g) - px.v[i];
      c += r * r;
      jtj->noalias() += g * g.transpose();
      *jtr += g * r;
    }
    return c;
  };
  double lambda = 1e-4;
  Mat jtj, jn;
  Vec jtr, rn;
  double c = eval(x, &jtj, &jtr);
  int it = 0;
  for (; it < max_iter; ++it) {
    Mat a = jtj;
    a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
    const Vec step = a.ldlt().solve(-jtr);
    if (!step.allFinite()) break;
    // Converged: the predicted decrease is negligible against the cost.
    if (-jtr.dot(step) <= 1e-6 * c + 1e-24) break;
    const Vec xn = x + step;
    const double cn = eval(xn, &jn, &rn);
    if (std::isfinite(cn) && cn < c) {
      const double rel = (c - cn) / std::max(c, 1e-30);
      x = xn;
      c = cn;
      jtj = jn;
      jtr = rn;
      lambda = std::max(lambda * 0.2, 1e-9);
      if (rel < 1e-6) break;
    } else {
      lambda *= 10.0;
      if (lambda > 1e6) break;
    }
  }
  out.x = x;
  out.jtj = jtj;
  out.iterations = it;
  out.rms = std::sqrt(c / std::max<double>(1.0, static_cast<double>(n) - N));
  out.ok = x.allFinite();
  return out;
}

inline double NoiseOf(double rms, double floor) { return std::max(rms, floor); }

// The f-quantile of v (reorders v; no copy).
inline double Percentile(std::vector<double>& v, double f) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(f * (v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

struct Blob {
  Eigen::Vector2d centre;
  double a = 0, b = 0;  // semi-axes [px]
  Eigen::Vector2d major{1, 0}, minor{0, 1};
  double area = 0;
  Eigen::Matrix2d Shape() const {
    return (major * major.transpose()) / (a * a) + (minor * minor.transpose()) / (b * b);
  }
  Eigen::Vector2d At(double ang, double s) const {
    return centre + s * (a * std::cos(ang) * major + b * std::sin(ang) * minor);
  }
};

// An ellipse from first and second moments; false when degenerate.
inline bool BlobFromMoments(double n, double sx, double sy, double sxx, double sxy, double syy,
                            Blob* blob) {
  if (n < 3) return false;
  blob->centre = Eigen::Vector2d(sx / n, sy / n);
  Eigen::Matrix2d m2;
  const double cx = blob->centre.x(), cy = blob->centre.y();
  m2 << sxx / n - cx * cx, sxy / n - cx * cy, sxy / n - cx * cy, syy / n - cy * cy;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(m2);
  if (!(es.eigenvalues()(0) > 0)) return false;
  // A uniform elliptical disc of semi-axes a, b has variances a^2/4, b^2/4.
  blob->a = 2 * std::sqrt(es.eigenvalues()(1));
  blob->b = 2 * std::sqrt(es.eigenvalues()(0));
  blob->major = es.eigenvectors().col(1);
  blob->minor = es.eigenvectors().col(0);
  blob->area = n;
  return true;
}

// The per-image state every stage writes to: the result, the measurement
// image and the rules for the border, rejections and discarded candidates.
struct Frame {
  Frame(const cv::Mat& measured, const Options& o, double noise)
      : im(measured), options(o), noise_floor(noise) {
    res.width = im.cols;
    res.height = im.rows;
  }
  const ImageView im;
  const Options& options;
  const double noise_floor;     // [DN] minimum image noise of the covariances
  bool listed_circles = false;  // the target list holds circles
  Result res;
  std::vector<double> residuals;                          // fit RMS of what was measured
  std::vector<std::array<Eigen::Vector2d, 4>> tag_quads;  // every decoded tag (no circle there)

  bool NearBorder(const Eigen::Vector2d& p, double extra) const {
    const double m = options.border_margin;
    return p.x() < m + extra || p.y() < m + extra || p.x() > im.cols - 1 - m - extra ||
           p.y() > im.rows - 1 - m - extra;
  }
  // A target seen but not measured.
  void Reject(const std::string& family, int id, const Eigen::Vector2d& where, RejectReason reason,
              const std::string& detail) {
    Rejection r;
    r.family = family;
    r.id = id;
    r.where = where;
    r.reason = reason;
    r.detail = detail;
    res.rejections.push_back(r);
    res.summary.rejects_by_reason[RejectReasonName(reason)]++;
  }
  // A circle candidate that is not a target of the design (debug output).
  void Discard(const Eigen::Vector2d& where, RejectReason reason, const std::string& detail) {
    Rejection r;
    r.family = "circle";
    r.where = where;
    r.reason = reason;
    r.detail = detail;
    res.discarded.push_back(r);
  }
};

// --- tag_detection.cpp ---
// Decodes the tags of mono8 and measures each (edge model or the detector's
// corners); every decoded quad goes to frame->tag_quads.
void DetectTags(apriltag_detector* td, const cv::Mat& mono8, const io::TargetList& targets,
                Pixels* buffer, Frame* frame);

// --- circle_candidates.cpp ---
// Work buffers of the candidate stage (kept between frames).
struct CandidateBuffers {
  cv::Mat small, thr, bright, labels, stats, centroids;
  int f = 1;  // reduction of the candidate level
  int n = 0;  // connected components (label 0 is the background)
};
// The bright components of mono8 on one reduced level (tags masked out).
void FindBrightComponents(const cv::Mat& mono8, CandidateBuffers* b, Frame* frame);
// The full-resolution ellipse of component `label`; false (discarded with
// the reason, or silently when it is no candidate at all) otherwise.
bool CandidateBlob(const CandidateBuffers& b, int label, Frame* frame, Blob* blob);

// --- ring_markers.cpp ---
// One edge of a ring marker: an ellipse [px] and which side is dark.
struct EdgeEllipse {
  Eigen::Vector2d centre{0, 0};
  double a = 0, b = 0;  // semi-axes [px], a >= b
  Eigen::Vector2d major{1, 0};
  bool dark_inside = false;  // the outer edge of a dark ring
  bool cut = false;          // its contour ran into the image border
  double rms = 0;            // [px] distance of its points from the ellipse
  double coverage = 0;       // share of its perimeter with points
  int points = 0;            // refined edges: the points fitted
  double MeanRadius() const { return 0.5 * (a + b); }
};
// A marker of kMinRings or more dark rings: its edges from the outside in,
// the image of the rings' common centre and its covariance.
struct RingMarker {
  std::vector<EdgeEllipse> edges;
  int rings = 0;
  Eigen::Vector2d centre{0, 0};
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
  bool partial = false;  // cut by the image border: named, not measured
  std::string detail;    // partial: why
  double contrast = 0;   // [DN] light ground minus dark ring
  double fit_rms = 0;    // [px] worst edge's RMS distance
};
// A candidate group of nested ellipses that is no marker (debug output).
struct RingDiscard {
  Eigen::Vector2d where;
  std::string detail;
};
// The ring markers of mono8 (measured on im).
void FindRingMarkers(const ImageView& im, const cv::Mat& mono8, const Options& o,
                     std::vector<RingMarker>* markers, std::vector<RingDiscard>* discarded);
// The ring markers as observations (measured; the ID read from the edge
// radii when one listed ring marker matches them) and rejections
// (partial); the groups that are none as discarded candidates.
void AddRingMarkers(const cv::Mat& mono8, const io::TargetList& list, Frame* frame,
                    std::vector<RingMarker>* markers);
// Whether p lies within a marker's outer edge.
bool InsideRingMarker(const std::vector<RingMarker>& markers, const Eigen::Vector2d& p);
// The conic matrix of an ellipse (x^T C x = 0 on it, x homogeneous).
Eigen::Matrix3d ConicOf(const EdgeEllipse& e);
// The image of the common centre of two concentric circles from their
// images: the point the pencil outer - lambda inner degenerates to at its
// single eigenvalue (the other two are equal for exact concentric circles).
bool CommonCentre(const EdgeEllipse& inner, const EdgeEllipse& outer, Eigen::Vector2d* centre);

// --- circle_identification.cpp ---
// A listed circle projected into the image (with a view).
struct ExpectedCircle {
  const io::TargetSpec* spec;
  Eigen::Vector2d px;
  double radius_px;
  double major_px;  // semi-major axis of the projected disc (0: unknown)
};
std::vector<ExpectedCircle> ProjectListedCircles(const ViewGeometry* view,
                                                 const io::TargetList& targets);
// The listed circle a blob is (nullptr: none within circle_id_gate).
const ExpectedCircle* IdentifyCircle(const std::vector<ExpectedCircle>& expected, const Blob& blob,
                                     const Options& o);
// One target per marker (see CircleDesign).
void DropNestedCircles(Result* res);

// --- circle_design.cpp ---
// What the 32 rays from a light centre show beyond it (CircleDesign): the
// design, the outer edge of the dark part and the first dark->light edge
// (both in radii of the light centre, medians over the rays).
struct DesignSeen {
  CircleDesign design = CircleDesign::kAuto;
  double outer = 0.0;  // dot: 0
  double first = 0.0;  // ring designs: the first light after the centre's dark ring
};
// The design of the configured ones that the rays show; false with the
// fault otherwise. disc and ring: the light centre's and the dark ring's levels.
bool SeeDesign(const ImageView& im, const Blob& blob, double disc, double ring, const Options& o,
               DesignSeen* seen, std::string* fault);

// --- circle_measurement.cpp ---
// Measures a candidate (its listed circle when identified): surround and
// design, the gray-weighted centroid, the ellipse-model refinement, the
// perspective correction; an observation, a rejection or a discarded
// candidate in frame->res.
void MeasureCircle(const Blob& blob, const ExpectedCircle* expected, const ViewGeometry* view,
                   Pixels* buffer, Frame* frame);

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
