#include "slope_monitor/core/flight/flight_matching.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <optional>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_file.h"

namespace slope_monitor {
namespace flight {
namespace {

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Footprints of the photos with GNSS (east/north in a tangent plane at the first).
std::vector<matching::PhotoFootprint> Footprints(const FlightPhotos& photos,
                                                 const matching::PairSelectionOptions& selection) {
  std::vector<matching::PhotoFootprint> out(photos.photos.size());
  std::optional<capture::LocalTangentPlane> ltp;
  for (size_t i = 0; i < photos.photos.size(); ++i) {
    const FlightPhoto& p = photos.photos[i];
    if (!p.exif.has_gps) continue;
    const capture::Geodetic g{p.exif.gps.latitude_deg, p.exif.gps.longitude_deg, 0.0};
    if (!ltp) ltp.emplace(g);
    // The photo's own flying height where its XMP says it (above the take-off
    // point: on a slope the ground under the photo may lie lower or higher).
    matching::PairSelectionOptions own = selection;
    if (p.attitude.has_height_above_ground && p.attitude.height_above_ground_m > 1.0)
      own.height_above_ground = p.attitude.height_above_ground_m;
    out[i] = matching::NadirFootprint(ltp->ToSite(g).head<2>(), p.attitude.has_yaw,
                                      p.attitude.yaw_deg, cv::Size(p.width, p.height),
                                      p.exif.focal_length_mm, p.attitude.pixel_size_mm, own);
  }
  return out;
}

// Grey value of a photo at a pixel (nearest).
std::uint8_t GreyAt(const cv::Mat& grey, const Eigen::Vector2d& px) {
  const int c = std::clamp(static_cast<int>(std::lround(px.x())), 0, grey.cols - 1);
  const int r = std::clamp(static_cast<int>(std::lround(px.y())), 0, grey.rows - 1);
  return grey.at<std::uint8_t>(r, c);
}

// Photos' features, computed at first use and released after the last pair
// that uses them. Thread-safe.
class FeatureCache {
 public:
  FeatureCache(const FlightPhotos& photos, const FlightMatchingOptions& options,
               std::vector<int> uses)
      : photos_(photos), options_(options), uses_(std::move(uses)), slots_(photos.photos.size()) {}

  // nullptr when the photo cannot be decoded (named in unreadable()).
  std::shared_ptr<const matching::PhotoFeatures> Get(int i) {
    Slot& s = slots_[i];
    std::call_once(s.once, [&] { Compute(i); });
    return s.features;
  }
  void Done(int i) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (--uses_[i] == 0 && slots_[i].features) {
      bytes_ -= slots_[i].features->MemoryBytes();
      slots_[i].features.reset();
    }
  }
  double seconds() const { return seconds_; }
  int computed() {
    std::lock_guard<std::mutex> lock(mutex_);
    return computed_;
  }
  std::size_t peak_bytes() const { return peak_; }
  std::vector<std::string> unreadable() const { return unreadable_; }

 private:
  struct Slot {
    std::once_flag once;
    std::shared_ptr<const matching::PhotoFeatures> features;
  };
  void Compute(int i) {
    const FlightPhoto& p = photos_.photos[i];
    cv::Mat image;
    std::string why;
    try {
      image = io::ReadImageChecked(p.path, cv::IMREAD_GRAYSCALE, photos_.options.image);
      if (image.cols != p.width || image.rows != p.height)
        why = Message("decodes to ", image.cols, "x", image.rows, " where its header says ",
                      p.width, "x", p.height);
    } catch (const std::exception& e) {
      why = e.what();
    }
    std::shared_ptr<const matching::PhotoFeatures> f;
    if (why.empty())
      f = std::make_shared<matching::PhotoFeatures>(image, p.name, options_.features);
    std::lock_guard<std::mutex> lock(mutex_);
    ++computed_;
    if (!why.empty()) {
      unreadable_.push_back(Message(p.path, ": ", why));
      return;
    }
    slots_[i].features = f;
    seconds_ += f->seconds();
    bytes_ += f->MemoryBytes();
    peak_ = std::max(peak_, bytes_);
  }

  const FlightPhotos& photos_;
  const FlightMatchingOptions& options_;
  std::vector<int> uses_;
  std::vector<Slot> slots_;
  std::mutex mutex_;
  double seconds_ = 0.0;
  int computed_ = 0;  // photos decoded (or found unreadable)
  std::size_t bytes_ = 0, peak_ = 0;
  std::vector<std::string> unreadable_;
};

// Tracks from the pairs' tie points: an interest point of photo a (its
// pixel, identical in every pair of a) is one track.
void BuildTracks(const std::vector<std::pair<int, int>>& pairs,
                 const std::vector<matching::PhotoPairResult>& results,
                 const std::vector<std::uint8_t>& used,
                 const std::vector<std::vector<std::uint8_t>>& grey_of, FlightTies* ties) {
  std::map<std::pair<int, std::pair<long, long>>, int> track_of;
  for (size_t k = 0; k < pairs.size(); ++k) {
    if (!used[k]) continue;
    const auto [a, b] = pairs[k];
    const auto& pts = results[k].tie_points;
    for (size_t t = 0; t < pts.size(); ++t) {
      const auto key = std::make_pair(a, std::make_pair(std::lround(pts[t].xa.x() * 100.0),
                                                        std::lround(pts[t].xa.y() * 100.0)));
      auto it = track_of.find(key);
      if (it == track_of.end()) {
        it = track_of.emplace(key, static_cast<int>(ties->tracks.size())).first;
        FlightTrack track;
        track.observations.emplace_back(a, pts[t].xa);
        track.grey = grey_of[k][t];
        ties->tracks.push_back(std::move(track));
      }
      ties->tracks[it->second].observations.emplace_back(b, pts[t].xb);
    }
  }
}

// Union-find over tracks.
int Root(std::vector<int>* parent, int i) {
  while ((*parent)[i] != i) i = (*parent)[i] = (*parent)[(*parent)[i]];
  return i;
}

}  // namespace

std::vector<std::vector<std::pair<int, int>>> JoinTracks(double radius,
                                                         std::vector<FlightTrack>* tracks_in) {
  std::vector<FlightTrack>& tracks = *tracks_in;
  std::map<std::pair<int, std::pair<long, long>>, std::vector<int>> start_cell;
  auto cell = [&](const Eigen::Vector2d& x) {
    return std::make_pair(static_cast<long>(std::floor(x.x() / radius)),
                          static_cast<long>(std::floor(x.y() / radius)));
  };
  for (size_t t = 0; t < tracks.size(); ++t)
    start_cell[{tracks[t].observations[0].first, cell(tracks[t].observations[0].second)}].push_back(
        static_cast<int>(t));
  std::vector<int> parent(tracks.size());
  for (size_t t = 0; t < tracks.size(); ++t) parent[t] = static_cast<int>(t);
  for (size_t t = 0; t < tracks.size(); ++t) {
    for (size_t k = 1; k < tracks[t].observations.size(); ++k) {
      const auto& [b, xb] = tracks[t].observations[k];
      const auto c = cell(xb);
      int best = -1;
      double best_d = radius;
      for (long dx = -1; dx <= 1; ++dx)
        for (long dy = -1; dy <= 1; ++dy) {
          auto it = start_cell.find({b, {c.first + dx, c.second + dy}});
          if (it == start_cell.end()) continue;
          for (int u : it->second) {
            const double d = (tracks[u].observations[0].second - xb).norm();
            if (d < best_d) best_d = d, best = u;
          }
        }
      if (best >= 0) parent[Root(&parent, best)] = Root(&parent, static_cast<int>(t));
    }
  }
  std::map<int, int> joined_of_root;
  std::vector<FlightTrack> joined;
  std::vector<std::vector<std::pair<int, int>>> origin;
  for (size_t t = 0; t < tracks.size(); ++t) {
    const int r = Root(&parent, static_cast<int>(t));
    auto it = joined_of_root.find(r);
    if (it == joined_of_root.end()) {
      it = joined_of_root.emplace(r, static_cast<int>(joined.size())).first;
      joined.push_back(FlightTrack{{}, tracks[t].grey});
      origin.emplace_back();
    }
    FlightTrack& j = joined[it->second];
    for (size_t k = 0; k < tracks[t].observations.size(); ++k) {
      const auto& o = tracks[t].observations[k];
      bool have = false;
      for (const auto& q : j.observations) have |= q.first == o.first;
      if (have) continue;
      j.observations.push_back(o);
      origin[it->second].emplace_back(static_cast<int>(t), static_cast<int>(k));
    }
  }
  tracks.swap(joined);
  return origin;
}

void FlightMatchingOptions::Check() const {
  RequireOption("flight matching", exhaustive_max_photos >= 2, "exhaustive_max_photos",
                "must be >= 2");
  RequireOption("flight matching", sequence_window >= 1, "sequence_window", "must be >= 1");
  RequireOption("flight matching", min_pair_tie_points >= 5, "min_pair_tie_points", "must be >= 5");
  RequireOption("flight matching", join_radius_px >= 0.0, "join_radius_px", "must be >= 0");
  RequireOption("flight matching", growth_join_radius >= 0.0, "growth_join_radius", "must be >= 0");
  RequireOption("flight matching", threads >= 0 && threads <= 64, "threads", "must be in [0, 64]");
  footprint.Check();
  features.Check();
  pair.Check();
}

std::vector<std::pair<int, int>> PlanFlightPairs(const FlightPhotos& photos,
                                                 const FlightMatchingOptions& options) {
  const int n = static_cast<int>(photos.photos.size());
  std::vector<std::pair<int, int>> pairs;
  if (n <= options.exhaustive_max_photos) {
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j) pairs.emplace_back(i, j);
    return pairs;
  }
  const std::vector<matching::PhotoFootprint> fp = Footprints(photos, options.footprint);
  for (int i = 0; i < n; ++i) {
    for (int j = i + 1; j < n; ++j) {
      const bool both = fp[i].has_position && fp[j].has_position;
      if (both ? matching::FootprintOverlap(fp[i], fp[j]) >= options.footprint.min_overlap
               : j - i <= options.sequence_window)
        pairs.emplace_back(i, j);
    }
  }
  return pairs;
}

double GrowthJoinRadiusPx(const FlightMatchingOptions& options, int width, int height) {
  const double reduce = std::min(
      1.0, static_cast<double>(options.features.coarse_max_side) / std::max(width, height));
  return options.growth_join_radius / reduce;
}

FlightTies MatchFlight(const FlightPhotos& photos, const FlightMatchingOptions& options,
                       const StageProgress& progress) {
  options.Check();
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<std::pair<int, int>> pairs = PlanFlightPairs(photos, options);
  std::vector<int> uses(photos.photos.size(), 0);
  for (const auto& [a, b] : pairs) ++uses[a], ++uses[b];
  FeatureCache cache(photos, options, uses);
  std::vector<matching::PhotoPairResult> results(pairs.size());
  std::vector<std::vector<std::uint8_t>> grey_of(pairs.size());
  const int threads = options.threads > 0 ? options.threads : cv::getNumberOfCPUs();
  int with_pairs = 0;
  for (int u : uses) with_pairs += u > 0;
  std::mutex progress_mutex;
  int pairs_done = 0, features_said = 0;
  auto report = [&] {  // after a pair
    if (!progress) return;
    std::lock_guard<std::mutex> lock(progress_mutex);
    const int features = cache.computed();
    if (features > features_said) progress("features", features_said = features, with_pairs);
    progress("pairs", ++pairs_done, static_cast<int>(pairs.size()));
  };
  // Pairs in order, `threads` at a time: photo a's features come first, so a
  // photo is released soon after the pairs that need it.
  cv::parallel_for_(
      cv::Range(0, static_cast<int>(pairs.size())),
      [&](const cv::Range& range) {
        for (int k = range.start; k < range.end; ++k) {
          const auto [a, b] = pairs[k];
          const auto fa = cache.Get(a), fb = cache.Get(b);
          if (fa && fb) {
            results[k] = matching::MatchPhotoPair(*fa, *fb, options.pair);
            for (const auto& t : results[k].tie_points)
              grey_of[k].push_back(GreyAt(fa->grey(), t.xa));
          } else {
            results[k].summary.message = "a photo could not be decoded";
          }
          cache.Done(a);
          cache.Done(b);
          report();
        }
      },
      threads);
  FlightTies ties;
  std::vector<std::uint8_t> used(pairs.size(), 0);
  for (size_t k = 0; k < pairs.size(); ++k) {
    const matching::PhotoPairSummary& s = results[k].summary;
    FlightPairStats st{pairs[k].first, pairs[k].second,
                       static_cast<int>(results[k].tie_points.size()), s.epipolar_rms, s.message};
    if (st.tie_points >= options.min_pair_tie_points) {
      used[k] = 1;
      ++ties.pairs_tied;
      ties.tie_points += st.tie_points;
    } else if (st.message.empty()) {
      st.message = Message(st.tie_points,
                           " tie points (min_pair_tie_points = ", options.min_pair_tie_points, ")");
    }
    ties.pair_seconds += s.seconds;
    ties.pairs.push_back(st);
  }
  BuildTracks(pairs, results, used, grey_of, &ties);
  // Tracks for the orientation's growth: joined at the interest points'
  // precision (a pixel fraction of the reduced copy they are detected on);
  // JoinTracks needs the tracks as built (each starting at its own point).
  if (options.growth_join_radius > 0.0 && !photos.photos.empty()) {
    ties.growth_tracks = ties.tracks;
    JoinTracks(GrowthJoinRadiusPx(options, photos.photos[0].width, photos.photos[0].height),
               &ties.growth_tracks);
  }
  if (options.join_radius_px > 0.0) JoinTracks(options.join_radius_px, &ties.tracks);
  ties.feature_seconds = cache.seconds();
  ties.peak_feature_bytes = cache.peak_bytes();
  ties.unreadable = cache.unreadable();
  ties.wall_seconds = Seconds(t0);
  return ties;
}

}  // namespace flight
}  // namespace slope_monitor
