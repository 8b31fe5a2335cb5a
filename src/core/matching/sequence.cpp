#include "slope_monitor/core/matching/sequence.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace matching {

void SequencePairOptions::Check() const {
  if (!(max_pair_distance > 0.0) || !std::isfinite(max_pair_distance)) {
    throw ConfigError(
        Message("SequencePairOptions.max_pair_distance must be > 0 m, got ", max_pair_distance));
  }
  if (max_pairs_per_image < 1 || max_pairs_per_image > 100) {
    throw ConfigError(Message("SequencePairOptions.max_pairs_per_image must be in [1, 100], got ",
                              max_pairs_per_image));
  }
  if (sequence_depth < 1 || sequence_depth > 100) {
    throw ConfigError(
        Message("SequencePairOptions.sequence_depth must be in [1, 100], got ", sequence_depth));
  }
}

std::vector<size_t> PlanSequencePairs(const std::vector<SequenceImage>& earlier,
                                      const SequenceImage& b, const SequencePairOptions& options) {
  options.Check();
  std::vector<size_t> out;
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
    std::sort(c.begin(), c.end());
    for (size_t k = 0; k < c.size() && static_cast<int>(k) < options.max_pairs_per_image; ++k) {
      out.push_back(std::get<2>(c[k]));
    }
    return out;
  }
  for (size_t k = 0; k < earlier.size() && static_cast<int>(k) < options.sequence_depth; ++k) {
    out.push_back(earlier.size() - 1 - k);
  }
  return out;
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

}  // namespace matching
}  // namespace slope_monitor
