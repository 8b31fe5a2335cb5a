#include "slope_monitor/core/matching/sequence.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include <Eigen/Geometry>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace matching {

void SequencePairOptions::Check() const {
  if (!(min_overlap > 0.0 && min_overlap <= 1.0)) {
    throw ConfigError(
        Message("SequencePairOptions.min_overlap must be in (0, 1], got ", min_overlap));
  }
  if (!(max_pair_distance > 0.0) || !std::isfinite(max_pair_distance)) {
    throw ConfigError(
        Message("SequencePairOptions.max_pair_distance must be > 0 m, got ", max_pair_distance));
  }
  if (max_pairs_per_image < 1 || max_pairs_per_image > 100) {
    throw ConfigError(Message("SequencePairOptions.max_pairs_per_image must be in [1, 100], got ",
                              max_pairs_per_image));
  }
  if (!(exhaustive_footprint_scale == 0.0 ||
        (exhaustive_footprint_scale >= 1.0 && exhaustive_footprint_scale <= 100.0))) {
    throw ConfigError(
        Message("SequencePairOptions.exhaustive_footprint_scale must be 0 or in [1, 100], got ",
                exhaustive_footprint_scale));
  }
  if (exhaustive_max_photos < 0 || exhaustive_max_photos > 1000) {
    throw ConfigError(
        Message("SequencePairOptions.exhaustive_max_photos must be in [0, 1000], got ",
                exhaustive_max_photos));
  }
  if (sequence_depth < 1 || sequence_depth > 100) {
    throw ConfigError(
        Message("SequencePairOptions.sequence_depth must be in [1, 100], got ", sequence_depth));
  }
}

PhotoFootprint FootprintOf(const SequenceImage& image) {
  PhotoFootprint f;
  f.has_position =
      image.has_position && image.ground_pixel > 0.0 && image.width > 0 && image.height > 0;
  if (!f.has_position) return f;
  f.east_north = image.position;
  f.has_heading = image.has_heading;
  f.heading_deg = image.heading_deg;
  f.width = image.width * image.ground_pixel;
  f.length = image.height * image.ground_pixel;
  return f;
}

bool PlansByFootprint(const std::vector<SequenceImage>& earlier, const SequenceImage& b) {
  return FootprintOf(b).has_position &&
         std::any_of(earlier.begin(), earlier.end(),
                     [](const SequenceImage& s) { return FootprintOf(s).has_position; });
}

bool PlansExhaustively(int epoch_images, const SequencePairOptions& options) {
  return epoch_images <= options.exhaustive_max_photos;
}

std::vector<size_t> PlanSequencePairs(const std::vector<SequenceImage>& earlier,
                                      const SequenceImage& b, const SequencePairOptions& options,
                                      int epoch_images) {
  options.Check();
  if (epoch_images <= 0) epoch_images = static_cast<int>(earlier.size()) + 1;
  if (PlansExhaustively(epoch_images, options)) {
    const double scale = options.exhaustive_footprint_scale;
    const auto scaled = [scale](PhotoFootprint f) {
      f.width *= scale;
      f.length *= scale;
      return f;
    };
    const PhotoFootprint fb = scaled(FootprintOf(b));
    std::vector<size_t> all;
    for (size_t k = earlier.size(); k-- > 0;) {  // latest first
      const PhotoFootprint fa = scaled(FootprintOf(earlier[k]));
      if (scale > 0.0 && fa.has_position && fb.has_position && FootprintOverlap(fa, fb) <= 0.0)
        continue;
      all.push_back(k);
    }
    return all;
  }
  // The first max_pairs_per_image of (key, -stamp, index), smallest key first.
  const auto take = [&](std::vector<std::tuple<double, double, size_t>>* c) {
    std::sort(c->begin(), c->end());
    std::vector<size_t> out;
    for (size_t k = 0; k < c->size() && static_cast<int>(k) < options.max_pairs_per_image; ++k)
      out.push_back(std::get<2>((*c)[k]));
    return out;
  };
  if (PlansByFootprint(earlier, b)) {
    const PhotoFootprint fb = FootprintOf(b);
    std::vector<std::tuple<double, double, size_t>> c;  // -overlap, -stamp, index
    for (size_t i = 0; i < earlier.size(); ++i) {
      const PhotoFootprint fa = FootprintOf(earlier[i]);
      if (!fa.has_position) continue;
      const double overlap = FootprintOverlap(fa, fb);
      if (overlap >= options.min_overlap) c.emplace_back(-overlap, -earlier[i].stamp, i);
    }
    return take(&c);
  }
  const bool any_prior =
      b.has_position && std::any_of(earlier.begin(), earlier.end(),
                                    [](const SequenceImage& s) { return s.has_position; });
  if (any_prior) {
    std::vector<std::tuple<double, double, size_t>> c;  // distance, -stamp, index
    for (size_t i = 0; i < earlier.size(); ++i) {
      if (!earlier[i].has_position) continue;
      const double d = (earlier[i].position - b.position).norm();
      if (d <= options.max_pair_distance) c.emplace_back(d, -earlier[i].stamp, i);
    }
    return take(&c);
  }
  std::vector<size_t> out;
  for (size_t k = 0; k < earlier.size() && static_cast<int>(k) < options.sequence_depth; ++k) {
    out.push_back(earlier.size() - 1 - k);
  }
  return out;
}

double GroundPixelFromTies(const std::vector<Eigen::Vector2d>& xa,
                           const std::vector<Eigen::Vector2d>& xb, const Eigen::Vector2d& centre_a,
                           const Eigen::Vector2d& centre_b, double baseline) {
  const size_t n = std::min(xa.size(), xb.size());
  if (n < 8 || !(baseline >= 1.0)) return 0.0;
  // Dynamic sizes: GCC 12 warns (a false -Wstringop-overread) inside
  // Eigen's umeyama for a fixed 2 x N input.
  Eigen::MatrixXd a(2, n), b(2, n);
  for (size_t k = 0; k < n; ++k) {
    a.col(k) = xa[k];
    b.col(k) = xb[k];
  }
  const Eigen::Matrix3d b_from_a = Eigen::umeyama(a, b, true);
  const Eigen::Vector2d p =
      b_from_a.topLeftCorner<2, 2>() * centre_a + b_from_a.topRightCorner<2, 1>();
  const double d = (p - centre_b).norm();
  return std::isfinite(d) && d >= 10.0 ? baseline / d : 0.0;
}

std::uint64_t SequenceTrackId(std::uint32_t serial_a, const Eigen::Vector2d& xa, int width) {
  if (serial_a == 0) throw InvalidArgument("SequenceTrackId: image serial must be >= 1");
  const long long col = std::llround(xa.x()), row = std::llround(xa.y());
  const long long index = row * width + col;
  if (width <= 0 || col < 0 || row < 0 || col >= width || index >= (1LL << 32)) {
    throw InvalidArgument(Message("SequenceTrackId: pixel (", xa.x(), ", ", xa.y(),
                                  ") outside an image of width ", width, " or beyond 2^32 pixels"));
  }
  return (static_cast<std::uint64_t>(serial_a) << 32) | static_cast<std::uint64_t>(index);
}

bool SequenceTrackStartsAt(std::uint64_t id, const Eigen::Vector2d& x, int width) {
  const long long col = std::llround(x.x()), row = std::llround(x.y());
  if (width <= 0 || col < 0 || row < 0 || col >= width) return false;
  return static_cast<std::uint64_t>(row * width + col) == (id & 0xffffffffULL);
}

}  // namespace matching
}  // namespace slope_monitor
