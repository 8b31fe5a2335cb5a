// Targetless matching of two images on hexagonal pyramids, refined by
// (modified) least-squares correlation.
//
// For every interest point xa of image a (MLSC rule, interest_points.h):
//   1. predicted position in b: xa + prior shift (MatchPrior), search radius
//      `radius` (or `moving_radius` where prior.moving(xa) is true);
//   2. on the coarsest pyramid level, every hex cell of b within the radius
//      (and, with an epipolar prior, within epipolar_band of the epipolar
//      line) is scored by the correlation of the six-profile descriptors
//      (hex_raster.h); the best must score >= min_score (else kLowScore) and
//      pass the ratio test d_best / d_second <= max_ratio with
//      d = sqrt(2 - 2 score), the second best taken more than two cells away
//      (else kAmbiguous);
//   3. the position is refined level by level (best cell within two cells);
//   4. mutual consistency: the same search from the found point back into a
//      must return within mutual_tolerance px of xa (else kNotMutual);
//   5. MLSC (lsc.h, integer correlation within +-lsc_search_radius, then LSC)
//      gives the sub-pixel position and its covariance (else the LSC status
//      is the reject reason);
//   6. with an epipolar prior the final point must lie within epipolar_band
//      of the line (else kEpipolar).
//   7. quality control (HexMatcherOptions::quality) of the match a crew
//      cannot trust, typically on occluding objects (swaying foliage, a
//      window straddling a silhouette): flags set when
//        kFlagLowCorrelation  LSC NCC < quality.min_correlation;
//        kFlagHighResidual    LSC residual sigma0 > quality.max_residual_ratio
//                             x the median sigma0 of all matches of the pair
//                             (the pair's noise level);
//        kFlagTwoWay          LSC back from xb into a (window of b, start xa)
//                             lands more than quality.max_two_way px from xa
//                             (or fails): the window is not the same surface
//                             in both images;
//        kFlagNeighbours      the displacement xb - xa differs by more than
//                             quality.max_neighbour_deviation px from the
//                             median of the matches within
//                             quality.neighbour_radius px (>= 3 of them).
//        kFlagExcluded        xa inside MatchPrior::excluded (the operator's
//                             outline of known obstacles), when given.
//      A flagged match is low quality: HexMatch::quality <= kLowQuality
//      (0.25 x its normal value; normal matches have quality >= 0.42 with
//      min_score 0.6 and lsc min_correlation 0.7), or it is dropped
//      (quality.reject, reason "low_quality").
// Epochs: with MatchPrior::estimate_global_shift the stable points (not
// prior.moving) are matched first, the median of their displacements
// becomes the global shift, and then all points are matched around it
// (stable: `radius`; moving areas: `moving_radius`).
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/matching/hex_raster.h"
#include "slope_monitor/core/matching/interest_points.h"
#include "slope_monitor/core/matching/lsc.h"

namespace slope_monitor {
namespace matching {

struct HexMatcherOptions {
  int pyramid_levels = 3;  // [1, 6]
  HexSampling sampling = HexSampling::kNearest;
  int profile_length = 4;         // [cells] per profile, [1, 16]
  double min_score = 0.6;         // [-1, 1] descriptor correlation
  double max_ratio = 0.85;        // (0, 1]
  double mutual_tolerance = 2.0;  // [px] > 0
  int lsc_search_radius = 3;      // [px] MLSC integer search, [0, 20]
  // [px] Gaussian low-pass of both images before LSC, [0, 5]; 0 = none. For
  // weak texture whose gradient is comparable to the noise (the simulator's
  // ground: 2.4 DN/px vs 2.7 DN noise), 1 px.
  double lsc_prefilter_sigma = 0.0;
  struct Quality {
    bool enabled = true;
    double min_correlation = 0.8;          // [-1, 1] LSC NCC
    double max_residual_ratio = 2.0;       // [-] sigma0 / median sigma0 of the pair, > 1
    double max_two_way = 0.5;              // [px] > 0, back-matching error; checked when two_way
    bool two_way = true;                   // run the b -> a LSC check (about doubles the LSC time)
    double neighbour_radius = 40.0;        // [px] > 0
    double max_neighbour_deviation = 1.5;  // [px] > 0
    bool reject = false;                   // drop flagged matches instead of marking them
  } quality;
  InterestPointOptions interest;  // interest points in image a
  LscOptions lsc;                 // refinement (search_radius set from lsc_search_radius)
  void Check() const;             // throws ConfigError naming the field
};

// Where to look for xa's match in b.
struct MatchPrior {
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();     // [px] predicted xb - xa
  double radius = 24.0;                                // [px] search radius around xa + shift, > 0
  std::function<bool(const Eigen::Vector2d&)> moving;  // true where the ground may move (optional)
  // The operator's outline of known non-ground objects in image a (trees,
  // boulders, structures; optional): matches whose xa lies there are flagged
  // kFlagExcluded (low quality). Rigid, static objects match perfectly well
  // and no image-based test can tell them from the ground.
  std::function<bool(const Eigen::Vector2d&)> excluded;
  double moving_radius = 48.0;  // [px] search radius there
  // Only the interest points xa with within(xa) true are matched (optional;
  // e.g. the part of a that the global shift puts inside b). The points are
  // still detected on the whole image a (same points, same positions for
  // every b); the others are not counted as candidates.
  std::function<bool(const Eigen::Vector2d&)> within;
  bool estimate_global_shift = false;  // first match stable points, take their median shift
  bool has_epipolar = false;
  Eigen::Matrix3d fundamental = Eigen::Matrix3d::Zero();  // xb^T F xa = 0 (homogeneous pixels)
  double epipolar_band = 2.0;                             // [px] > 0
};

// Fundamental matrix from approximate orientations (pinhole part of the
// camera models; distortion is left to the epipolar band).
Eigen::Matrix3d FundamentalFromOrientation(const camera::CameraModel& camera_a,
                                           const camera::ExteriorOrientation& pose_a,
                                           const camera::CameraModel& camera_b,
                                           const camera::ExteriorOrientation& pose_b);
// Distance [px] of xb from the epipolar line F xa.
double EpipolarDistance(const Eigen::Matrix3d& f, const Eigen::Vector2d& xa,
                        const Eigen::Vector2d& xb);

enum class RejectReason {
  kNone,
  kNoDescriptor,  // descriptor of xa not available (border, flat)
  kLowScore,
  kAmbiguous,
  kNotMutual,
  kLsc,  // LSC failed; see lsc_status
  kEpipolar,
};
const char* RejectReasonName(RejectReason reason);

// HexMatch::flags bits (quality control, step 7).
constexpr unsigned kFlagLowCorrelation = 1u;
constexpr unsigned kFlagHighResidual = 2u;
constexpr unsigned kFlagTwoWay = 4u;
constexpr unsigned kFlagNeighbours = 8u;
constexpr unsigned kFlagExcluded = 16u;  // inside MatchPrior::excluded
// Flagged matches have quality <= kLowQuality; unflagged ones more.
constexpr double kLowQuality = 0.25;
// "low_correlation+two_way" etc.; "" for 0.
std::string QualityFlagNames(unsigned flags);

struct HexMatch {
  Eigen::Vector2d xa = Eigen::Vector2d::Zero();          // [px]
  Eigen::Vector2d xb = Eigen::Vector2d::Zero();          // [px]
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2] of xb
  double score = 0.0;                                    // descriptor correlation (coarsest level)
  double correlation = 0.0;                              // LSC NCC at the solution
  double quality = 0.0;                                  // [0, 1]; <= kLowQuality when flagged
  double sigma0 = 0.0;                                   // [grey] LSC residual RMS
  double two_way_error =
      0.0;             // [px] back-matching error (-1 when the back LSC failed; 0 when not run)
  unsigned flags = 0;  // kFlag* (0 = normal quality)
  bool IsLowQuality() const { return flags != 0; }
};

struct HexMatchSummary {
  int candidates = 0;
  int matched = 0;
  std::map<std::string, int> rejects;  // reason name -> count (LSC: "lsc_<status>")
  int low_quality = 0;  // matches flagged by quality control (kept when !quality.reject)
  std::map<std::string, int> flags;  // flag name -> count of matches carrying it
  Eigen::Vector2d global_shift = Eigen::Vector2d::Zero();  // [px] used for the final pass
  double seconds = 0.0;
  bool IsSolutionUsable() const { return matched > 0; }
};

struct HexMatchResult {
  std::vector<HexMatch> matches;
  HexMatchSummary summary;
};

class HexMatcher {
 public:
  explicit HexMatcher(const HexMatcherOptions& options);
  // Throws InvalidArgument when the images are empty, multi-channel, of
  // different sizes or different depths (naming both). Textureless images
  // give no matches (kNoDescriptor / LSC textureless rejects).
  HexMatchResult Match(const cv::Mat& image_a, const cv::Mat& image_b,
                       const MatchPrior& prior) const;

 private:
  HexMatcherOptions options_;
};

}  // namespace matching
}  // namespace slope_monitor
