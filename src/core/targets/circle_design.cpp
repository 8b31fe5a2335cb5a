// Stage 4 of TargetCentroider::DetectMono: which circular design a
// candidate is (CircleDesign), told by 32 rays from its light centre.
#include "centroider_stages.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace detail {
namespace {

// Under perspective the outer edge of a ring is an ellipse that is not
// concentric with the light centre's (the two circles' perspective biases
// differ): along the rays from the light centre its ratio varies as
// m + c cos(t) + s sin(t) to first order in the offset. The ratios with that
// first harmonic removed; it is fitted on the rays within 30 % of the median
// (a stray ray does not tilt it), with 8 of them at least. Perspective
// offsets the outer edge by about (m^2 - 1) r^2 k (r the light centre's
// radius [px], k growing with the obliquity and shrinking with the focal
// length): an offset over kMaxRingOffsetRate (m^2 - 1) r is not perspective
// and is left in (ratios unchanged). Measured: the renders of
// bench_targets_design_sweep need k up to 0.0015 / px (concentric markers
// 100-150 px across, 40 deg oblique, 25 deg off the axis of a 500 px focal
// length); the blobs of the AprilTag photos (test/data/apriltag_real) would
// need 0.0018 / px and more, and are no markers. A margin that thin is what
// the rule is: an oblique marker under a shorter focal length may be refused
// (reason design).
constexpr double kMaxRingOffsetRate = 0.0016;  // [1/px]
std::vector<double> WithoutRingOffset(const std::vector<double>& angles,
                                      const std::vector<double>& ratios, double radius_px) {
  std::vector<double> tmp = ratios;
  const double med = Percentile(tmp, 0.5);
  Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
  Eigen::Vector3d atb = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t i = 0; i < ratios.size(); ++i) {
    if (std::abs(ratios[i] / med - 1.0) > 0.3) continue;
    const Eigen::Vector3d row(1.0, std::cos(angles[i]), std::sin(angles[i]));
    ata += row * row.transpose();
    atb += row * ratios[i];
    ++n;
  }
  if (n < 8) return ratios;
  const Eigen::Vector3d x = ata.ldlt().solve(atb);
  if (!x.allFinite() || x[0] <= 1.0 ||
      std::hypot(x[1], x[2]) > kMaxRingOffsetRate * (x[0] * x[0] - 1.0) * radius_px)
    return ratios;
  std::vector<double> out(ratios.size());
  for (size_t i = 0; i < ratios.size(); ++i)
    out[i] = ratios[i] - x[1] * std::cos(angles[i]) - x[2] * std::sin(angles[i]);
  return out;
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
  std::vector<double> ratios, angles;
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
        angles.push_back(ang);
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
  ratios = WithoutRingOffset(angles, ratios, blob.a);
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
constexpr double kDotSizeShare = 0.9;

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
  std::vector<double> outers, firsts, ground, outer_angles;
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
      outer_angles.push_back(ang);
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
    const std::vector<double> centred = WithoutRingOffset(outer_angles, outers, blob.a);
    int within = 0, inner = 0;
    std::vector<double> first_within;
    for (size_t i = 0; i < outers.size(); ++i) {
      if (std::abs(centred[i] / med - 1.0) > kRingTolerance) continue;
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
    ring_fault =
        Message("outer edge of the dark part seen on ", outers.size(), " of ", ring_rays, " rays");
  }
  // A dot: dark ground on (nearly) every ray, and a ground, not texture: its
  // brightest tenth still in the dark quarter of the contrast; the dot at
  // least circle_min_diameter across on average (a speck of texture is
  // smaller; to within 10 %: the blob's size at the midpoint threshold shrinks a
  // little with blur and noise).
  const double ground_top = Percentile(ground, 0.9);
  const bool uniform = ground_top <= ring + kDotGroundSpread * (disc - ring);
  const bool large = blob.a + blob.b >= kDotSizeShare * min_diameter;
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

}  // namespace

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

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
