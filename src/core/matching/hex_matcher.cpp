#include "slope_monitor/core/matching/hex_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>

#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace matching {

namespace {

struct SearchResult {
  RejectReason reason = RejectReason::kNone;
  Eigen::Vector2d x = Eigen::Vector2d::Zero();
  double score = 0.0;
};

double Dot(const float* a, const float* b, size_t n) {
  double s = 0;
  for (size_t i = 0; i < n; ++i) s += double(a[i]) * b[i];
  return s;
}

// Descriptors of one hex raster computed once per cell on first use (the
// coarsest level is scanned by every search, forward and backward, and the
// finer levels' refinement windows overlap, so the same cells were described
// many times). Falls back to computing on
// the fly when the raster is too large to cache.
class DescriptorCache {
 public:
  DescriptorCache(const HexRaster& raster, int length, bool enabled)
      : raster_(raster), length_(length), n_(6 * length + 1) {
    const size_t cells = static_cast<size_t>(raster.rows()) * raster.cols();
    if (enabled && cells * n_ <= kMaxFloats) {
      values_.reset(new float[cells * n_]);  // uninitialised: only the pages used are touched
      state_.assign(cells, 0);
    }
  }
  // Descriptor of cell (i, k) or nullptr (outside, border, flat).
  const float* Get(int i, int k) {
    if (!raster_.Contains(i, k)) return nullptr;
    if (state_.empty())
      return raster_.Descriptor(i, k, length_, &scratch_) ? scratch_.data() : nullptr;
    const size_t c = static_cast<size_t>(i) * raster_.cols() + k;
    if (state_[c] == 0) {
      state_[c] = raster_.Descriptor(i, k, length_, &scratch_) ? 1 : 2;
      if (state_[c] == 1) std::copy(scratch_.begin(), scratch_.end(), values_.get() + c * n_);
    }
    return state_[c] == 1 ? values_.get() + c * n_ : nullptr;
  }
  size_t size() const { return n_; }

 private:
  static constexpr size_t kMaxFloats = size_t(1) << 26;  // 256 MB
  const HexRaster& raster_;
  const int length_;
  const size_t n_;
  std::unique_ptr<float[]> values_;
  std::vector<std::uint8_t> state_;  // 0 not computed, 1 valid, 2 no descriptor
  std::vector<float> scratch_;
};

using Caches = std::vector<std::unique_ptr<DescriptorCache>>;  // one per pyramid level

Caches MakeCaches(const HexPyramid& p, int length) {
  Caches c;
  // Level 0 is not cached: it is large, its refinement windows are visited
  // once per search, and caching it measured slower (page faults).
  for (int l = 0; l < p.levels(); ++l) {
    c.push_back(std::make_unique<DescriptorCache>(p.level(l), length, l > 0 || p.levels() == 1));
  }
  return c;
}

// Coarse-to-fine search of xa (in pyramid a) in pyramid b around centre_b.
// `line` (if non-null) maps a point of a to its epipolar line in b. cas,
// cbs: descriptor caches of the levels of pa and pb.
SearchResult Search(const HexPyramid& pa, const HexPyramid& pb, Caches& cas, Caches& cbs,
                    const Eigen::Vector2d& xa, const Eigen::Vector2d& centre_b, double radius,
                    const Eigen::Matrix3d* f, double band, const HexMatcherOptions& o) {
  SearchResult res;
  const int top = pa.levels() - 1;
  DescriptorCache* ca = cas[top].get();
  DescriptorCache* cb = cbs[top].get();
  const HexRaster& ha = pa.level(top);
  const HexRaster& hb = pb.level(top);
  int ia, ka;
  ha.NearestCell(xa, &ia, &ka);
  const float* dtop = ca->Get(ia, ka);
  if (!dtop) {
    res.reason = RejectReason::kNoDescriptor;
    return res;
  }
  Eigen::Vector3d line = Eigen::Vector3d::Zero();
  if (f) {
    line = *f * Eigen::Vector3d(xa.x(), xa.y(), 1.0);
    line /= std::max(1e-12, line.head<2>().norm());
  }
  struct Cand {
    double score;
    Eigen::Vector2d x;
  };
  std::vector<Cand> cands;
  const int i0 = static_cast<int>(std::floor((centre_b.y() - radius + 0.5) / hb.dy() - 0.5)) - 1;
  const int i1 = static_cast<int>(std::ceil((centre_b.y() + radius + 0.5) / hb.dy() - 0.5)) + 1;
  const int k0 = static_cast<int>(std::floor((centre_b.x() - radius) / hb.dx())) - 1;
  const int k1 = static_cast<int>(std::ceil((centre_b.x() + radius) / hb.dx())) + 1;
  const double r2 = radius * radius;
  for (int i = std::max(0, i0); i <= std::min(hb.rows() - 1, i1); ++i) {
    for (int k = std::max(0, k0); k <= std::min(hb.cols() - 1, k1); ++k) {
      const Eigen::Vector2d c = hb.Centre(i, k);
      if ((c - centre_b).squaredNorm() > r2) continue;
      if (f && std::fabs(line.dot(Eigen::Vector3d(c.x(), c.y(), 1.0))) > band + hb.dx()) continue;
      const float* dc = cb->Get(i, k);
      if (!dc) continue;
      cands.push_back({Dot(dtop, dc, cb->size()), c});
    }
  }
  if (cands.empty()) {
    res.reason = RejectReason::kLowScore;
    return res;
  }
  const auto best = std::max_element(
      cands.begin(), cands.end(), [](const Cand& a, const Cand& b) { return a.score < b.score; });
  if (best->score < o.min_score) {
    res.reason = RejectReason::kLowScore;
    return res;
  }
  double second = -1.0;
  const double excl2 = std::pow(2.5 * hb.dx(), 2);
  for (const Cand& c : cands)
    if ((c.x - best->x).squaredNorm() > excl2) second = std::max(second, c.score);
  const double d_best = std::sqrt(std::max(0.0, 2.0 - 2.0 * best->score));
  const double d_second = std::sqrt(std::max(0.0, 2.0 - 2.0 * second));
  if (second > -1.0 && d_best > o.max_ratio * d_second) {
    res.reason = RejectReason::kAmbiguous;
    return res;
  }
  res.score = best->score;
  Eigen::Vector2d x = best->x;
  // Refinement down the pyramid.
  for (int l = top - 1; l >= 0; --l) {
    const HexRaster& la = pa.level(l);
    const HexRaster& lb = pb.level(l);
    la.NearestCell(xa, &ia, &ka);
    const float* da = cas[l]->Get(ia, ka);
    if (!da) continue;
    int ib, kb;
    lb.NearestCell(x, &ib, &kb);
    double bs = -2.0;
    Eigen::Vector2d bx = x;
    const double rr = std::pow(2.2 * lb.dx() * 2.0, 2);
    for (int i = ib - 5; i <= ib + 5; ++i)
      for (int k = kb - 5; k <= kb + 5; ++k) {
        if (!lb.Contains(i, k)) continue;
        const Eigen::Vector2d c = lb.Centre(i, k);
        if ((c - x).squaredNorm() > rr) continue;
        const float* db = cbs[l]->Get(i, k);
        if (!db) continue;
        const double s = Dot(da, db, cbs[l]->size());
        if (s > bs) {
          bs = s;
          bx = c;
        }
      }
    x = bx;
  }
  res.x = x;
  return res;
}

}  // namespace

void HexMatcherOptions::Check() const {
  auto fail = [](const char* key, auto value, const char* range) {
    throw ConfigError(Message("hex matcher option '", key, "' = ", value, " out of range ", range));
  };
  if (pyramid_levels < 1 || pyramid_levels > 6) fail("pyramid_levels", pyramid_levels, "[1, 6]");
  if (profile_length < 1 || profile_length > 16) fail("profile_length", profile_length, "[1, 16]");
  if (!(min_score >= -1 && min_score <= 1)) fail("min_score", min_score, "[-1, 1]");
  if (!(max_ratio > 0 && max_ratio <= 1)) fail("max_ratio", max_ratio, "(0, 1]");
  if (!(mutual_tolerance > 0)) fail("mutual_tolerance", mutual_tolerance, "(0, inf)");
  if (lsc_search_radius < 0 || lsc_search_radius > 20)
    fail("lsc_search_radius", lsc_search_radius, "[0, 20]");
  if (!(lsc_prefilter_sigma >= 0 && lsc_prefilter_sigma <= 5)) {
    fail("lsc_prefilter_sigma", lsc_prefilter_sigma, "[0, 5]");
  }
  if (!(quality.min_correlation >= -1 && quality.min_correlation <= 1)) {
    fail("quality.min_correlation", quality.min_correlation, "[-1, 1]");
  }
  if (!(quality.max_residual_ratio > 1))
    fail("quality.max_residual_ratio", quality.max_residual_ratio, "(1, inf)");
  if (!(quality.max_two_way > 0)) fail("quality.max_two_way", quality.max_two_way, "(0, inf)");
  if (!(quality.neighbour_radius > 0))
    fail("quality.neighbour_radius", quality.neighbour_radius, "(0, inf)");
  if (!(quality.max_neighbour_deviation > 0)) {
    fail("quality.max_neighbour_deviation", quality.max_neighbour_deviation, "(0, inf)");
  }
  interest.Check();
  lsc.Check();
}

std::string QualityFlagNames(unsigned flags) {
  std::string out;
  auto add = [&](unsigned bit, const char* name) {
    if (!(flags & bit)) return;
    if (!out.empty()) out += "+";
    out += name;
  };
  add(kFlagLowCorrelation, "low_correlation");
  add(kFlagHighResidual, "high_residual");
  add(kFlagTwoWay, "two_way");
  add(kFlagNeighbours, "neighbours");
  add(kFlagExcluded, "excluded");
  return out;
}

const char* RejectReasonName(RejectReason reason) {
  switch (reason) {
    case RejectReason::kNone:
      return "none";
    case RejectReason::kNoDescriptor:
      return "no_descriptor";
    case RejectReason::kLowScore:
      return "low_score";
    case RejectReason::kAmbiguous:
      return "ambiguous";
    case RejectReason::kNotMutual:
      return "not_mutual";
    case RejectReason::kLsc:
      return "lsc";
    case RejectReason::kEpipolar:
      return "epipolar";
  }
  return "unknown";
}

Eigen::Matrix3d FundamentalFromOrientation(const camera::CameraModel& camera_a,
                                           const camera::ExteriorOrientation& pose_a,
                                           const camera::CameraModel& camera_b,
                                           const camera::ExteriorOrientation& pose_b) {
  const Eigen::Matrix3d ka = camera_a.ToOpenCv().k, kb = camera_b.ToOpenCv().k;
  const Rigid3 b_from_a = pose_b.OpticalFromSite() * pose_a.SiteFromOptical();
  const Eigen::Matrix3d r = b_from_a.rotation.toRotationMatrix();
  const Eigen::Vector3d t = b_from_a.translation;
  Eigen::Matrix3d tx;
  tx << 0, -t.z(), t.y(), t.z(), 0, -t.x(), -t.y(), t.x(), 0;
  return kb.inverse().transpose() * tx * r * ka.inverse();
}

double EpipolarDistance(const Eigen::Matrix3d& f, const Eigen::Vector2d& xa,
                        const Eigen::Vector2d& xb) {
  const Eigen::Vector3d l = f * Eigen::Vector3d(xa.x(), xa.y(), 1.0);
  const double n = l.head<2>().norm();
  if (n <= 0) return 0.0;
  return std::fabs(l.dot(Eigen::Vector3d(xb.x(), xb.y(), 1.0))) / n;
}

HexMatcher::HexMatcher(const HexMatcherOptions& options) : options_(options) { options_.Check(); }

namespace {

// Quality control of a pair's matches: flags for a residual above the
// pair's noise level, a displacement inconsistent with the neighbours' (their
// median, tolerance widened by their spread); flagged matches are counted
// and rejected or kept with a low quality (q.reject).
void ApplyMatchQualityControl(const HexMatcherOptions::Quality& q, HexMatchResult* result_io) {
  HexMatchResult& result = *result_io;
  // Residual against the pair's noise level (median sigma0 of all matches).
  std::vector<double> s0;
  for (const HexMatch& m : result.matches) s0.push_back(m.sigma0);
  std::nth_element(s0.begin(), s0.begin() + s0.size() / 2, s0.end());
  const double noise = s0[s0.size() / 2];
  // Displacement consistency with the neighbours (median of each component).
  const double r2 = q.neighbour_radius * q.neighbour_radius;
  std::vector<double> nx, ny;
  for (HexMatch& m : result.matches) {
    if (m.sigma0 > q.max_residual_ratio * noise) m.flags |= kFlagHighResidual;
    nx.clear();
    ny.clear();
    for (const HexMatch& o : result.matches) {
      if (&o == &m || (o.xa - m.xa).squaredNorm() > r2) continue;
      nx.push_back(o.xb.x() - o.xa.x());
      ny.push_back(o.xb.y() - o.xa.y());
    }
    if (nx.size() < 3) continue;
    const Eigen::Vector2d median(UpperMedian(nx), UpperMedian(ny));
    // Spread of the neighbours (MAD): a real displacement gradient (the
    // margin of a moving body) widens the tolerance.
    for (double& v : nx) v = std::fabs(v - median.x());
    for (double& v : ny) v = std::fabs(v - median.y());
    const double spread = 1.4826 * std::hypot(UpperMedian(nx), UpperMedian(ny));
    if ((m.xb - m.xa - median).norm() > q.max_neighbour_deviation + 3.0 * spread)
      m.flags |= kFlagNeighbours;
  }
  std::vector<HexMatch> kept;
  for (HexMatch& m : result.matches) {
    if (m.flags == 0) {
      kept.push_back(m);
      continue;
    }
    ++result.summary.low_quality;
    for (unsigned bit = 1; bit <= kFlagExcluded; bit <<= 1) {
      if (m.flags & bit) ++result.summary.flags[QualityFlagNames(bit)];
    }
    if (q.reject) {
      ++result.summary.rejects["low_quality"];
      continue;
    }
    m.quality = std::min(kLowQuality, 0.25 * m.quality);
    kept.push_back(m);
  }
  result.matches.swap(kept);
}

}  // namespace

HexMatchResult HexMatcher::Match(const cv::Mat& image_a, const cv::Mat& image_b,
                                 const MatchPrior& prior) const {
  const auto t0 = std::chrono::steady_clock::now();
  if (image_a.empty() || image_b.empty())
    throw InvalidArgument("HexMatcher::Match: an input image is empty");
  if (image_a.size() != image_b.size()) {
    throw InvalidArgument(Message("HexMatcher::Match: images differ in size (a ", image_a.cols, "x",
                                  image_a.rows, ", b ", image_b.cols, "x", image_b.rows, ")"));
  }
  if (image_a.type() != image_b.type()) {
    throw InvalidArgument(Message("HexMatcher::Match: images differ in encoding (OpenCV type a ",
                                  image_a.type(), ", b ", image_b.type(), ")"));
  }
  if (!(prior.radius > 0) || !(prior.moving_radius > 0) || !(prior.epipolar_band > 0)) {
    throw InvalidArgument(
        "HexMatcher::Match: prior radius, moving_radius and epipolar_band must be > 0");
  }
  const cv::Mat fa = ToFloat(image_a, "image a"), fb = ToFloat(image_b, "image b");
  const HexPyramid pa(fa, options_.pyramid_levels, options_.sampling);
  const HexPyramid pb(fb, options_.pyramid_levels, options_.sampling);
  const std::vector<InterestPoint> points = DetectInterestPoints(fa, options_.interest);
  LscOptions lsc = options_.lsc;
  lsc.search_radius = options_.lsc_search_radius;
  // LSC on low-passed copies when asked (weak texture under noise).
  const cv::Mat la =
      options_.lsc_prefilter_sigma > 0 ? GaussianBlur(fa, options_.lsc_prefilter_sigma) : fa;
  const cv::Mat lb =
      options_.lsc_prefilter_sigma > 0 ? GaussianBlur(fb, options_.lsc_prefilter_sigma) : fb;
  const Eigen::Matrix3d* f = prior.has_epipolar ? &prior.fundamental : nullptr;
  const Eigen::Matrix3d ft = prior.fundamental.transpose();
  const Eigen::Matrix3d* f_back = prior.has_epipolar ? &ft : nullptr;

  Caches cache_a = MakeCaches(pa, options_.profile_length);
  Caches cache_b = MakeCaches(pb, options_.profile_length);
  LscOptions lsc_back = lsc;
  lsc_back.search_radius = 0;  // plain LSC from xa: the forward solution is already sub-pixel
  // The texture tests were passed by window a; b's window at a sub-pixel
  // position may fall just below them without being a different surface.
  lsc_back.min_eigen_ratio = 0.0;
  lsc_back.min_gradient_energy = 0.0;
  const HexMatcherOptions::Quality& q = options_.quality;
  auto match_one = [&](const Eigen::Vector2d& xa, const Eigen::Vector2d& shift, double radius,
                       HexMatch* m, bool final_pass) {
    const SearchResult fw =
        Search(pa, pb, cache_a, cache_b, xa, xa + shift, radius, f, prior.epipolar_band, options_);
    if (fw.reason != RejectReason::kNone) return std::string(RejectReasonName(fw.reason));
    const SearchResult bw = Search(pb, pa, cache_b, cache_a, fw.x, fw.x - shift, radius, f_back,
                                   prior.epipolar_band, options_);
    if (bw.reason != RejectReason::kNone || (bw.x - xa).norm() > options_.mutual_tolerance) {
      return std::string(RejectReasonName(RejectReason::kNotMutual));
    }
    const LscSummary s = MatchLsc(la, lb, xa, fw.x, lsc);
    if (!s.IsSolutionUsable()) return std::string("lsc_") + LscStatusName(s.status);
    if (f && EpipolarDistance(*f, xa, s.xb) > prior.epipolar_band) {
      return std::string(RejectReasonName(RejectReason::kEpipolar));
    }
    m->xa = xa;
    m->xb = s.xb;
    m->covariance = s.covariance;
    m->score = fw.score;
    m->correlation = s.correlation;
    m->quality =
        std::max(0.0, std::min(1.0, s.correlation)) * std::max(0.0, std::min(1.0, fw.score));
    m->sigma0 = s.sigma0;
    m->flags = 0;
    if (final_pass && q.enabled) {
      if (s.correlation < q.min_correlation) m->flags |= kFlagLowCorrelation;
      if (prior.excluded && prior.excluded(xa)) m->flags |= kFlagExcluded;
      if (q.two_way) {
        const LscSummary back = MatchLsc(lb, la, s.xb, xa, lsc_back);
        // Its position is what counts: a back solution that ran out of
        // iterations (measured: eq. 1 on a noise-free warp, still within
        // 0.01 px) or is imprecise is still compared.
        using St = LscSummary::Status;
        const bool placed = back.status == St::kConverged || back.status == St::kNotConverged ||
                            back.status == St::kImprecise;
        m->two_way_error = placed ? (back.xb - xa).norm() : -1.0;
        if (m->two_way_error < 0 || m->two_way_error > q.max_two_way) m->flags |= kFlagTwoWay;
      }
    }
    return std::string();
  };

  HexMatchResult result;
  Eigen::Vector2d shift = prior.shift;
  if (prior.estimate_global_shift) {
    std::vector<double> dx, dy;
    for (const InterestPoint& p : points) {
      if (prior.moving && prior.moving(p.x)) continue;
      if (prior.within && !prior.within(p.x)) continue;
      HexMatch m;
      if (match_one(p.x, prior.shift, prior.radius, &m, false).empty()) {
        dx.push_back(m.xb.x() - m.xa.x());
        dy.push_back(m.xb.y() - m.xa.y());
      }
    }
    if (!dx.empty()) {
      std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
      std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
      shift = Eigen::Vector2d(dx[dx.size() / 2], dy[dy.size() / 2]);
    }
  }
  result.summary.global_shift = shift;
  for (const InterestPoint& p : points) {
    if (prior.within && !prior.within(p.x)) continue;
    ++result.summary.candidates;
    const bool moving = prior.moving && prior.moving(p.x);
    HexMatch m;
    const std::string reason =
        match_one(p.x, shift, moving ? prior.moving_radius : prior.radius, &m, true);
    if (reason.empty()) {
      result.matches.push_back(m);
    } else {
      ++result.summary.rejects[reason];
    }
  }
  if (q.enabled && !result.matches.empty()) ApplyMatchQualityControl(q, &result);
  result.summary.matched = static_cast<int>(result.matches.size());
  result.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace matching
}  // namespace slope_monitor
