// Tie points between the photos of one moving camera (UAV flight): which
// earlier photos a new photo is matched with, and the track IDs that make the
// same interest point of an earlier photo one multi-ray tie point.
//
// Pairs for a new image b (PlanSequencePairs):
//   * while the epoch has at most exhaustive_max_photos images (b included):
//     every earlier image, latest first (process_flight's rule for a
//     flight of that size, flight_matching.h: the same pairs), but for those
//     whose footprint does not touch b's at exhaustive_footprint_scale
//     times their size (both footprints known);
//   * b and earlier images have a ground footprint (a position prior and a
//     ground pixel size; a heading from the prior's attitude, else the disc
//     inside the rectangle): the earlier images whose footprint overlaps b's
//     by at least min_overlap of the smaller one (FootprintOverlap,
//     photo_pair_matcher.h), largest overlap first (equal: the later image
//     first), at most max_pairs_per_image. Photos along the strip, of the
//     neighbouring strips and across turns are tied, in the order of how
//     much they share, whatever the distance;
//   * else b has a position prior and at least one earlier image has one:
//     every earlier image with a prior whose horizontal distance to b's is
//     <= max_pair_distance, nearest first (equal distances: the later image
//     first), at most max_pairs_per_image of them;
//   * otherwise the previous `sequence_depth` images, latest first.
// The ground pixel size is measured by the flight itself
// (GroundPixelFromTies): the GNSS baseline of a matched pair over the image
// distance between b's centre and where a's centre falls in b, so neither
// the flying height nor the terrain need to be known.
// Track IDs (SequenceTrackId): (serial of image a, from 1) << 32 | (row *
// width + col) of the rounded interest point xa. Interest points are
// detected on the whole image a, so the same point of a carries the same ID
// in every pair with a as image a; IDs of different images never collide and
// are never 0.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/matching/photo_pair_matcher.h"

namespace slope_monitor {
namespace matching {

struct SequencePairOptions {
  // [-] (0, 1]: predicted footprint overlap a pair needs. On the simulated
  // blocks (config/sim/uav_block_*) photos three apart on a strip share
  // 10 % and failed after every method (doc/uav_block_scaling.md).
  double min_overlap = 0.2;
  // [m] > 0: without footprints, horizontal distance of the position priors.
  double max_pair_distance = 30.0;
  int max_pairs_per_image = 4;  // [1, 100]
  int sequence_depth = 2;       // previous images without priors, [1, 100]
  // Every earlier image is a partner while the epoch has at most this many
  // images (photo_pair_matcher.h: the block's rule), [0, 1000]; 0: never.
  int exhaustive_max_photos = kBlockExhaustiveMaxPhotos;
  // ... but for an image whose footprint and b's, each scaled by this
  // factor about its centre, do not overlap at all (such a pair shares no
  // ground: process_flight tries it and gets no tie points), [1, 100]; 0:
  // every one. The sequence cannot know whether a flight stays within
  // exhaustive_max_photos: without this a 150-photo flight pairs its first
  // 60 photos all with all (1770 pairs). At 2 the simulated 150-photo block
  // still tries 1196 pairs in its first epoch (542 with the footprint rule
  // alone); at 1 or 1.5 the real caliterra flight lost a pair of 260 tie
  // points (the predicted footprints are rough: GNSS, a ground pixel size
  // measured by the first pairs), at 2 it keeps all of process_flight's.
  double exhaustive_footprint_scale = 2.0;
  void Check() const;  // throws ConfigError naming the field
};

struct SequenceImage {
  std::uint32_t serial = 0;  // order of arrival within the run, from 1
  double stamp = 0.0;        // [s]
  bool has_position = false;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // [m] horizontal prior (site x, y)
  // Where the image's top points on the ground [deg, clockwise from site
  // north = +y], from the prior's attitude.
  bool has_heading = false;
  double heading_deg = 0.0;
  int width = 0, height = 0;  // [px]
  double ground_pixel = 0.0;  // [m/px] > 0: the footprint is known
};

// The footprint (position, heading, size x ground pixel);
// has_position false without a position or ground pixel size.
PhotoFootprint FootprintOf(const SequenceImage& image);

// Whether PlanSequencePairs chooses b's partners by footprint overlap: b and
// at least one earlier image have a footprint.
bool PlansByFootprint(const std::vector<SequenceImage>& earlier, const SequenceImage& b);

// Indices into `earlier` (the epoch's earlier images kept as partners, in
// time order) of image b's partners, in the order they are to be matched.
// epoch_images: the epoch's images so far, b included (0: earlier.size() + 1).
std::vector<size_t> PlanSequencePairs(const std::vector<SequenceImage>& earlier,
                                      const SequenceImage& b, const SequencePairOptions& options,
                                      int epoch_images = 0);
// Whether the epoch's images so far (b included) are all paired.
bool PlansExhaustively(int epoch_images, const SequencePairOptions& options);

// Ground pixel size [m/px] of image b from its tie points with image a
// (xa -> xb) and the horizontal GNSS baseline [m] of the pair: a similarity
// b_from_a of the tie points (least squares, Eigen::umeyama) puts a's centre
// at p in b; for nadir photos p is `baseline` metres from b's centre on the
// ground. 0 when it cannot be told: fewer than 8 tie points, a baseline under
// 1 m or p less than 10 px from b's centre.
double GroundPixelFromTies(const std::vector<Eigen::Vector2d>& xa,
                           const std::vector<Eigen::Vector2d>& xb, const Eigen::Vector2d& centre_a,
                           const Eigen::Vector2d& centre_b, double baseline);

// Track ID of interest point xa [px] of image a (serial >= 1) of width
// `width` [px]; throws InvalidArgument for serial 0 or xa outside 2^32 pixels.
std::uint64_t SequenceTrackId(std::uint32_t serial_a, const Eigen::Vector2d& xa, int width);
// Whether x (rounded) is the interest point track `id` starts at, in an
// image `width` px wide: the pixel part of SequenceTrackId read back.
bool SequenceTrackStartsAt(std::uint64_t id, const Eigen::Vector2d& x, int width);

}  // namespace matching
}  // namespace slope_monitor
