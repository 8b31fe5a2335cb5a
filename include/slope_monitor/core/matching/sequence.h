// Tie points between the photos of one moving camera (UAV flight): which
// earlier photos a new photo is matched with, and the track IDs that make the
// same interest point of an earlier photo one multi-ray tie point.
//
// Pairs for a new image b (PlanSequencePairs):
//   * b has a position prior and at least one earlier image has one: every
//     earlier image with a prior whose horizontal distance to b's is
//     <= max_pair_distance, nearest first (equal distances: the later image
//     first), at most max_pairs_per_image of them. Neighbouring parallel
//     strips are tied too, not only the previous photos of the strip;
//   * otherwise the previous `sequence_depth` images, latest first.
// Track IDs (SequenceTrackId): (serial of image a, from 1) << 32 | (row *
// width + col) of the rounded interest point xa. Interest points are
// detected on the whole image a, so the same point of a carries the same ID
// in every pair with a as image a; IDs of different images never collide and
// are never 0.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace matching {

struct SequencePairOptions {
  double max_pair_distance = 30.0;  // [m] horizontal distance of the position priors, > 0
  int max_pairs_per_image = 4;      // [1, 100]
  int sequence_depth = 2;           // previous images without priors, [1, 100]
  void Check() const;               // throws ConfigError naming the field
};

struct SequenceImage {
  std::uint32_t serial = 0;  // order of arrival within the run, from 1
  double stamp = 0.0;        // [s]
  bool has_position = false;
  Eigen::Vector2d position = Eigen::Vector2d::Zero();  // [m] horizontal prior (site x, y)
};

// Indices into `earlier` (the epoch's earlier images, in time order) of
// image b's partners, in the order they are to be matched.
std::vector<size_t> PlanSequencePairs(const std::vector<SequenceImage>& earlier,
                                      const SequenceImage& b, const SequencePairOptions& options);

// Track ID of interest point xa [px] of image a (serial >= 1) of width
// `width` [px]; throws InvalidArgument for serial 0 or xa outside 2^32 pixels.
std::uint64_t SequenceTrackId(std::uint32_t serial_a, const Eigen::Vector2d& xa, int width);

}  // namespace matching
}  // namespace slope_monitor
