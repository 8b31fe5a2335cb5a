// Tie points of one moving camera's photos (a UAV flight), with no ROS in it:
// the hex_matcher nodelet (mode sequence) and the process_bag tool feed the
// same SequenceMatcher, so both give the same tie points.
//
// Input, in arrival order: images (AddImage) and position priors (AddPrior,
// e.g. the GNSS of the photo and the flight log's attitude). With priors,
// partners are chosen by predicted footprint overlap (sequence.h): the
// ground pixel size is measured by the epoch's matched pairs
// (GroundPixelFromTies; the median of a photo's pairs, carried to the next
// photo), the heading from the prior's attitude. Output: per image b, one
// SequencePair per partner image a (PlanSequencePairs, sequence.h), each with
// its tie points (track IDs: SequenceTrackId of the interest point of a), the
// number of pairs image b gets (pairs_b) and, for a pair without tie points,
// the reason. An image without partner gives one pair without image a.
//
// When an image is matched is decided by the messages, never by a clock:
//   * priors expected (SetPriorsExpected, default): an image is ready when a
//     prior within position_prior_max_dt of its stamp is in, or a prior later
//     than that has come (the priors moved past it: its own is not coming);
//     images are matched in arrival order;
//   * no priors expected: every image is ready when it comes;
//   * Poll(now) is the only place time counts: an image that waited
//     prior_wait (in the caller's clock, `now` given to AddImage) is matched
//     without its prior, and the log says which image it gave up on (live
//     sensors whose prior never comes). Finish() (end of the input) matches
//     what waits, with the priors that are in.
// A new epoch (flight) starts after a gap of more than max_gap between
// stamps, or when the stamps run backwards (a bag replayed again).
//
// Pair methods:
//   * kPhoto (default): the real-photo matcher (photo_pair_matcher.h):
//     PhotoFeatures computed once per photo and reused for every pair; any
//     rotation (strips flown both ways, turns), crab and scale change; when
//     it finds no relation (weak texture), the method below on the same
//     grey images (fallback_shift_hex);
//   * kGlobalShiftHex: the global shift (phase correlation, global_shift.h)
//     as the prior of the hexagonal matcher (hex_matcher.h); nadir photos
//     flown in one direction only (no rotation between the photos).
// Measured on the simulator's UAV surveys: doc/nodes/hex_matcher.md.
//
// Memory is bounded: a photo's features (or image) are released when no later
// image can pair with it (outside the last sequence_depth images and without
// a position prior, or at a new epoch), and the oldest are released when the
// epoch's photos exceed max_memory_mb or max_images (said in the log).
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "slope_monitor/core/matching/global_shift.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/matching/photo_pair_matcher.h"
#include "slope_monitor/core/matching/sequence.h"

namespace slope_monitor {
namespace matching {

enum class SequencePairMethod { kPhoto, kGlobalShiftHex };
const char* SequencePairMethodName(SequencePairMethod method);  // "photo", "shift_hex"
// Throws ConfigError naming the allowed names.
SequencePairMethod SequencePairMethodFromName(const std::string& name);

struct SequenceMatcherOptions {
  SequencePairMethod method = SequencePairMethod::kPhoto;
  double max_gap = 120.0;              // [s] gap between stamps that starts a new epoch, >= 0
  double position_prior_max_dt = 0.1;  // [s] a prior belongs to the image within this, >= 0
  double prior_wait = 2.0;             // [s] Poll: longest wait for an image's prior, >= 0
  int max_images = 300;                // photos of an epoch kept as partners, >= 1
  double max_memory_mb = 2048.0;       // [MB] their features (or images), > 0
  SequencePairOptions pairing;
  // kGlobalShiftHex: only the points of a that the shift puts this far inside
  // b are matched [px], >= 0.
  double border = 12.0;
  GlobalShiftOptions shift;
  // Interest points per image a: half the pair default (measured 0.90 s
  // instead of 1.23 s per 1280 x 960 pair with the same precision,
  // bench_hex_matcher_sequence).
  HexMatcherOptions hex = [] {
    HexMatcherOptions o;
    o.interest.max_points = 1000;
    return o;
  }();
  MatchPrior hex_prior;  // search radii, excluded areas; shift and within set per pair
  // kPhoto: features per photo, the block's (photo_pair_matcher.h: shared
  // with process_flight, so the graph ties a real flight as process_flight
  // does). Interest points spread over 8 x 8 cells: the 1000 strongest of a
  // real photo left 16 candidates (7 tie points) in the overlap of the
  // snowpeak turn pair, spread 149 (114). Until 29 Nov 2026 the sequence
  // had its own (1000 interest points, SIFT on a 640 px copy): half the tie
  // points of process_flight on the real caliterra flight.
  PhotoFeatureOptions photo = BlockPhotoFeatureOptions();
  PhotoPairOptions photo_pair;
  // kPhoto: a pair without a SIFT relation (weak texture: with OpenCV's
  // contrast threshold 0.04 the simulator's ground gave 7 consistent SIFT
  // matches where 12 are needed; with 0.01: 2 of 1083 pairs of the simulated
  // 150-photo block)
  // of photos of one size is matched by the global shift + hex matcher.
  // Only for a pair expected to overlap: planned by footprint, or both
  // footprints known and overlapping (an exhaustively planned pair without
  // a relation mostly does not overlap at all).
  bool fallback_shift_hex = true;
  // A pair with fewer tie points gives none (reason "too_few_tie_points"),
  // [0, 100000]: the block's rule (process_flight drops such pairs too).
  int min_pair_tie_points = kBlockMinPairTiePoints;
  // A photo's pairs are matched at once on this many threads (0: the
  // hardware's). Each pair is matched on its own and the results are kept in
  // the pairs' order, so the tie points do not depend on it.
  int threads = 0;     // [0, 64]
  void Check() const;  // throws ConfigError naming the field
};

// What a position prior says about a photo.
struct SequencePrior {
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // [m] site x, y
  // The camera's attitude (optical frame: x right, y down, z forward) when
  // the flight log gives one: the footprint's heading.
  std::optional<Eigen::Quaterniond> site_from_optical;
};

struct SequenceTie {
  std::uint64_t id = 0;                                  // SequenceTrackId
  Eigen::Vector2d xa = Eigen::Vector2d::Zero();          // [px] in a
  Eigen::Vector2d xb = Eigen::Vector2d::Zero();          // [px] in b
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2] of xb
  double correlation = 0.0;                              // LSC NCC
  double quality = 0.0;  // [0, 1]; <= kLowQuality: flagged by quality control
};

// One pair (a, b) of image b, or image b alone (has_a false: no partner).
struct SequencePair {
  std::uint32_t epoch = 0;   // from 1
  std::int64_t stamp_b = 0;  // [ns] as given to AddImage
  std::string frame_b;
  bool has_a = false;
  std::int64_t stamp_a = 0;  // [ns]
  std::string frame_a;
  std::uint32_t pairs_b = 1;  // pairs image b gets (>= 1)
  std::uint32_t index = 1;    // this one's number among them, from 1
  std::vector<SequenceTie> points;
  // "" when matched; else "no_relation" (kPhoto: no coarse relation),
  // "shift_unusable" (kGlobalShiftHex), "too_few_tie_points"
  // (min_pair_tie_points) or "error" (a bad image, named).
  std::string reason;
  std::string message;   // what happened (a line for the log)
  double seconds = 0.0;  // matching this pair (features of the photos not included)
  // Whether the photos were expected to share ground: false for a pair of a
  // small flight's all-with-all pairs whose footprints do not overlap (or
  // are not known yet), where no tie points are no failure.
  bool expected_to_overlap = true;
};

struct SequenceStep {
  std::vector<SequencePair> pairs;
  std::vector<std::string> log;  // epochs started, priors given up on, photos released
};

struct SequenceMatcherSummary {
  int images = 0;    // images matched (with or without partner)
  int unpaired = 0;  // of them, without partner
  int pairs = 0;     // pairs matched
  int tie_points = 0;
  std::map<std::string, int> failed_pairs;  // reason -> count
  int errors = 0;                           // bad images
  std::string last_error;
  int prior_timeouts = 0;  // images matched without their prior after prior_wait
  std::uint32_t epoch = 0;
  int images_in_memory = 0;
  std::size_t memory_bytes = 0, peak_memory_bytes = 0;
  int released = 0;           // photos released before the end of their epoch
  int footprint_planned = 0;  // images whose partners were chosen by footprint overlap
  double ground_pixel = 0.0;  // [m/px] the latest measured (GroundPixelFromTies), 0: none
  double feature_seconds = 0.0, pair_seconds = 0.0;  // totals
};

class SequenceMatcher {
 public:
  explicit SequenceMatcher(const SequenceMatcherOptions& options);  // checks them

  void SetPriorsExpected(bool expected) { priors_expected_ = expected; }
  // image: 8 or 16 bit, 1, 3 or 4 channels (BGR). A bad image (empty,
  // unsupported, another size than the epoch's images) gives its
  // pairs reason "error" with a message naming it; it is never a partner.
  // The image is copied (the caller's may be a view of a message).
  // now: the caller's clock [s] (Poll's time-out only).
  SequenceStep AddImage(std::int64_t stamp_ns, const std::string& frame_id, const cv::Mat& image,
                        double now = 0.0);
  // The camera's prior at stamp_ns; the second form: a position alone.
  SequenceStep AddPrior(std::int64_t stamp_ns, const SequencePrior& prior);
  SequenceStep AddPrior(std::int64_t stamp_ns, const Eigen::Vector2d& position) {
    return AddPrior(stamp_ns, SequencePrior{position, std::nullopt});
  }
  SequenceStep Poll(double now);
  SequenceStep Finish();

  const SequenceMatcherSummary& summary() const { return summary_; }
  const SequenceMatcherOptions& options() const { return options_; }

 private:
  struct Pending {
    std::int64_t stamp_ns;
    std::string frame_id;
    cv::Mat image;
    double received;
  };
  struct Earlier {
    SequenceImage info;
    std::int64_t stamp_ns = 0;
    std::string frame_id;
    cv::Mat image;                            // kGlobalShiftHex: grey
    std::shared_ptr<PhotoFeatures> features;  // kPhoto
    std::size_t bytes = 0;
    cv::Size size;
  };

  bool FrontReady() const;
  void ProcessFront(SequenceStep* step);
  void Drain(SequenceStep* step);
  std::optional<SequencePrior> TakePrior(double t);
  void MeasureGroundPixel(const std::vector<size_t>& plan, const std::vector<SequencePair>& pairs,
                          Earlier* b);
  // expected_to_overlap: the shift_hex fallback is tried (and the pair's
  // field of that name set).
  SequencePair MatchPair(const Earlier& a, const Earlier& b, bool expected_to_overlap) const;
  bool ExpectedToOverlap(const Earlier& a, const Earlier& b) const;
  void MatchPhotos(const Earlier& a, const Earlier& b, SequencePair* out) const;
  void MatchShiftHex(const cv::Mat& a, const cv::Mat& b, std::uint32_t serial_a,
                     SequencePair* out) const;
  void Keep(Earlier b, SequenceStep* step);
  void Release(std::size_t index);

  SequenceMatcherOptions options_;
  HexMatcher hex_;
  bool priors_expected_ = true;
  std::deque<Pending> pending_;
  std::deque<std::pair<double, SequencePrior>> priors_;  // stamp [s], prior
  double latest_prior_ = -1e300;
  std::vector<Earlier> history_;  // the epoch's partners, in time order
  std::uint32_t serial_ = 0;
  double last_stamp_ = 0.0;
  double ground_pixel_ = 0.0;  // [m/px] the latest measured in this epoch (0: none yet)
  int epoch_images_ = 0;       // images of this epoch so far
  SequenceMatcherSummary summary_;
};

}  // namespace matching
}  // namespace slope_monitor
