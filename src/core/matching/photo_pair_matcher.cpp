#include "slope_monitor/core/matching/photo_pair_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>

#include <Eigen/Geometry>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"

namespace slope_monitor {
namespace matching {
namespace {

cv::Mat ToGrey8(const cv::Mat& image, const std::string& name) {
  if (image.empty()) throw InvalidArgument(Message("photo '", name, "': empty image"));
  const int ch = image.channels();
  if (image.depth() != CV_8U && image.depth() != CV_16U) {
    throw InvalidArgument(Message("photo '", name, "': pixel depth must be 8 or 16 bit"));
  }
  if (ch != 1 && ch != 3 && ch != 4) {
    throw InvalidArgument(Message("photo '", name, "': ", ch, " channels (1, 3 or 4 supported)"));
  }
  cv::Mat grey;
  if (ch == 1) {
    grey = image;
  } else {
    cv::cvtColor(image, grey, ch == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
  }
  if (grey.depth() == CV_16U) grey.convertTo(grey, CV_8U, 1.0 / 257.0);
  return grey.clone();
}

Eigen::Vector2d Apply(const Eigen::Matrix3d& h, const Eigen::Vector2d& x) {
  const Eigen::Vector3d p = h * x.homogeneous();
  return p.hnormalized();
}

// d(H x)/dx at x.
Eigen::Matrix2d Jacobian(const Eigen::Matrix3d& h, const Eigen::Vector2d& x) {
  const Eigen::Vector3d p = h * x.homogeneous();
  Eigen::Matrix2d j;
  for (int r = 0; r < 2; ++r) {
    for (int c = 0; c < 2; ++c) j(r, c) = (h(r, c) * p.z() - p(r) * h(2, c)) / (p.z() * p.z());
  }
  return j;
}

struct CoarseRelation {
  Eigen::Matrix3d b_from_a = Eigen::Matrix3d::Identity();
  std::vector<Eigen::Vector2d> xa;        // inlier positions in a
  std::vector<Eigen::Vector2d> residual;  // xb - H xa of the inliers
};

// Angle in (-180, 180].
double Wrap(double deg) {
  deg = std::fmod(deg, 360.0);
  if (deg > 180.0) deg -= 360.0;
  if (deg <= -180.0) deg += 360.0;
  return deg;
}

// Rotation and log2 scale of a match's keypoints (b relative to a).
struct MatchShape {
  double rotation;  // [deg]
  double log2_scale;
};

// The pair's rotation and log2 scale: the prior where given, else the peak
// of the vote (bins of the tolerances, each match voting for its bin and the
// 3 x 3 neighbourhood summed at the peak).
MatchShape PairShape(const std::vector<MatchShape>& shapes, const PhotoPairOptions& o,
                     const PhotoPairPrior& prior) {
  const int na = std::max(1, static_cast<int>(std::lround(360.0 / o.rotation_tolerance_deg)));
  const double wa = 360.0 / na, ws = o.log2_scale_tolerance;
  const int ns = 2 * static_cast<int>(std::ceil(3.0 / ws)) + 1;  // log2 scale within +-3
  auto sbin = [&](double l) {
    return std::clamp(static_cast<int>(std::floor(l / ws + 0.5)) + ns / 2, 0, ns - 1);
  };
  auto abin = [&](double r) { return static_cast<int>(std::floor((r + 180.0) / wa)) % na; };
  std::vector<int> votes(static_cast<size_t>(na) * ns, 0);
  for (const MatchShape& m : shapes) {
    if (prior.has_rotation &&
        std::abs(Wrap(m.rotation - prior.rotation_deg)) > o.rotation_tolerance_deg)
      continue;
    if (prior.has_scale && std::abs(m.log2_scale - std::log2(prior.scale)) > o.log2_scale_tolerance)
      continue;
    ++votes[sbin(m.log2_scale) * na + abin(m.rotation)];
  }
  int best = -1, best_votes = -1;
  for (int is = 0; is < ns; ++is) {
    for (int ia = 0; ia < na; ++ia) {
      int v = 0;
      for (int ds = -1; ds <= 1; ++ds) {
        for (int da = -1; da <= 1; ++da) {
          if (is + ds >= 0 && is + ds < ns) v += votes[(is + ds) * na + (ia + da + na) % na];
        }
      }
      if (v > best_votes) best_votes = v, best = is * na + ia;
    }
  }
  const int rotation_bin = best % na, scale_bin = best / na - ns / 2;  // scale 0 at ns / 2
  MatchShape peak{(rotation_bin + 0.5) * wa - 180.0, scale_bin * ws};
  if (prior.has_rotation) peak.rotation = prior.rotation_deg;
  if (prior.has_scale) peak.log2_scale = std::log2(prior.scale);
  return peak;
}

// SIFT matches (FLANN, ratio test), those consistent with the pair's
// rotation and scale, RANSAC homography. False when too few inliers.
bool CoarseMatch(const PhotoFeatures& a, const PhotoFeatures& b, const PhotoPairOptions& o,
                 const PhotoPairPrior& prior, CoarseRelation* rel, PhotoPairSummary* s) {
  if (a.coarse_descriptors().rows < 2 || b.coarse_descriptors().rows < 2) {
    s->message = "too few SIFT features";
    return false;
  }
  // Exact nearest neighbours (brute force, L2): the same matches on every
  // run and thread. OpenCV's FLANN k-d trees are drawn from the thread's
  // random state, and on the real snowpeak pairs the approximate search
  // changed the tie points by a third from one random state to another.
  std::vector<std::vector<cv::DMatch>> knn;
  cv::BFMatcher matcher(cv::NORM_L2);
  matcher.knnMatch(a.coarse_descriptors(), b.coarse_descriptors(), knn, 2);
  std::vector<cv::DMatch> ratio;
  std::vector<MatchShape> shapes;
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < o.coarse_ratio * m[1].distance) {
      ratio.push_back(m[0]);
      shapes.push_back(
          {Wrap(b.coarse_angles()[m[0].trainIdx] - a.coarse_angles()[m[0].queryIdx]),
           std::log2(b.coarse_sizes()[m[0].trainIdx] / a.coarse_sizes()[m[0].queryIdx])});
    }
  }
  s->coarse_matches = static_cast<int>(ratio.size());
  const MatchShape peak = PairShape(shapes, o, prior);
  std::vector<cv::Point2f> pa, pb;
  for (size_t i = 0; i < ratio.size(); ++i) {
    if (std::abs(Wrap(shapes[i].rotation - peak.rotation)) <= o.rotation_tolerance_deg &&
        std::abs(shapes[i].log2_scale - peak.log2_scale) <= o.log2_scale_tolerance) {
      pa.push_back(a.coarse_points()[ratio[i].queryIdx]);
      pb.push_back(b.coarse_points()[ratio[i].trainIdx]);
    }
  }
  s->coarse_consistent = static_cast<int>(pa.size());
  if (static_cast<int>(pa.size()) < o.min_coarse_inliers) {
    s->message = Message("only ", pa.size(), " consistent coarse SIFT matches (min_coarse_inliers ",
                         o.min_coarse_inliers, ")");
    return false;
  }
  std::vector<unsigned char> mask;
  const cv::Mat h =
      cv::findHomography(pa, pb, cv::RANSAC, o.coarse_ransac_threshold, mask, 4000, 0.999);
  if (h.empty()) {
    s->message = "no homography from the coarse matches";
    return false;
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rel->b_from_a(r, c) = h.at<double>(r, c);
  for (size_t i = 0; i < pa.size(); ++i) {
    if (!mask[i]) continue;
    const Eigen::Vector2d xa(pa[i].x, pa[i].y), xb(pb[i].x, pb[i].y);
    rel->xa.push_back(xa);
    rel->residual.push_back(xb - Apply(rel->b_from_a, xa));
  }
  s->coarse_inliers = static_cast<int>(rel->xa.size());
  if (s->coarse_inliers < o.min_coarse_inliers) {
    s->message = Message("only ", s->coarse_inliers, " coarse inliers (min_coarse_inliers ",
                         o.min_coarse_inliers, ")");
    return false;
  }
  const Eigen::Vector2d centre(0.5 * (a.size().width - 1), 0.5 * (a.size().height - 1));
  const Eigen::Matrix2d j = Jacobian(rel->b_from_a, centre);
  s->b_from_a = rel->b_from_a;
  s->rotation_deg = std::atan2(j(1, 0) - j(0, 1), j(0, 0) + j(1, 1)) * 180.0 / M_PI;
  s->scale = std::sqrt(std::abs(j.determinant()));
  return true;
}

// Median residual of the `k` coarse inliers nearest to xa.
Eigen::Vector2d LocalCorrection(const CoarseRelation& rel, const Eigen::Vector2d& xa, int k,
                                std::vector<std::pair<double, int>>* scratch) {
  scratch->clear();
  for (size_t i = 0; i < rel.xa.size(); ++i)
    scratch->emplace_back((rel.xa[i] - xa).squaredNorm(), int(i));
  const size_t n = std::min(scratch->size(), static_cast<size_t>(k));
  std::partial_sort(scratch->begin(), scratch->begin() + n, scratch->end());
  std::vector<double> dx, dy;
  for (size_t i = 0; i < n; ++i) {
    dx.push_back(rel.residual[(*scratch)[i].second].x());
    dy.push_back(rel.residual[(*scratch)[i].second].y());
  }
  return Eigen::Vector2d(UpperMedian(dx), UpperMedian(dy));
}

}  // namespace

PhotoFeatureOptions BlockPhotoFeatureOptions() {
  PhotoFeatureOptions o;
  o.coarse_max_features = 2000;
  o.coarse_sift_max_side = 640;
  o.interest.max_points = 2000;
  o.interest.cells = 8;
  return o;
}

void PhotoFeatureOptions::Check() const {
  if (coarse_max_side < 200 || coarse_max_side > 10000)
    throw ConfigError("coarse_max_side must be in [200, 10000]");
  if (coarse_sift_max_side < 100 || coarse_sift_max_side > 10000)
    throw ConfigError("coarse_sift_max_side must be in [100, 10000]");
  if (coarse_max_features < 10) throw ConfigError("coarse_max_features must be >= 10");
  if (!(coarse_contrast_threshold > 0.0 && coarse_contrast_threshold < 1.0))
    throw ConfigError("coarse_contrast_threshold must be in (0, 1)");
  interest.Check();
}

PhotoFeatures::PhotoFeatures(const cv::Mat& image, const std::string& name,
                             const PhotoFeatureOptions& options)
    : name_(name) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  grey_ = ToGrey8(image, name);
  const double reduce = std::min(
      1.0, static_cast<double>(options.coarse_max_side) / std::max(grey_.cols, grey_.rows));
  reduce_ = reduce;
  reduced_ = grey_;
  if (reduce < 1.0) cv::resize(grey_, reduced_, cv::Size(), reduce, reduce, cv::INTER_AREA);
  // SIFT (the coarse relation) and the interest points (the LSC candidates)
  // are independent: both at once, each into its own members.
  std::exception_ptr failed[2];
  cv::parallel_for_(
      cv::Range(0, 2),
      [&](const cv::Range& range) {
        for (int task = range.start; task < range.end; ++task) {
          try {
            if (task == 0)
              DetectSift(options);
            else
              interest_points_ = DetectInterestPoints(reduced_, options.interest);
          } catch (...) {
            failed[task] = std::current_exception();
          }
        }
      },
      2);
  for (const std::exception_ptr& e : failed)
    if (e) std::rethrow_exception(e);
  seconds_ = SecondsSince(start);
}

void PhotoFeatures::DetectSift(const PhotoFeatureOptions& options) {
  // SIFT's copy: the reduced one, or smaller (coarse_sift_max_side).
  const double scale = std::min(reduce_, static_cast<double>(options.coarse_sift_max_side) /
                                             std::max(grey_.cols, grey_.rows));
  cv::Mat copy = reduced_;
  if (scale < reduce_) cv::resize(grey_, copy, cv::Size(), scale, scale, cv::INTER_AREA);
  std::vector<cv::KeyPoint> keys;
  cv::SIFT::create(options.coarse_max_features, 3, options.coarse_contrast_threshold)
      ->detectAndCompute(copy, cv::noArray(), keys, coarse_descriptors_);
  const float s = static_cast<float>(scale);
  for (const auto& k : keys) {
    // Pixel centres: x_full + 0.5 = (x_small + 0.5) / scale.
    coarse_points_.emplace_back((k.pt.x + 0.5f) / s - 0.5f, (k.pt.y + 0.5f) / s - 0.5f);
    // OpenCV's SIFT angle, measured from x towards y (clockwise on screen);
    // checked on the real pairs: rotation of the homography = angle in b - in a.
    coarse_angles_.push_back(static_cast<float>(Wrap(k.angle)));
    coarse_sizes_.push_back(k.size / s);
  }
}

size_t PhotoFeatures::MemoryBytes() const {
  return grey_.total() * grey_.elemSize() +
         (reduce_ < 1.0 ? reduced_.total() * reduced_.elemSize() : 0) +
         coarse_descriptors_.total() * coarse_descriptors_.elemSize() +
         coarse_points_.size() * (sizeof(cv::Point2f) + 2 * sizeof(float)) +
         interest_points_.size() * sizeof(InterestPoint);
}

void PhotoPairOptions::Check() const {
  if (!(coarse_ratio > 0.0 && coarse_ratio <= 1.0))
    throw ConfigError("coarse_ratio must be in (0, 1]");
  if (!(rotation_tolerance_deg > 0.0 && rotation_tolerance_deg <= 180.0)) {
    throw ConfigError("rotation_tolerance_deg must be in (0, 180]");
  }
  if (!(log2_scale_tolerance > 0.0)) throw ConfigError("log2_scale_tolerance must be > 0");
  if (!(coarse_ransac_threshold > 0.0)) throw ConfigError("coarse_ransac_threshold must be > 0");
  if (min_coarse_inliers < 8) throw ConfigError("min_coarse_inliers must be >= 8");
  if (neighbours < 1) throw ConfigError("neighbours must be >= 1");
  if (max_candidates < 1) throw ConfigError("max_candidates must be >= 1");
  if (border < 0) throw ConfigError("border must be >= 0");
  if (!(screen_threshold > 0.0)) throw ConfigError("screen_threshold must be > 0");
  if (threads < 0 || threads > 64) throw ConfigError("threads must be in [0, 64]");
  lsc.Check();
  refine_lsc.Check();
}

double EpipolarRms(const std::vector<cv::Point2f>& xa, const std::vector<cv::Point2f>& xb,
                   double threshold, std::vector<unsigned char>* inliers) {
  std::vector<unsigned char> mask;
  if (inliers) inliers->clear();
  if (xa.size() < 8 || xa.size() != xb.size()) return 0.0;
  const cv::Mat f = cv::findFundamentalMat(xa, xb, cv::FM_RANSAC, threshold, 0.999, mask);
  if (f.rows != 3 || f.cols != 3) return 0.0;
  Eigen::Matrix3d fe;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) fe(r, c) = f.at<double>(r, c);
  double sum = 0.0;
  int n = 0;
  for (size_t i = 0; i < xa.size(); ++i) {
    if (!mask[i]) continue;
    const Eigen::Vector3d a(xa[i].x, xa[i].y, 1.0), b(xb[i].x, xb[i].y, 1.0);
    const Eigen::Vector3d lb = fe * a, la = fe.transpose() * b;
    const double e = b.dot(lb);
    sum += e * e / lb.head<2>().squaredNorm() + e * e / la.head<2>().squaredNorm();
    n += 2;
  }
  if (inliers) *inliers = mask;
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

namespace {

// One window: a's window around xa against b warped into a's frame by the
// local map xb = xb0 + j (x - xa); modified LSC; the solution mapped into b.
// False (and the LSC status in *status) when LSC fails.
bool MatchWindow(const cv::Mat& grey_a, const cv::Mat& grey_b, const Eigen::Vector2d& xa,
                 const Eigen::Vector2d& xb0, const Eigen::Matrix2d& j, const LscOptions& lsc,
                 PhotoTiePoint* tp, Eigen::Matrix2d* local, std::string* status) {
  const int half = std::max(lsc.half_window, lsc.search_half_window) + lsc.search_radius +
                   static_cast<int>(std::ceil(lsc.max_shift)) + 3;
  const int size = 2 * half + 1;
  const cv::Rect win(static_cast<int>(std::lround(xa.x())) - half,
                     static_cast<int>(std::lround(xa.y())) - half, size, size);
  if ((win & cv::Rect(0, 0, grey_a.cols, grey_a.rows)) != win) {
    *status = "outside_a";
    return false;
  }
  const Eigen::Vector2d xa_in_win = xa - Eigen::Vector2d(win.x, win.y);
  // Window pixel x <- b at xb0 + j (x - xa_in_win).
  const Eigen::Vector2d t = xb0 - j * xa_in_win;
  const cv::Matx23d m(j(0, 0), j(0, 1), t.x(), j(1, 0), j(1, 1), t.y());
  cv::Mat wa, wb;
  grey_a(win).convertTo(wa, CV_32F);
  cv::warpAffine(grey_b, wb, m, cv::Size(size, size), cv::INTER_CUBIC | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REPLICATE);
  wb.convertTo(wb, CV_32F);
  const LscSummary r = MatchLsc(wa, wb, xa_in_win, xa_in_win, lsc);
  if (!r.IsSolutionUsable()) {
    *status = std::string("lsc_") + LscStatusName(r.status);
    return false;
  }
  tp->xa = xa;
  tp->xb = xb0 + j * (r.xb - xa_in_win);
  tp->covariance = j * r.covariance * j.transpose();
  tp->quality = std::clamp(r.correlation, 0.0, 1.0);
  // The affine LSC's map of a's window into the warped window, composed with j.
  *local = j * (Eigen::Matrix2d::Identity() +
                Eigen::Map<const Eigen::Matrix2d>(r.affine.data()).transpose());
  if (tp->xb.x() < 0 || tp->xb.y() < 0 || tp->xb.x() > grey_b.cols - 1 ||
      tp->xb.y() > grey_b.rows - 1) {
    *status = "outside_b";
    return false;
  }
  return true;
}

Eigen::Vector2d Scaled(const Eigen::Vector2d& x, double f) {  // pixel centres: (x + 0.5) f - 0.5
  return (x.array() + 0.5) * f - 0.5;
}

struct WindowMatch {
  bool matched = false;
  PhotoTiePoint tie_point;
  std::string status;  // why not matched ("" when matched)
};

// Candidate xa (full-resolution pixels of a): predicted in b by the relation
// and the local correction of its nearest coarse inliers, matched on the
// reduced photos, then (refine) at full resolution from there.
WindowMatch MatchCandidate(const PhotoFeatures& a, const PhotoFeatures& b,
                           const CoarseRelation& rel, const Eigen::Vector2d& xa, bool refine,
                           const PhotoPairOptions& options,
                           std::vector<std::pair<double, int>>* scratch) {
  const double ra = a.reduce(), rb = b.reduce();
  const Eigen::Vector2d xb0 =
      Apply(rel.b_from_a, xa) + LocalCorrection(rel, xa, options.neighbours, scratch);
  // Local map in reduced pixels: b_reduced = rb * J * a_reduced / ra.
  const Eigen::Matrix2d j = Jacobian(rel.b_from_a, xa) * (rb / ra);
  WindowMatch out;
  PhotoTiePoint& tp = out.tie_point;
  Eigen::Matrix2d local;
  if (!MatchWindow(a.reduced(), b.reduced(), Scaled(xa, ra), Scaled(xb0, rb), j, options.lsc, &tp,
                   &local, &out.status)) {
    return out;
  }
  if (refine) {
    const Eigen::Vector2d xb1 = Scaled(tp.xb, 1.0 / rb);
    const Eigen::Matrix2d j1 = local * (ra / rb);
    if (!MatchWindow(a.grey(), b.grey(), xa, xb1, j1, options.refine_lsc, &tp, &local,
                     &out.status)) {
      out.status = "refine_" + out.status;
      return out;
    }
  } else {
    tp.xa = xa;
  }
  out.matched = true;
  return out;
}

}  // namespace

PhotoPairResult MatchPhotoPair(const PhotoFeatures& a, const PhotoFeatures& b,
                               const PhotoPairOptions& options, const PhotoPairPrior& prior) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  PhotoPairResult result;
  PhotoPairSummary& s = result.summary;
  CoarseRelation rel;
  if (!CoarseMatch(a, b, options, prior, &rel, &s)) {
    s.seconds = SecondsSince(start);
    return result;
  }
  // Level 1: the reduced photos (the coarse relation's resolution, where its
  // prediction is within the integer search). Level 2: full resolution, from
  // the level-1 match and its local affine map.
  const double ra = a.reduce(), rb = b.reduce();
  const bool refine = ra < 1.0 || rb < 1.0;
  const cv::Size bs = b.size();
  // Candidates: a's interest points (full-resolution position) predicted inside b.
  std::vector<Eigen::Vector2d> candidates;
  std::vector<int> todo;
  for (const InterestPoint& ip : a.interest_points()) {
    if (static_cast<int>(candidates.size()) >= options.max_candidates) break;
    const Eigen::Vector2d xa = Scaled(ip.x, 1.0 / ra);
    const Eigen::Vector2d xb_h = Apply(rel.b_from_a, xa);
    if (!std::isfinite(xb_h.x()) || xb_h.x() < options.border || xb_h.y() < options.border ||
        xb_h.x() > bs.width - 1 - options.border || xb_h.y() > bs.height - 1 - options.border) {
      continue;
    }
    todo.push_back(static_cast<int>(candidates.size()));
    candidates.push_back(xa);
  }
  s.candidates = static_cast<int>(candidates.size());
  std::vector<std::string> status(candidates.size());
  std::vector<cv::Point2f> pa, pb;
  std::vector<PhotoTiePoint> found;
  // Pass 1 predicts from the coarse relation; pass 2 retries the failures
  // from the relation of pass 1's tie points (many, precise, spread over the
  // overlap: the relief between coarse matches is followed).
  for (int pass = 0; pass < 2 && !todo.empty(); ++pass) {
    // Each candidate is matched on its own (MatchCandidate reads only the
    // photos and the relation) into its own slot, in stripes on `threads`
    // threads; the slots are then taken in candidate order, so the result
    // does not depend on the threads.
    std::vector<WindowMatch> slots(todo.size());
    const int n = static_cast<int>(todo.size());
    cv::parallel_for_(
        cv::Range(0, n),
        [&](const cv::Range& range) {
          std::vector<std::pair<double, int>> scratch;
          for (int k = range.start; k < range.end; ++k)
            slots[k] = MatchCandidate(a, b, rel, candidates[todo[k]], refine, options, &scratch);
        },
        options.threads > 0 ? std::min(options.threads, n) : -1.0);
    std::vector<int> failed;
    for (int k = 0; k < n; ++k) {
      const int c = todo[k];
      status[c] = std::move(slots[k].status);
      if (!slots[k].matched) {
        if (status[c] != "outside_a") failed.push_back(c);
        continue;
      }
      const PhotoTiePoint& tp = slots[k].tie_point;
      found.push_back(tp);
      pa.emplace_back(static_cast<float>(tp.xa.x()), static_cast<float>(tp.xa.y()));
      pb.emplace_back(static_cast<float>(tp.xb.x()), static_cast<float>(tp.xb.y()));
    }
    todo.clear();
    if (pass == 0 && !failed.empty() &&
        static_cast<int>(found.size()) >= options.min_coarse_inliers) {
      std::vector<unsigned char> mask;
      const cv::Mat h = cv::findHomography(pa, pb, cv::RANSAC, options.coarse_ransac_threshold,
                                           mask, 4000, 0.999);
      if (h.empty()) break;
      CoarseRelation dense;
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) dense.b_from_a(r, c) = h.at<double>(r, c);
      for (size_t i = 0; i < found.size(); ++i) {
        if (!mask[i]) continue;
        dense.xa.push_back(found[i].xa);
        dense.residual.push_back(found[i].xb - Apply(dense.b_from_a, found[i].xa));
      }
      rel = std::move(dense);
      todo = std::move(failed);
    }
  }
  for (const std::string& st : status) {
    if (!st.empty()) ++s.rejects[st];
  }
  std::vector<unsigned char> inliers;
  EpipolarRms(pa, pb, options.screen_threshold, &inliers);
  if (inliers.size() == found.size()) {
    std::vector<cv::Point2f> qa, qb;
    for (size_t i = 0; i < found.size(); ++i) {
      if (inliers[i]) {
        result.tie_points.push_back(found[i]);
        qa.push_back(pa[i]);
        qb.push_back(pb[i]);
      } else {
        ++s.rejects["epipolar"];
      }
    }
    s.epipolar_rms = EpipolarRms(qa, qb, options.screen_threshold);
  } else {
    s.message = Message("only ", found.size(), " LSC matches: too few for a fundamental matrix");
  }
  s.matched = static_cast<int>(result.tie_points.size());
  s.seconds = SecondsSince(start);
  return result;
}

void PairSelectionOptions::Check() const {
  if (!(min_overlap > 0.0 && min_overlap <= 1.0))
    throw ConfigError("min_overlap must be in (0, 1]");
  if (!(height_above_ground > 0.0)) throw ConfigError("height_above_ground must be > 0");
}

PhotoFootprint NadirFootprint(const Eigen::Vector2d& east_north, bool has_heading,
                              double heading_deg, const cv::Size& image, double focal_mm,
                              double pixel_size_mm, const PairSelectionOptions& options) {
  options.Check();
  if (!(focal_mm > 0.0) || !(pixel_size_mm > 0.0)) {
    throw InvalidArgument(Message("NadirFootprint: focal length ", focal_mm, " mm and pixel size ",
                                  pixel_size_mm, " mm must be > 0"));
  }
  PhotoFootprint f;
  f.has_position = true;
  f.east_north = east_north;
  f.has_heading = has_heading;
  f.heading_deg = heading_deg;
  const double ground_pixel = pixel_size_mm / focal_mm * options.height_above_ground;  // [m]
  f.width = image.width * ground_pixel;
  f.length = image.height * ground_pixel;
  return f;
}

double FootprintOverlap(const PhotoFootprint& a, const PhotoFootprint& b) {
  // Without a heading: the disc inside the rectangle, as a 32-gon.
  auto polygon = [](const PhotoFootprint& f) {
    std::vector<cv::Point2f> p;
    if (f.has_heading) {
      const double h = f.heading_deg * M_PI / 180.0;
      const Eigen::Vector2d along(std::sin(h), std::cos(h)), across(std::cos(h), -std::sin(h));
      for (const auto& c : {Eigen::Vector2d(-1, -1), Eigen::Vector2d(1, -1), Eigen::Vector2d(1, 1),
                            Eigen::Vector2d(-1, 1)}) {
        const Eigen::Vector2d q =
            f.east_north + 0.5 * c.x() * f.width * across + 0.5 * c.y() * f.length * along;
        p.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
      }
    } else {
      const double r = 0.5 * std::min(f.width, f.length);
      for (int i = 0; i < 32; ++i) {
        const double t = 2.0 * M_PI * i / 32;
        p.emplace_back(static_cast<float>(f.east_north.x() + r * std::cos(t)),
                       static_cast<float>(f.east_north.y() + r * std::sin(t)));
      }
    }
    // Positive orientation for intersectConvexConvex.
    std::vector<cv::Point2f> hull;
    cv::convexHull(p, hull);
    return hull;
  };
  const std::vector<cv::Point2f> pa = polygon(a), pb = polygon(b);
  std::vector<cv::Point2f> inter;
  const float area = cv::intersectConvexConvex(pa, pb, inter, true);
  const double smaller = std::min(cv::contourArea(pa), cv::contourArea(pb));
  return area > 0 && smaller > 0 ? area / smaller : 0.0;
}

std::vector<std::pair<int, int>> SelectOverlappingPairs(const std::vector<PhotoFootprint>& photos,
                                                        const PairSelectionOptions& options) {
  options.Check();
  std::vector<std::pair<int, int>> pairs;
  for (size_t i = 0; i < photos.size(); ++i) {
    for (size_t j = i + 1; j < photos.size(); ++j) {
      const bool both = photos[i].has_position && photos[j].has_position;
      if (!both || FootprintOverlap(photos[i], photos[j]) >= options.min_overlap) {
        pairs.emplace_back(static_cast<int>(i), static_cast<int>(j));
      }
    }
  }
  return pairs;
}

}  // namespace matching
}  // namespace slope_monitor
