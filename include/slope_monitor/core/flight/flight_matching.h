// Tie points of a flight's photos, as multi-photo tracks.
//
// Pairs: every pair of photos up to exhaustive_max_photos photos (as COLMAP's
// exhaustive matcher); beyond that, pairs whose GNSS footprints overlap
// (matching::SelectOverlappingPairs with the flying height the photos give,
// or the options' when they give none) and, for photos without GNSS, each
// photo with the next sequence_window photos in name order. Each photo is
// decoded once (grey) and its features (matching::PhotoFeatures) are reused
// by all its pairs and released after its last pair; pairs are matched on
// `threads` threads, each into its own slot, so the result does not depend on
// the thread count.
//
// Tracks: the tie points of a pair (a, b) start at interest points of a
// (photo_pair_matcher.h); one interest point of a matched into several
// photos is one track, so a track has photo a and every photo it was
// matched into (>= 2 photos). Tracks are then joined through the photos they
// share: a track's observation in b within join_radius_px of the interest
// point another track starts at in b makes them one track (one observation
// per photo). A second set, joined within growth_join_radius, serves the
// orientation's growth only (FlightTies::growth_tracks).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/flight/flight_photos.h"
#include "slope_monitor/core/matching/photo_pair_matcher.h"

namespace slope_monitor {
namespace flight {

// Progress of a stage as work completes: ("features", photos done, photos),
// ("pairs", pairs done, pairs), ("oriented", photos oriented, photos). Called
// from one thread at a time.
using StageProgress = std::function<void(const char* stage, int done, int total)>;

struct FlightMatchingOptions {
  int exhaustive_max_photos = matching::kBlockExhaustiveMaxPhotos;  // all pairs up to it, >= 2
  int sequence_window = 8;  // photos without GNSS: each with the next N by name, >= 1
  // Beyond exhaustive_max_photos, with GNSS: footprint overlap; the flying
  // height above ground is taken from the photos' XMP relative altitude when
  // they have one, else footprint.height_above_ground.
  matching::PairSelectionOptions footprint;
  // Features per photo (photo_pair_matcher.h: the block's, shared with the
  // graph's sequence matcher).
  matching::PhotoFeatureOptions features = matching::BlockPhotoFeatureOptions();
  matching::PhotoPairOptions pair = [] {
    matching::PhotoPairOptions o;
    o.threads = 1;  // pairs run in parallel instead
    return o;
  }();
  int min_pair_tie_points = matching::kBlockMinPairTiePoints;  // a pair with fewer: not used, >= 5
  // [px] tracks are joined where one's observation in photo b lies this
  // close to the interest point another starts at in b (0: not joined), >= 0.
  double join_radius_px = 1.0;
  // [px of the reduced copy, features.coarse_max_side] the tracks are also
  // joined within this of the interest point another starts at, for the
  // orientation's growth only (FlightTies::growth_tracks): a ground point
  // seen from several strips then joins their photos, while the adjustment
  // keeps the unjoined tracks (each an interest point and its LSC matches,
  // so no track mixes two nearby points). Interest points are placed to
  // about half a pixel of that copy: at 1 full-resolution px a 50-photo
  // part of a real fixed-wing flight (3600 x 2700, copy 1200) oriented 5
  // photos, at 2 px (2/3 of the copy's pixel) 41. 0: not joined, >= 0.
  double growth_join_radius = 2.0 / 3.0;
  int threads = 0;     // pairs matched at once (0: the hardware's), [0, 64]
  void Check() const;  // throws ConfigError naming the field
};

struct FlightTrack {
  std::vector<std::pair<int, Eigen::Vector2d>> observations;  // (photo index, pixel), photo a first
  std::uint8_t grey = 128;                                    // photo a's grey value at the point
};

struct FlightPairStats {
  int a = 0, b = 0;
  int tie_points = 0;
  double epipolar_rms = 0.0;
  std::string message;  // why none ("" when tied)
};

struct FlightTies {
  std::vector<FlightTrack> tracks;
  // The tracks joined at growth_join_radius (the orientation's growth; empty:
  // it grows on `tracks`).
  std::vector<FlightTrack> growth_tracks;
  std::vector<FlightPairStats> pairs;   // every pair tried, in order
  int pairs_tied = 0;                   // with >= min_pair_tie_points
  long tie_points = 0;                  // pairwise tie points kept
  std::vector<std::string> unreadable;  // "<photo>: <reason>" photos that could not be decoded
  double feature_seconds = 0.0, pair_seconds = 0.0;  // CPU time summed over threads
  double wall_seconds = 0.0;
  std::size_t peak_feature_bytes = 0;
};

// The pairs to try (i < j, indices into photos.photos).
std::vector<std::pair<int, int>> PlanFlightPairs(const FlightPhotos& photos,
                                                 const FlightMatchingOptions& options);

// Joins tracks through the photos they share (observations[0] of a track is
// the interest point it starts at): an observation (b, xb) of one track
// within radius_px of the point another track starts at in b makes them one
// track. A joined track keeps one observation per photo (the first, in track
// order). Returns, per joined track, where each of its observations came
// from: (index of the track given, index of its observation).
std::vector<std::vector<std::pair<int, int>>> JoinTracks(double radius_px,
                                                         std::vector<FlightTrack>* tracks);

// [full-resolution px] the growth's join radius for photos of this size:
// options.growth_join_radius pixels of the reduced copy.
double GrowthJoinRadiusPx(const FlightMatchingOptions& options, int width, int height);

// Decodes the photos, matches the planned pairs and builds the tracks.
FlightTies MatchFlight(const FlightPhotos& photos, const FlightMatchingOptions& options,
                       const StageProgress& progress = {});

}  // namespace flight
}  // namespace slope_monitor
