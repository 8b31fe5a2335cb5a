#include "slope_monitor/core/targets/target_centroider.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <mutex>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace {

constexpr double kInvSqrt2Pi = 0.3989422804014327;
constexpr double kInvSqrt2 = 0.7071067811865476;
// libapriltag puts the centre of the top-left pixel at (0.5, 0.5).
constexpr double kAprilTagPixelOffset = 0.5;
// Smallest optical blur sigma of the edge models [px] (the pixel's own area
// is modelled separately, see EdgeProfile).
constexpr double kMinBlur = 0.1;

struct FamilyFactory {
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const std::map<std::string, FamilyFactory>& Factories() {
  static const std::map<std::string, FamilyFactory> f = {
      {"tag36h11", {tag36h11_create, tag36h11_destroy}},
      {"tag36h10", {tag36h10_create, tag36h10_destroy}},
      {"tag25h9", {tag25h9_create, tag25h9_destroy}},
      {"tag16h5", {tag16h5_create, tag16h5_destroy}},
      {"tagStandard41h12", {tagStandard41h12_create, tagStandard41h12_destroy}},
      {"tagStandard52h13", {tagStandard52h13_create, tagStandard52h13_destroy}},
      {"tagCircle21h7", {tagCircle21h7_create, tagCircle21h7_destroy}},
      {"tagCircle49h12", {tagCircle49h12_create, tagCircle49h12_destroy}},
      {"tagCustom48h12", {tagCustom48h12_create, tagCustom48h12_destroy}},
  };
  return f;
}

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

double NoiseOf(double rms, double floor) { return std::max(rms, floor); }

// The f-quantile of v (reorders v; no copy).
double Percentile(std::vector<double>& v, double f) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(f * (v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

// ---------------------------------------------------------------------------
void Options::Check() const {
  auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError(Message("targets option '", key, "' ", what));
  };
  if (families.empty() && !detect_circles)
    fail("families", "is empty and detect_circles is false: nothing to detect");
  for (const auto& f : families) {
    if (!Factories().count(f)) fail("families", "has unknown tag family '" + f + "'");
  }
  if (!(quad_decimate >= 1.0 && quad_decimate <= 8.0))
    fail("quad_decimate", Message("= ", quad_decimate, " is outside [1, 8]"));
  if (!(quad_sigma >= 0.0 && quad_sigma <= 10.0))
    fail("quad_sigma", Message("= ", quad_sigma, " px is outside [0, 10]"));
  if (!(decode_sharpening >= 0.0 && decode_sharpening <= 10.0))
    fail("decode_sharpening", Message("= ", decode_sharpening, " is outside [0, 10]"));
  if (threads < 1 || threads > 64) fail("threads", Message("= ", threads, " is outside [1, 64]"));
  if (max_hamming < 0 || max_hamming > 3)
    fail("max_hamming", Message("= ", max_hamming, " is outside [0, 3]"));
  if (!(min_decision_margin >= 0.0)) fail("min_decision_margin", "must be >= 0");
  if (!(circle_min_diameter >= 4.0 && circle_min_diameter <= circle_max_diameter))
    fail("circle_min_diameter",
         Message("= ", circle_min_diameter, " px must be in [4, circle_max_diameter]"));
  if (!(circle_max_diameter <= 2000.0))
    fail("circle_max_diameter", Message("= ", circle_max_diameter, " px is over 2000"));
  if (!(circle_max_eccentricity > 0.0 && circle_max_eccentricity < 1.0))
    fail("circle_max_eccentricity", "must be in (0, 1)");
  if (!(circle_id_gate > 0.0 && circle_id_gate <= 5.0)) fail("circle_id_gate", "must be in (0, 5]");
  if (!(min_contrast > 0.0 && min_contrast < 255.0))
    fail("min_contrast", Message("= ", min_contrast, " DN is outside (0, 255)"));
  if (!(border_margin >= 0.0 && border_margin <= 100.0))
    fail("border_margin", "must be in [0, 100] px");
  if (!(saturation_level > 0.0 && saturation_level <= 255.0))
    fail("saturation_level", "must be in (0, 255] DN");
  if (!(max_saturated_fraction >= 0.0 && max_saturated_fraction <= 1.0))
    fail("max_saturated_fraction", "must be in [0, 1]");
  if (!(max_edge_blur > 0.0 && max_edge_blur <= 20.0))
    fail("max_edge_blur", "must be in (0, 20] px");
  if (!(max_residual > 0.0 && max_residual <= 1.0)) fail("max_residual", "must be in (0, 1]");
  if (!(max_dark_surround > 0.0 && max_dark_surround <= 1.0))
    fail("max_dark_surround", "must be in (0, 1]");
  if (!(noise_floor >= 0.0 && noise_floor <= 50.0)) fail("noise_floor", "must be in [0, 50] DN");
  if (!(tag_refine_max_residual > 0.0 && tag_refine_max_residual <= 1.0))
    fail("tag_refine_max_residual", "must be in (0, 1]");
  if (!(tag_refine_max_sigma > 0.0 && tag_refine_max_sigma <= 10.0))
    fail("tag_refine_max_sigma", "must be in (0, 10] px");
  if (!(circle_ring_ratio > 1.0 && circle_ring_ratio <= 10.0))
    fail("circle_ring_ratio", Message("= ", circle_ring_ratio, " is outside (1, 10]"));
  if (!(circle_ring_ratio_tolerance > 0.0 && circle_ring_ratio_tolerance <= 1.0))
    fail("circle_ring_ratio_tolerance", "must be in (0, 1]");
  if (!(circle_max_residual > 0.0 && circle_max_residual <= 1.0))
    fail("circle_max_residual", "must be in (0, 1]");
  if (!(circle_size_tolerance > 0.0 && circle_size_tolerance <= 1.0))
    fail("circle_size_tolerance", "must be in (0, 1]");
}

std::string CircleDesignName(CircleDesign design) {
  switch (design) {
    case CircleDesign::kAuto:
      return "auto";
    case CircleDesign::kDiscInRing:
      return "disc_in_ring";
    case CircleDesign::kDot:
      return "dot";
    case CircleDesign::kRing:
      return "ring";
    case CircleDesign::kConcentric:
      return "concentric";
  }
  return "unknown";
}

CircleDesign ParseCircleDesign(const std::string& name, const std::string& key) {
  for (CircleDesign d : {CircleDesign::kAuto, CircleDesign::kDiscInRing, CircleDesign::kDot,
                         CircleDesign::kRing, CircleDesign::kConcentric}) {
    if (CircleDesignName(d) == name) return d;
  }
  throw ConfigError(Message("targets option '", key, "' = '", name,
                            "' is not a circle design (auto, disc_in_ring, dot, ring, concentric)"));
}

std::string RejectReasonName(RejectReason reason) {
  switch (reason) {
    case RejectReason::kBorder:
      return "border";
    case RejectReason::kSaturated:
      return "saturated";
    case RejectReason::kBlurred:
      return "blurred";
    case RejectReason::kPartial:
      return "partial";
    case RejectReason::kLowContrast:
      return "low_contrast";
    case RejectReason::kWeakDecode:
      return "weak_decode";
    case RejectReason::kFitFailed:
      return "fit_failed";
    case RejectReason::kNotDisc:
      return "not_disc";
    case RejectReason::kDesign:
      return "design";
    case RejectReason::kResidual:
      return "residual";
    case RejectReason::kSize:
      return "size";
  }
  return "unknown";
}

std::string CentreMethodName(CentreMethod method) {
  switch (method) {
    case CentreMethod::kEdgeModel:
      return "edge_model";
    case CentreMethod::kDetector:
      return "detector";
    case CentreMethod::kEllipseModel:
      return "ellipse_model";
    case CentreMethod::kGrayCentroid:
      return "gray_centroid";
  }
  return "unknown";
}

const std::vector<std::string>& SupportedEncodings() {
  static const std::vector<std::string> e = {
      "mono8",        "mono16",       "bgr8",         "rgb8",        "bgra8",
      "rgba8",        "bayer_rggb8",  "bayer_bggr8",  "bayer_gbrg8", "bayer_grbg8",
      "bayer_rggb16", "bayer_bggr16", "bayer_gbrg16", "bayer_grbg16"};
  return e;
}

MonoImage ToMono(const cv::Mat& image, const std::string& encoding) {
  const auto& enc = SupportedEncodings();
  if (std::find(enc.begin(), enc.end(), encoding) == enc.end()) {
    std::string list;
    for (const auto& e : enc) list += (list.empty() ? "" : ", ") + e;
    throw InvalidArgument(
        Message("image encoding '", encoding, "' is not supported (supported: ", list, ")"));
  }
  if (image.empty() || image.cols < 2 || image.rows < 2) {
    throw InvalidArgument(
        Message("image is empty (", image.cols, "x", image.rows, ", encoding '", encoding, "')"));
  }
  auto need = [&](int type) {
    if (image.type() != type) {
      throw InvalidArgument(Message("image of encoding '", encoding, "' has ", image.channels(),
                                    " channel(s) of depth ", image.depth(),
                                    ", which does not match the encoding"));
    }
  };
  MonoImage out;
  cv::Mat gray;  // 8U or 16U
  const bool is16 =
      encoding == "mono16" || (encoding.size() > 2 && encoding.substr(encoding.size() - 2) == "16");
  if (encoding == "mono8" || encoding == "mono16") {
    need(is16 ? CV_16UC1 : CV_8UC1);
    gray = image;  // no copy
  } else if (encoding == "bgr8" || encoding == "rgb8") {
    need(CV_8UC3);
    cv::cvtColor(image, gray, encoding == "bgr8" ? cv::COLOR_BGR2GRAY : cv::COLOR_RGB2GRAY);
  } else if (encoding == "bgra8" || encoding == "rgba8") {
    need(CV_8UC4);
    cv::cvtColor(image, gray, encoding == "bgra8" ? cv::COLOR_BGRA2GRAY : cv::COLOR_RGBA2GRAY);
  } else {
    need(is16 ? CV_16UC1 : CV_8UC1);
    // ROS bayer names give the pattern of the top-left 2x2; OpenCV names it by
    // the second row's middle pair (cv_bridge uses the same mapping).
    const std::string pattern = encoding.substr(6, 4);
    int code = cv::COLOR_BayerBG2BGR;
    if (pattern == "rggb") code = cv::COLOR_BayerBG2BGR;
    if (pattern == "bggr") code = cv::COLOR_BayerRG2BGR;
    if (pattern == "gbrg") code = cv::COLOR_BayerGR2BGR;
    if (pattern == "grbg") code = cv::COLOR_BayerGB2BGR;
    cv::Mat bgr;
    cv::cvtColor(image, bgr, code);
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  }
  if (gray.depth() == CV_16U) {
    gray.convertTo(out.intensity, CV_32F, 1.0 / 257.0);
    gray.convertTo(out.mono8, CV_8U, 1.0 / 257.0);
    out.quantisation = 1.0 / 257.0;
  } else {
    out.mono8 = gray;  // measured directly: no float copy
    out.quantisation = 1.0;
  }
  return out;
}

void CheckImageInput(const std::string& topic, int width, int height, const std::string& encoding,
                     int info_width, int info_height) {
  if (width <= 0 || height <= 0) {
    throw InvalidArgument(Message("image on '", topic, "' is empty (", width, "x", height,
                                  ", encoding '", encoding, "')"));
  }
  const auto& enc = SupportedEncodings();
  if (std::find(enc.begin(), enc.end(), encoding) == enc.end()) {
    std::string list;
    for (const auto& e : enc) list += (list.empty() ? "" : ", ") + e;
    throw InvalidArgument(Message("image on '", topic, "' has encoding '", encoding,
                                  "', which is not supported (supported: ", list, ")"));
  }
  if (width != info_width || height != info_height) {
    throw InvalidArgument(Message("image on '", topic, "' is ", width, "x", height,
                                  " px but its camera_info is ", info_width, "x", info_height,
                                  " px"));
  }
}

// ---------------------------------------------------------------------------
// libapriltag state and the per-frame work buffers (kept between frames so a
// frame allocates no large buffers once the image size is steady).
struct TargetCentroider::Detector {
  apriltag_detector_t* td = nullptr;
  std::vector<std::pair<apriltag_family_t*, void (*)(apriltag_family_t*)>> families;
  std::mutex mutex;  // libapriltag's detector is not re-entrant; guards the buffers too
  cv::Mat small, thr, bright, labels, stats, centroids;  // circle candidates (one pyramid level)
  Pixels px;                                             // fit pixels
};

TargetCentroider::TargetCentroider(const Options& options, const io::TargetList& targets)
    : options_(options), targets_(targets) {
  options_.Check();
  detector_ = new Detector;
  detector_->td = apriltag_detector_create();
  detector_->td->quad_decimate = static_cast<float>(options_.quad_decimate);
  detector_->td->quad_sigma = static_cast<float>(options_.quad_sigma);
  detector_->td->refine_edges = options_.refine_edges;
  detector_->td->decode_sharpening = options_.decode_sharpening;
  detector_->td->nthreads = options_.threads;
  for (const auto& name : options_.families) {
    const FamilyFactory& f = Factories().at(name);
    apriltag_family_t* fam = f.create();
    detector_->families.emplace_back(fam, f.destroy);
    apriltag_detector_add_family_bits(detector_->td, fam, options_.max_hamming);
  }
}

TargetCentroider::~TargetCentroider() {
  if (!detector_) return;
  apriltag_detector_destroy(detector_->td);
  for (auto& f : detector_->families) f.second(f.first);
  delete detector_;
}

Result TargetCentroider::Detect(const cv::Mat& image, const std::string& encoding,
                                const ViewGeometry* view) const {
  return DetectMono(ToMono(image, encoding), view);
}

bool TargetCentroider::GrayWeightedCentroid(const cv::Mat& intensity, const Eigen::Vector2d& seed,
                                            double radius, Eigen::Vector2d* centroid) {
  if (intensity.channels() != 1 || (intensity.depth() != CV_8U && intensity.depth() != CV_32F))
    return false;
  const ImageView im(intensity);
  const int x0 = static_cast<int>(std::floor(seed.x() - radius)),
            x1 = static_cast<int>(std::ceil(seed.x() + radius));
  const int y0 = static_cast<int>(std::floor(seed.y() - radius)),
            y1 = static_cast<int>(std::ceil(seed.y() + radius));
  if (x0 < 0 || y0 < 0 || x1 >= intensity.cols || y1 >= intensity.rows) return false;
  std::vector<float> sorted;
  sorted.reserve((x1 - x0 + 1) * (y1 - y0 + 1));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) sorted.push_back(im.At(x, y));
  std::sort(sorted.begin(), sorted.end());
  const double dark = sorted[sorted.size() / 10], bright = sorted[sorted.size() * 9 / 10];
  if (bright - dark <= 1e-6) return false;
  const double threshold = 0.5 * (dark + bright);
  double sq = 0, sx = 0, sy = 0;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double v = im.At(x, y);
      const double q = v >= threshold ? v : 0.0;
      sq += q;
      sx += q * x;
      sy += q * y;
    }
  }
  if (sq <= 0) return false;
  *centroid = Eigen::Vector2d(sx / sq, sy / sq);
  return true;
}

namespace {

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
  for (int k = 0; k < 4; ++k) {
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
// ---------------------------------------------------------------------------
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
bool BlobFromMoments(double n, double sx, double sy, double sxx, double sxy, double syy,
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

// The target design seen in the image: along 32 rays from the disc's centre
// (in disc radii s, s = 1 on the disc's edge), the dark ring must end where
// the design says (s = circle_ring_ratio) and the surround beyond must be
// brighter than the ring (by min_contrast / 2). Per ray the edge is the first crossing of the
// midpoint between the ring level and that ray's level just outside the
// tolerance band. A ray with no visible step (surround as dark as the ring,
// outside the image) does not count; at least 16 of 32 rays must count and
// their median and 60 % of them must be within the tolerance.
bool MeasureRingRatio(const ImageView& im, const Blob& blob, double ring, const Options& o,
                      double* ratio, std::string* fault) {
  const double design = o.circle_ring_ratio, tol = o.circle_ring_ratio_tolerance;
  const double s_out = design * (1.0 + tol) + 0.25;
  const double ds = 0.5 / std::max(blob.a, 1.0);
  const double min_step = 0.5 * o.min_contrast;
  std::vector<double> ratios;
  auto inside = [&](const Eigen::Vector2d& p) {
    return p.x() >= 0 && p.y() >= 0 && p.x() <= im.cols - 1 && p.y() <= im.rows - 1;
  };
  for (int k = 0; k < 32; ++k) {
    const double ang = 2 * M_PI * (k + 0.5) / 32;
    double outside = 0;
    bool in_image = true;
    for (double e : {0.0, 0.1, 0.2}) {
      const Eigen::Vector2d p = blob.At(ang, s_out + e);
      in_image = in_image && inside(p);
      if (in_image) outside += im.Sample(p.x(), p.y()) / 3.0;
    }
    if (!in_image || outside - ring < min_step) continue;
    const double thr = ring + 0.5 * (outside - ring);
    double prev_s = 1.15, prev_v = 1e9;
    for (double s = 1.15; s <= s_out; s += ds) {
      const Eigen::Vector2d p = blob.At(ang, s);
      const double v = im.Sample(p.x(), p.y());
      if (v >= thr && prev_v < thr) {
        ratios.push_back(prev_s + (s - prev_s) * (thr - prev_v) / (v - prev_v));
        break;
      }
      prev_s = s;
      prev_v = v;
    }
  }
  if (ratios.size() < 16) {
    *fault = Message("outer edge of the dark ring seen on ", ratios.size(),
                     " of 32 rays (design: ring to ", design, " disc diameters)");
    return false;
  }
  int within = 0;
  for (double r : ratios) within += std::abs(r / design - 1.0) <= tol;
  *ratio = Percentile(ratios, 0.5);
  if (std::abs(*ratio / design - 1.0) > tol || within < 0.6 * ratios.size()) {
    *fault = Message("ring outer / disc diameter ", *ratio, " (", within, " of ", ratios.size(),
                     " rays within tolerance), design ", design, " +- ", 100 * tol, " %");
    return false;
  }
  return true;
}

// What the 32 rays from a light centre show beyond it (CircleDesign): the
// design, the outer edge of the dark part and the first dark->light edge
// (both in radii of the light centre, medians over the rays).
struct DesignSeen {
  CircleDesign design = CircleDesign::kAuto;
  double outer = 0.0;  // dot: 0
  double first = 0.0;  // ring designs: the first light after the centre's dark ring
};

// Limits of the ring designs (in radii of the light centre): the outer edge
// between kMinOuterRatio and kMaxOuterRatio; light for kLightRun at least
// beyond it (a light gap between two rings or a code band is shorter; the
// gap to a neighbouring marker on a board longer); a dot's dark ground out to
// kDotGround at least. Consistency: kRingRayShare of the counted rays (at
// least kMinRingRays) within kRingTolerance of the median; a concentric or
// coded marker shows light inside the outer edge on kConcentricShare of them.
constexpr double kMinOuterRatio = 1.2, kMaxOuterRatio = 4.0, kLightRun = 0.6, kDotGround = 2.5;
constexpr double kRingTolerance = 0.12, kRingRayShare = 0.75, kConcentricShare = 0.25;
constexpr double kDotRayShare = 0.9, kDotGroundSpread = 0.25;
constexpr int kMinRingRays = 20, kMinDotRays = 24;

// The ring designs and the dot: per ray the profile is classified against the
// midpoint of the light centre's and the dark ring's levels. A ray counts for
// the ring rule when it finds the outer edge or stays in the image to
// kMaxOuterRatio + kLightRun, for the dot rule when it stays in the image to
// kDotGround.
bool SeeRingOrDot(const ImageView& im, const Blob& blob, double disc, double ring,
                  double min_diameter, CircleDesign wanted, DesignSeen* seen, std::string* fault) {
  const double thr = ring + 0.5 * (disc - ring);
  const double ds = 0.5 / std::max(blob.a, 1.0);
  const double s_end = kMaxOuterRatio + kLightRun;
  auto in_image = [&](const Eigen::Vector2d& p) {
    return p.x() >= 0 && p.y() >= 0 && p.x() <= im.cols - 1 && p.y() <= im.rows - 1;
  };
  int ring_rays = 0, dot_rays = 0, dark_rays = 0;
  std::vector<double> outers, firsts, ground;
  for (int k = 0; k < 32; ++k) {
    const double ang = 2 * M_PI * (k + 0.5) / 32;
    double prev_s = 1.15, up = -1.0, first = -1.0;
    Eigen::Vector2d p = blob.At(ang, prev_s);
    if (!in_image(p)) continue;
    double prev_v = im.Sample(p.x(), p.y());
    bool found = false, whole = true;
    for (double s = prev_s + ds; s <= s_end; s += ds) {
      p = blob.At(ang, s);
      if (!in_image(p)) {
        whole = false;
        break;
      }
      const double v = im.Sample(p.x(), p.y());
      if (s >= 1.3 && s <= kDotGround) ground.push_back(v);
      if (v >= thr && prev_v < thr) {
        up = prev_s + (s - prev_s) * (thr - prev_v) / (v - prev_v);
        if (first < 0) first = up;
      } else if (v < thr && prev_v >= thr) {
        up = -1.0;  // dark again: a gap between rings, not the outer edge
      }
      if (up > 0 && s - up >= kLightRun) {
        found = true;
        break;
      }
      if (s >= kDotGround && s - ds < kDotGround) {
        ++dot_rays;
        if (first < 0) ++dark_rays;
      }
      prev_s = s;
      prev_v = v;
    }
    if (found) {
      ++ring_rays;
      outers.push_back(up);
      firsts.push_back(first);
    } else if (whole) {
      ++ring_rays;
    }
  }
  const bool want_ring = wanted == CircleDesign::kAuto || wanted == CircleDesign::kRing ||
                         wanted == CircleDesign::kConcentric;
  std::string ring_fault;
  if (want_ring && ring_rays >= kMinRingRays && !outers.empty()) {
    std::vector<double> tmp = outers;
    const double med = Percentile(tmp, 0.5);
    int within = 0, inner = 0;
    std::vector<double> first_within;
    for (size_t i = 0; i < outers.size(); ++i) {
      if (std::abs(outers[i] / med - 1.0) > kRingTolerance) continue;
      ++within;
      if (firsts[i] < 0.85 * outers[i]) {
        ++inner;
        first_within.push_back(firsts[i]);
      }
    }
    const bool concentric = inner >= kConcentricShare * within;
    if (med >= kMinOuterRatio && med <= kMaxOuterRatio && within >= kRingRayShare * ring_rays &&
        (wanted == CircleDesign::kAuto || concentric == (wanted == CircleDesign::kConcentric))) {
      seen->design = concentric ? CircleDesign::kConcentric : CircleDesign::kRing;
      seen->outer = med;
      seen->first = concentric ? Percentile(first_within, 0.5) : med;
      return true;
    }
    ring_fault = Message("outer edge of the dark part at ", med, " radii on ", within, " of ",
                         ring_rays, " rays", concentric ? " (concentric)" : "");
  } else {
    ring_fault = Message("outer edge of the dark part seen on ", outers.size(), " of ", ring_rays,
                         " rays");
  }
  // A dot: dark ground on (nearly) every ray, and a ground, not texture: its
  // brightest tenth still in the dark quarter of the contrast; the dot at
  // least circle_min_diameter across (a speck of texture is smaller).
  const double ground_top = Percentile(ground, 0.9);
  const bool uniform = ground_top <= ring + kDotGroundSpread * (disc - ring);
  const bool large = blob.a + blob.b >= min_diameter;
  if ((wanted == CircleDesign::kAuto || wanted == CircleDesign::kDot) && dot_rays >= kMinDotRays &&
      dark_rays >= kDotRayShare * dot_rays && uniform && large) {
    seen->design = CircleDesign::kDot;
    return true;
  }
  *fault = Message(ring_fault, "; dark ground to ", kDotGround, " radii on ", dark_rays, " of ",
                   dot_rays, " rays", uniform ? "" : " (not uniform)",
                   large ? "" : " (smaller than circle_min_diameter)");
  return false;
}

// The design of the configured ones that the rays show (see CircleDesign).
// kAuto tries kDiscInRing first: the simulator's plates keep exactly their
// former evidence and measurement.
bool SeeDesign(const ImageView& im, const Blob& blob, double disc, double ring, const Options& o,
               DesignSeen* seen, std::string* fault) {
  std::string disc_fault;
  if (o.circle_design == CircleDesign::kAuto || o.circle_design == CircleDesign::kDiscInRing) {
    double ratio = 0.0;
    if (MeasureRingRatio(im, blob, ring, o, &ratio, &disc_fault)) {
      // auto: a concentric or coded marker whose outer edge happens to be at
      // the ratio is measured as what it is (its dark part has light inside).
      DesignSeen other;
      std::string unused;
      if (o.circle_design == CircleDesign::kAuto &&
          SeeRingOrDot(im, blob, disc, ring, o.circle_min_diameter, CircleDesign::kConcentric,
                       &other, &unused)) {
        *seen = other;
        return true;
      }
      seen->design = CircleDesign::kDiscInRing;
      seen->outer = seen->first = ratio;
      return true;
    }
    if (o.circle_design == CircleDesign::kDiscInRing) {
      *fault = disc_fault;
      return false;
    }
  }
  if (SeeRingOrDot(im, blob, disc, ring, o.circle_min_diameter, o.circle_design, seen, fault))
    return true;
  if (!disc_fault.empty()) *fault = disc_fault + "; " + *fault;
  return false;
}

// Semi-major axis [px] of the image of a circle (diameter [m], centre and
// normal in site): half the longest chord between 36 projected rim points;
// 0 when a rim point does not project.
double ProjectedSemiMajor(const ViewGeometry& view, const Eigen::Vector3d& centre,
                          const Eigen::Vector3d& normal, double diameter) {
  const Eigen::Vector3d n = normal.normalized(), u = n.unitOrthogonal(), v = n.cross(u);
  std::array<Eigen::Vector2d, 36> p;
  for (int i = 0; i < 36; ++i) {
    const double a = 2 * M_PI * i / 36;
    if (!view.camera.Project(view.pose,
                             centre + 0.5 * diameter * (std::cos(a) * u + std::sin(a) * v), &p[i]))
      return 0.0;
  }
  double longest = 0.0;
  for (int i = 0; i < 36; ++i)
    for (int j = i + 1; j < 36; ++j) longest = std::max(longest, (p[i] - p[j]).norm());
  return 0.5 * longest;
}

// Ellipse intensity model: parameters cx, cy, A11, A12, A22 (shape matrix,
// (p-c)^T A (p-c) = 1 on the edge), ring level, disc level, blur sigma.
using EllipseParams = Eigen::Matrix<double, 8, 1>;

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

}  // namespace

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
  FitConicCentre(pts, &ellipse_centre);
  return ellipse_centre - projected_centre;
}

namespace {

// One target per marker: a circle whose centre lies within another circle's
// outer edge (a light gap or code segment of a ring marker, a dot inside a
// ring) is dropped in favour of the larger one (debug output: discarded,
// reason "design").
double OuterRadius(const Observation& o) {
  return 0.5 * o.size_px * std::max(o.ring_ratio, 1.0);
}

void DropNestedCircles(Result* res) {
  std::vector<bool> drop(res->observations.size(), false);
  for (size_t i = 0; i < res->observations.size(); ++i) {
    const Observation& a = res->observations[i];
    if (a.family != "circle") continue;
    for (size_t j = 0; j < res->observations.size(); ++j) {
      const Observation& b = res->observations[j];
      if (i == j || b.family != "circle" || drop[i]) continue;
      const double ra = OuterRadius(a), rb = OuterRadius(b);
      if ((a.centre - b.centre).norm() < rb && (ra < rb || (ra == rb && i > j))) drop[i] = true;
    }
  }
  // Unlisted markers that could not be measured: the same rule among them
  // and against the measured ones.
  std::vector<bool> drop_r(res->rejections.size(), false);
  for (size_t i = 0; i < res->rejections.size(); ++i) {
    const Rejection& a = res->rejections[i];
    if (a.family != "circle" || a.id >= 0) continue;
    for (size_t j = 0; j < res->observations.size() && !drop_r[i]; ++j) {
      const Observation& b = res->observations[j];
      if (!drop[j] && b.family == "circle" && (a.where - b.centre).norm() < OuterRadius(b))
        drop_r[i] = true;
    }
    for (size_t j = 0; j < res->rejections.size() && !drop_r[i]; ++j) {
      const Rejection& b = res->rejections[j];
      if (i == j || b.family != "circle") continue;
      if ((a.where - b.where).norm() < b.radius_px &&
          (a.radius_px < b.radius_px || (a.radius_px == b.radius_px && i > j)))
        drop_r[i] = true;
    }
  }
  std::vector<Rejection> kept_r;
  for (size_t i = 0; i < res->rejections.size(); ++i) {
    if (!drop_r[i]) {
      kept_r.push_back(res->rejections[i]);
      continue;
    }
    res->summary.rejects_by_reason[RejectReasonName(res->rejections[i].reason)]--;
    Rejection r = res->rejections[i];
    r.detail += " (inside the outer edge of a larger circle: one target per marker)";
    res->discarded.push_back(r);
  }
  res->rejections.swap(kept_r);
  std::vector<Observation> kept;
  for (size_t i = 0; i < res->observations.size(); ++i) {
    const Observation& o = res->observations[i];
    if (!drop[i]) {
      kept.push_back(o);
      continue;
    }
    Rejection r;
    r.family = "circle";
    r.id = o.id;
    r.where = o.centre;
    r.reason = RejectReason::kDesign;
    r.detail = "inside the outer edge of a larger circle (one target per marker)";
    res->discarded.push_back(r);
    res->summary.num_circles--;
    if (!o.role) res->summary.num_unknown--;
  }
  res->observations.swap(kept);
}

}  // namespace

Result TargetCentroider::DetectMono(const MonoImage& mono, const ViewGeometry* view) const {
  if (mono.mono8.empty() && mono.intensity.empty()) throw InvalidArgument("image is empty");
  if (!mono.intensity.empty() && mono.intensity.type() != CV_32FC1) {
    throw InvalidArgument(
        Message("MonoImage.intensity must be CV_32FC1, got type ", mono.intensity.type()));
  }
  if (!mono.mono8.empty() && mono.mono8.type() != CV_8UC1) {
    throw InvalidArgument(Message("MonoImage.mono8 must be CV_8UC1, got type ", mono.mono8.type()));
  }
  // What is measured: the float intensity of deep inputs, else mono8 itself.
  cv::Mat mono8 = mono.mono8;
  if (mono8.empty()) mono.intensity.convertTo(mono8, CV_8U);
  const cv::Mat& meas = mono.intensity.empty() ? mono8 : mono.intensity;
  if (meas.cols < 2 || meas.rows < 2) {
    throw InvalidArgument(Message("image is empty (", meas.cols, "x", meas.rows, ")"));
  }
  if (!mono.intensity.empty() && mono.intensity.size() != mono8.size()) {
    throw InvalidArgument(Message("MonoImage.mono8 is ", mono8.cols, "x", mono8.rows,
                                  " but intensity is ", mono.intensity.cols, "x",
                                  mono.intensity.rows));
  }
  const ImageView im(meas);
  Result res;
  res.width = im.cols;
  res.height = im.rows;
  if (view) {
    const auto& s = view->camera.sensor();
    if (s.width != im.cols || s.height != im.rows) {
      throw InvalidArgument(Message("image is ", im.cols, "x", im.rows,
                                    " px but the camera model (camera_info) is ", s.width, "x",
                                    s.height, " px"));
    }
  }
  Detector& D = *detector_;
  std::lock_guard<std::mutex> lock(D.mutex);
  const double noise_floor =
      options_.noise_floor > 0 ? options_.noise_floor : mono.quantisation / std::sqrt(12.0);
  const double margin = options_.border_margin;
  auto near_border = [&](const Eigen::Vector2d& p, double extra) {
    return p.x() < margin + extra || p.y() < margin + extra ||
           p.x() > im.cols - 1 - margin - extra || p.y() > im.rows - 1 - margin - extra;
  };
  auto reject = [&](const std::string& family, int id, const Eigen::Vector2d& where,
                    RejectReason reason, const std::string& detail) {
    Rejection r;
    r.family = family;
    r.id = id;
    r.where = where;
    r.reason = reason;
    r.detail = detail;
    res.rejections.push_back(r);
    res.summary.rejects_by_reason[RejectReasonName(reason)]++;
  };
  // A circle candidate that is not a target of the design (debug output).
  auto discard = [&](const Eigen::Vector2d& where, RejectReason reason, const std::string& detail) {
    Rejection r;
    r.family = "circle";
    r.where = where;
    r.reason = reason;
    r.detail = detail;
    res.discarded.push_back(r);
  };
  std::vector<double> residuals;
  std::vector<std::array<Eigen::Vector2d, 4>> tag_quads;

  // ---------------- AprilTags ----------------
  if (!options_.families.empty()) {
    image_u8_t header{mono8.cols, mono8.rows, static_cast<int32_t>(mono8.step[0]),
                      const_cast<uint8_t*>(mono8.ptr<uint8_t>(0))};
    zarray_t* dets = apriltag_detector_detect(D.td, &header);
    for (int i = 0; i < zarray_size(dets); ++i) {
      apriltag_detection_t* det;
      zarray_get(dets, i, &det);
      const std::string family = det->family->name;
      Observation o;
      o.id = det->id;
      o.family = family;
      o.decision_margin = det->decision_margin;
      o.hamming = det->hamming;
      o.has_corners = true;
      for (int k = 0; k < 4; ++k) {
        o.corners[k] = Eigen::Vector2d(det->p[k][0] - kAprilTagPixelOffset,
                                       det->p[k][1] - kAprilTagPixelOffset);
      }
      o.detector_centre =
          Eigen::Vector2d(det->c[0] - kAprilTagPixelOffset, det->c[1] - kAprilTagPixelOffset);
      o.centre = o.detector_centre;
      tag_quads.push_back(o.corners);
      if (const io::TargetSpec* spec = targets_.Find(family, det->id)) o.role = spec->role;
      double edge_sum = 0;
      for (int k = 0; k < 4; ++k) edge_sum += (o.corners[(k + 1) % 4] - o.corners[k]).norm();
      o.size_px = edge_sum / 4;
      if (det->decision_margin < options_.min_decision_margin) {
        reject(
            family, det->id, o.centre, RejectReason::kWeakDecode,
            Message("decision margin ", det->decision_margin, " < ", options_.min_decision_margin));
        continue;
      }
      bool at_border = false;
      for (const auto& c : o.corners) at_border = at_border || near_border(c, 1.0);
      if (at_border) {
        reject(family, det->id, o.centre, RejectReason::kBorder,
               "a corner within the border margin");
        continue;
      }
      // The detector's corners as published when the edge model cannot do
      // better (see below): the covariance then follows the decode contrast
      // (decision margin, about the black/white difference in DN) and the tag
      // size: an edge of L px at noise s and contrast C places a line to
      // ~ s / C / sqrt(L).
      auto publish_detector = [&](Observation o, const Eigen::Matrix2d& extra_cov) {
        const double contrast_proxy = std::max(static_cast<double>(det->decision_margin), 1.0);
        const double sigma =
            std::max(noise_floor, 2.0) / contrast_proxy * std::sqrt(8.0 / std::max(o.size_px, 1.0));
        o.method = CentreMethod::kDetector;
        o.centre = o.detector_centre;
        o.covariance = Eigen::Matrix2d::Identity() * sigma * sigma + extra_cov;
        if (o.quality <= 0.0) o.quality = 0.5 * std::clamp(det->decision_margin / 100.0, 0.0, 1.0);
        res.observations.push_back(o);
        res.summary.num_tags++;
        if (!o.role) res.summary.num_unknown++;
      };
      // Edge-model fits on the pixels of a narrow band along each edge only.
      const double cell = o.size_px / det->family->width_at_border;
      std::array<EdgeFit, 4> edges;
      bool fits_ok = true;
      double worst_rel = 0, blur = 0, contrast = 1e9;
      for (int k = 0; k < 4; ++k) {
        edges[k] = FitEdge(im, o.corners[k], o.corners[(k + 1) % 4], o.centre, cell,
                           det->family->width_at_border, noise_floor, &D.px);
        if (!edges[k].ok) {
          fits_ok = false;
          break;
        }
        const double c = edges[k].w - edges[k].b;
        contrast = std::min(contrast, c);
        worst_rel = std::max(worst_rel, edges[k].rms / std::max(c, 1e-9));
        blur = std::max(blur, edges[k].sigma);
      }
      if (!fits_ok) {
        // The tag was decoded: its quad stands; no edge model to check it by.
        publish_detector(o, Eigen::Matrix2d::Zero());
        continue;
      }
      o.contrast = contrast;
      o.edge_blur = blur;
      o.fit_residual = worst_rel;
      // Saturation of the white surround along the edges.
      int sat = 0, tot = 0;
      for (int k = 0; k < 4; ++k) {
        const Eigen::Vector2d a = o.corners[k], b = o.corners[(k + 1) % 4];
        const Eigen::Vector2d nrm = edges[k].Normal();
        for (int j = 1; j < 16; ++j) {
          const Eigen::Vector2d p = a + (b - a) * (j / 16.0) + nrm * (0.5 * cell);
          ++tot;
          if (im.Sample(p.x(), p.y()) >= options_.saturation_level) ++sat;
        }
      }
      if (contrast < options_.min_contrast) {
        reject(family, det->id, o.centre, RejectReason::kLowContrast,
               Message("edge contrast ", contrast, " DN"));
        continue;
      }
      if (sat > options_.max_saturated_fraction * tot) {
        reject(family, det->id, o.centre, RejectReason::kSaturated,
               Message(100 * sat / tot, "% of the white border saturated"));
        continue;
      }
      // An edge the model does not explain (blurred beyond max_edge_blur, a
      // residual over max_residual: a neighbouring tag or texture in the band,
      // JPEG blocks): the decoded quad stands, with the detector's corners.
      if (blur > options_.max_edge_blur || worst_rel > options_.max_residual) {
        o.quality = 0.0;
        publish_detector(o, Eigen::Matrix2d::Zero());
        continue;
      }
      std::array<Line, 4> lines;
      for (int k = 0; k < 4; ++k) lines[k] = ToLine(edges[k]);
      {
        // Something in front of part of the plate bends the edge fits without
        // raising their residual much (the occluder sits in the white
        // surround, next to the band): look at the whole surround.
        std::array<Line, 4> l0 = lines;
        std::array<Eigen::Vector2d, 4> outer;
        double black = 0.0, white = 0.0;
        for (int k = 0; k < 4; ++k) {
          black += 0.25 * edges[k].b;
          white += 0.25 * edges[k].w;
        }
        if (CornersFromEdges(l0, &outer)) {
          const double dark = DarkSurroundFraction(im, outer, det->family->width_at_border, cell,
                                                   1.5 * blur + 0.5, black, white);
          if (dark > options_.max_dark_surround) {
            reject(family, det->id, o.centre, RejectReason::kPartial,
                   Message(std::lround(100.0 * dark), "% of the white surround dark (occluded)"));
            continue;
          }
        }
      }
      o.quality = std::clamp(det->decision_margin / 100.0, 0.0, 1.0) *
                  std::clamp(1.0 - worst_rel / options_.max_residual, 0.0, 1.0);
      std::array<Eigen::Vector2d, 4> corners;
      Eigen::Vector2d centre;
      if (!CornersFromEdges(lines, &corners) || !CentreFromCorners(corners, &centre) ||
          (centre - o.detector_centre).norm() > 0.25 * o.size_px) {
        publish_detector(o, Eigen::Matrix2d::Zero());  // the edge lines do not make this quad
        continue;
      }
      const Eigen::Matrix2d cov = CentreCovariance(edges, lines);
      for (const auto& e : edges) residuals.push_back(e.rms);
      // Per tag: the refined corners replace the detector's only where the
      // edge model explains the pixels (residual) and places the centre
      // precisely (covariance). Otherwise the detector's corners stand, with
      // the disagreement of the two added to their covariance.
      const double sigma_max = std::sqrt(
          std::max(Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(cov).eigenvalues()(1), 0.0));
      if (!options_.refine_tags || worst_rel > options_.tag_refine_max_residual ||
          !(sigma_max <= options_.tag_refine_max_sigma)) {
        const Eigen::Vector2d d = centre - o.detector_centre;
        publish_detector(
            o, options_.refine_tags ? Eigen::Matrix2d(d * d.transpose()) : Eigen::Matrix2d(cov));
        continue;
      }
      o.method = CentreMethod::kEdgeModel;
      o.corners = corners;
      o.centre = centre;
      o.covariance = cov;
      res.observations.push_back(o);
      res.summary.num_tags++;
      if (!o.role) res.summary.num_unknown++;
    }
    apriltag_detections_destroy(dets);
  }

  // ---------------- circles ----------------
  if (options_.detect_circles) {
    const double dmin = options_.circle_min_diameter, dmax = options_.circle_max_diameter;
    // Candidates on one pyramid level: the image reduced by f (area mean) so
    // that the smallest disc is still >= 4 px across there; one local-contrast
    // threshold per scale (box mean, saturating difference, threshold) and one
    // connected-components pass. Everything after works on small ROIs of the
    // full-resolution image. Buffers are members (no per-frame allocation).
    const int f = std::clamp(static_cast<int>(std::floor(dmin / 4.0)), 1, 4);
    cv::Mat small;
    if (f > 1) {
      const cv::Mat whole = mono8(cv::Rect(0, 0, (mono8.cols / f) * f, (mono8.rows / f) * f));
      cv::resize(whole, D.small, cv::Size(mono8.cols / f, mono8.rows / f), 0, 0, cv::INTER_AREA);
      small = D.small;
    } else {
      small = mono8;
    }
    auto to_full = [f](double xs) { return f * xs + 0.5 * (f - 1); };
    D.bright.create(small.size(), CV_8U);
    D.bright.setTo(0);
    // Window sizes from 3 dmin to 1.5 dmax, at most a factor 4 apart.
    const double kmin = 3 * dmin, kmax = std::max(kmin, 1.5 * dmax);
    const int nscales =
        1 + static_cast<int>(std::ceil(std::log(kmax / kmin) / std::log(4.0) - 1e-9));
    const int kcap = std::max(3, 2 * ((std::min(small.cols, small.rows) - 1) / 2) + 1);
    for (int i = 0; i < nscales; ++i) {
      const double k = nscales == 1
                           ? kmin
                           : kmin * std::pow(kmax / kmin, static_cast<double>(i) / (nscales - 1));
      const int ks = std::clamp(2 * static_cast<int>(k / f / 2) + 1, 3, kcap);
      cv::blur(small, D.thr, cv::Size(ks, ks), cv::Point(-1, -1), cv::BORDER_REPLICATE);
      cv::subtract(small, D.thr, D.thr);  // saturating: max(0, image - local mean)
      cv::threshold(D.thr, D.thr, 0.4 * options_.min_contrast, 255, cv::THRESH_BINARY);
      cv::bitwise_or(D.bright, D.thr, D.bright);
    }
    // Tags are not circles: mask them out.
    for (const auto& q : tag_quads) {
      std::vector<cv::Point> poly;
      Eigen::Vector2d c = 0.25 * (q[0] + q[1] + q[2] + q[3]);
      for (const auto& p : q) {
        const Eigen::Vector2d g =
            (c + 1.3 * (p - c) - Eigen::Vector2d::Constant(0.5 * (f - 1))) / f;
        poly.emplace_back(static_cast<int>(std::lround(g.x())),
                          static_cast<int>(std::lround(g.y())));
      }
      cv::fillConvexPoly(D.bright, poly, cv::Scalar(0));
    }
    const int nl =
        cv::connectedComponentsWithStats(D.bright, D.labels, D.stats, D.centroids, 8, CV_32S);
    const double amin = M_PI / 4 * dmin * dmin * 0.4 / (f * f),
                 amax = M_PI / 4 * dmax * dmax * 1.5 / (f * f);
    // Listed circles projected into the image (when the view is known).
    struct Expected {
      const io::TargetSpec* spec;
      Eigen::Vector2d px;
      double radius_px;
      double major_px;  // semi-major axis of the projected disc (0: unknown)
    };
    std::vector<Expected> expected;
    if (view) {
      for (const auto& s : targets_.targets()) {
        if (s.family != "circle" || !s.position) continue;
        Eigen::Vector2d px;
        if (!view->camera.Project(view->pose, *s.position, &px)) continue;
        Eigen::Vector3d n = s.normal ? *s.normal : Eigen::Vector3d(0, 0, 1);
        Eigen::Vector2d edge;
        view->camera.Project(view->pose, *s.position + 0.5 * s.size * n.unitOrthogonal(), &edge);
        expected.push_back({&s, px, (edge - px).norm(),
                            s.normal ? ProjectedSemiMajor(*view, *s.position, n, s.size) : 0.0});
      }
    }
    std::vector<double> inner, sectors, vals;
    Pixels& px = D.px;
    for (int l = 1; l < nl; ++l) {
      const int area = D.stats.at<int>(l, cv::CC_STAT_AREA);
      if (area < amin || area > amax) continue;
      const int bx = D.stats.at<int>(l, cv::CC_STAT_LEFT), by = D.stats.at<int>(l, cv::CC_STAT_TOP);
      const int bw = D.stats.at<int>(l, cv::CC_STAT_WIDTH),
                bh = D.stats.at<int>(l, cv::CC_STAT_HEIGHT);
      if (f * std::max(bw, bh) > 1.3 * dmax + 2 * f) continue;
      // Coarse ellipse from the component's moments on the reduced level.
      double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, cnt = 0;
      for (int y = by; y < by + bh; ++y) {
        const int* lr = D.labels.ptr<int>(y);
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
      if (!BlobFromMoments(cnt, sx, sy, sxx, sxy, syy, &coarse)) continue;
      // Not disc-like (a ring of bright background around a dark target, a
      // streak): the component fills its moment ellipse badly.
      const double coarse_fill = cnt / (M_PI * coarse.a * coarse.b);
      coarse.centre = Eigen::Vector2d(to_full(coarse.centre.x()), to_full(coarse.centre.y()));
      if (coarse_fill < 0.6 || coarse_fill > 1.6) {
        discard(coarse.centre, RejectReason::kNotDisc,
                Message("bright blob fills ", coarse_fill, " of its moment ellipse"));
        continue;
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
      for (int y = ry0; y <= ry1; ++y) {
        for (int x = rx0; x <= rx1; ++x) {
          const Eigen::Vector2d d(x - coarse.centre.x(), y - coarse.centre.y());
          if (d.dot(cshape * d) > 1.69 || im.At(x, y) < thr0) continue;
          sx += x;
          sy += y;
          sxx += double(x) * x;
          sxy += double(x) * y;
          syy += double(y) * y;
          ++cnt;
        }
      }
      Blob blob;
      if (!BlobFromMoments(cnt, sx, sy, sxx, sxy, syy, &blob)) {
        discard(coarse.centre, RejectReason::kNotDisc,
                "no bright pixels above the disc/surround midpoint");
        continue;
      }
      const double fill = cnt / (M_PI * blob.a * blob.b);
      if (fill < 0.8 || fill > 1.2) {
        discard(blob.centre, RejectReason::kNotDisc,
                Message("thresholded blob fills ", fill, " of its moment ellipse"));
        continue;
      }
      if (2 * blob.a < 0.8 * dmin || 2 * blob.a > dmax) {
        discard(blob.centre, RejectReason::kSize,
                Message("diameter ", 2 * blob.a, " px outside [", dmin, ", ", dmax, "]"));
        continue;
      }
      if (1.0 - blob.b / blob.a > options_.circle_max_eccentricity) {
        discard(blob.centre, RejectReason::kNotDisc,
                Message("eccentricity ", 1.0 - blob.b / blob.a));
        continue;
      }
      // Identification against the listed circles.
      int id = -1;
      const io::TargetSpec* spec = nullptr;
      int best = -1;
      double best_d = 1e18;
      for (size_t k = 0; k < expected.size(); ++k) {
        const double d = (expected[k].px - blob.centre).norm();
        if (d < best_d) {
          best_d = d;
          best = static_cast<int>(k);
        }
      }
      if (best >= 0 &&
          best_d < options_.circle_id_gate * std::max(expected[best].radius_px, 2.0) + 1.0) {
        spec = expected[best].spec;
        id = spec->id;
      }
      // A listed circle expected here is a target that cannot be measured (a
      // rejection); an unlisted candidate that fails is not a target
      // (discarded, debug output only).
      // A candidate that shows a design's evidence is a marker: when it
      // cannot be measured it is a rejection too.
      double marker_radius = 0.0;
      auto fail = [&](RejectReason reason, const std::string& detail) {
        if (spec || marker_radius > 0.0) {
          reject("circle", id, blob.centre, reason, detail);
          res.rejections.back().radius_px = marker_radius;
        } else {
          discard(blob.centre, reason, detail);
        }
      };
      if (near_border(blob.centre, 1.7 * blob.a)) {
        fail(RejectReason::kBorder, "disc and its ring reach the image border");
        continue;
      }
      // Surround: 16 sectors of the annulus 1.3..1.6 radii must be dark.
      inner.clear();
      sectors.clear();
      for (int k = 0; k < 32; ++k) {
        const double ang = 2 * M_PI * k / 32;
        for (double s : {0.2, 0.45, 0.65}) {
          const Eigen::Vector2d p = blob.At(ang, s);
          inner.push_back(im.Sample(p.x(), p.y()));
        }
      }
      for (int k = 0; k < 16; ++k) {
        double sum = 0;
        int n = 0;
        for (int j = 0; j < 3; ++j) {
          const double ang = 2 * M_PI * (k + j / 3.0) / 16;
          for (double s : {1.3, 1.45, 1.6}) {
            const Eigen::Vector2d p = blob.At(ang, s);
            sum += im.Sample(p.x(), p.y());
            ++n;
          }
        }
        sectors.push_back(sum / n);
      }
      const double disc = Percentile(inner, 0.5);
      double ring = Percentile(sectors, 0.5);
      double contrast = disc - ring;
      // (The darkest quarter of the sectors: a coded ring's light segments
      // may lift the median.)
      std::vector<double> sorted_sectors = sectors;
      if (disc - Percentile(sorted_sectors, 0.25) < options_.min_contrast) {  // bright texture
        discard(blob.centre, RejectReason::kLowContrast,
                Message("disc/ring contrast ", contrast, " DN"));
        continue;
      }
      double worst_sector = *std::max_element(sectors.begin(), sectors.end());
      // The design: where the dark part around the light centre ends.
      DesignSeen seen;
      std::string design_fault;
      if (!SeeDesign(im, blob, disc, ring, options_, &seen, &design_fault)) {
        fail(RejectReason::kDesign, design_fault);
        continue;
      }
      const double ring_ratio = seen.outer;
      // (A dot's evidence is weaker, a dark ground only: an unlisted dot
      // that cannot be measured is not called a marker.)
      if (seen.design != CircleDesign::kDot) marker_radius = blob.a * ring_ratio;
      if (seen.design == CircleDesign::kRing || seen.design == CircleDesign::kConcentric) {
        // The centre's own dark ring may end before 1.3 radii (a thin inner
        // ring, a code band): the surround is judged within it.
        const double w = seen.first - 1.0;
        sectors.clear();
        for (int k = 0; k < 16; ++k) {
          double sum = 0;
          int n = 0;
          for (int j = 0; j < 3; ++j) {
            const double ang = 2 * M_PI * (k + j / 3.0) / 16;
            for (double s : {1.0 + 0.45 * w, 1.0 + 0.55 * w, 1.0 + 0.65 * w}) {
              const Eigen::Vector2d p = blob.At(ang, s);
              sum += im.Sample(p.x(), p.y());
              ++n;
            }
          }
          sectors.push_back(sum / n);
        }
        ring = Percentile(sectors, 0.5);
        contrast = disc - ring;
        worst_sector = *std::max_element(sectors.begin(), sectors.end());
      }
      // With a pose: the listed target's projected size.
      if (spec && expected[best].major_px > 0.0) {
        const double rel = blob.a / expected[best].major_px - 1.0;
        if (std::abs(rel) > options_.circle_size_tolerance) {
          fail(RejectReason::kSize, Message("semi-major axis ", blob.a, " px, circle/", spec->id,
                                            " projects to ", expected[best].major_px, " px"));
          continue;
        }
      }
      if (worst_sector > disc - 0.5 * contrast) {
        fail(RejectReason::kPartial, "dark ring interrupted (occluded or partial target)");
        continue;
      }
      int sat = 0;
      for (double v : inner) sat += v >= options_.saturation_level;
      if (sat > options_.max_saturated_fraction * inner.size()) {
        fail(RejectReason::kSaturated,
             Message(100 * sat / static_cast<int>(inner.size()), "% of the disc saturated"));
        continue;
      }
      Observation o;
      o.family = "circle";
      o.id = id;
      o.ring_ratio = ring_ratio;
      o.design = seen.design;
      if (spec) o.role = spec->role;
      o.contrast = contrast;
      const Eigen::Matrix2d shape = blob.Shape();
      // Plain gray-weighted centroid (DESIGN.md) over the disc and the inner ring.
      {
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
        o.gray_centroid = sq > 0 ? Eigen::Vector2d(cx / sq, cy / sq) : blob.centre;
      }
      o.centre = o.gray_centroid;
      o.size_px = blob.a + blob.b;
      // Intensity-model ellipse fit on the pixels of a band around the edge.
      const double rmean = 0.5 * (blob.a + blob.b);
      const double band = std::clamp(0.25 * rmean, 1.5, 4.0);
      EllipseParams x0;
      x0 << o.gray_centroid.x(), o.gray_centroid.y(), shape(0, 0), shape(0, 1), shape(1, 1), ring,
          disc, 0.4;
      px.clear();
      {
        const double rout = 1.0 + band / blob.b, rin = std::max(0.0, 1.0 - band / blob.b);
        const int xa = static_cast<int>(std::floor(blob.centre.x() - blob.a - band - 1)),
                  xb = static_cast<int>(std::ceil(blob.centre.x() + blob.a + band + 1));
        const int ya = static_cast<int>(std::floor(blob.centre.y() - blob.a - band - 1)),
                  yb = static_cast<int>(std::ceil(blob.centre.y() + blob.a + band + 1));
        for (int y = std::max(0, ya); y <= std::min(im.rows - 1, yb); ++y) {
          for (int x = std::max(0, xa); x <= std::min(im.cols - 1, xb); ++x) {
            const Eigen::Vector2d d(x - o.gray_centroid.x(), y - o.gray_centroid.y());
            const double r2 = d.dot(shape * d);
            if (r2 > rout * rout || r2 < rin * rin) continue;
            px.p.emplace_back(x, y);
            px.v.push_back(im.At(x, y));
          }
        }
      }
      EllipseModel model;
      const LmResult<8> fit = FitModel<8>(px, x0, model, 30);
      if (!fit.ok || (fit.x.head<2>() - o.gray_centroid).norm() > 0.25 * rmean) {
        marker_radius = 0.0;  // unlisted: no model, no marker
        fail(RejectReason::kFitFailed, "ellipse model fit did not converge");
        continue;
      }
      const double fit_contrast = fit.x[6] - fit.x[5];
      const double rel = fit.rms / std::max(fit_contrast, 1e-9);
      o.fit_residual = rel;
      o.edge_blur = std::max(fit.x[7], kMinBlur);
      if (o.edge_blur > options_.max_edge_blur) {
        fail(RejectReason::kBlurred, Message("edge blur sigma ", o.edge_blur, " px"));
        continue;
      }
      if (rel > options_.max_residual) {
        marker_radius = 0.0;  // unlisted: the model does not explain it, no marker
        fail(RejectReason::kPartial, Message("ellipse fit residual ", rel, " of the contrast"));
        continue;
      }
      if (rel > options_.circle_max_residual) {
        fail(RejectReason::kResidual, Message("ellipse fit residual ", rel, " of the contrast > ",
                                              options_.circle_max_residual));
        continue;
      }
      const double noise = NoiseOf(fit.rms, noise_floor);
      const Eigen::Matrix<double, 7, 7> cov = noise * noise * fit.jtj.block<7, 7>(0, 0).inverse();
      residuals.push_back(fit.rms);
      o.method = CentreMethod::kGrayCentroid;
      if (options_.refine_circles) {
        o.centre = fit.x.head<2>();
        o.method = CentreMethod::kEllipseModel;
      }
      o.covariance = cov.block<2, 2>(0, 0);
      if (!o.covariance.allFinite()) {
        fail(RejectReason::kFitFailed, "singular ellipse fit");
        continue;
      }
      if (options_.correct_perspective && view && spec && spec->position && spec->normal) {
        o.perspective_correction =
            CirclePerspectiveBias(*view, *spec->position, *spec->normal, spec->size);
        o.centre -= o.perspective_correction;
        o.perspective_corrected = true;
      }
      o.quality = std::clamp(fit_contrast / 100.0, 0.0, 1.0) *
                  std::clamp(1.0 - rel / options_.max_residual, 0.0, 1.0);
      res.observations.push_back(o);
      res.summary.num_circles++;
      if (!o.role) res.summary.num_unknown++;
    }
    DropNestedCircles(&res);
  }
  if (!residuals.empty()) res.summary.noise_estimate = Percentile(residuals, 0.5);
  return res;
}

cv::Mat DrawResult(const cv::Mat& mono8, const Result& result) {
  cv::Mat out;
  if (mono8.channels() == 1) {
    cv::cvtColor(mono8, out, cv::COLOR_GRAY2BGR);
  } else {
    out = mono8.clone();
  }
  auto pt = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  };
  for (const auto& o : result.observations) {
    const cv::Scalar colour = o.role ? cv::Scalar(0, 220, 0) : cv::Scalar(0, 220, 220);
    if (o.has_corners) {
      for (int k = 0; k < 4; ++k)
        cv::line(out, pt(o.corners[k]), pt(o.corners[(k + 1) % 4]), colour, 1);
    } else {
      cv::circle(out, pt(o.centre), static_cast<int>(std::lround(0.5 * o.size_px)), colour, 1);
    }
    cv::drawMarker(out, pt(o.centre), colour, cv::MARKER_CROSS, 7, 1);
    cv::putText(out, o.Key(), pt(o.centre + Eigen::Vector2d(4, -4)), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                colour, 1);
  }
  for (const auto& r : result.rejections) {
    cv::drawMarker(out, pt(r.where), cv::Scalar(0, 0, 255), cv::MARKER_TILTED_CROSS, 9, 1);
    cv::putText(out, RejectReasonName(r.reason), pt(r.where + Eigen::Vector2d(4, 10)),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 255), 1);
  }
  return out;
}

}  // namespace targets
}  // namespace slope_monitor
