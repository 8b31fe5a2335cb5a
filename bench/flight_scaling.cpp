// Benchmark: how process_flight's stages scale to a 150-photo flight of
// 12 MP photos (issue 34), where no real flight of that size is at hand.
//
// Two parts, in one run:
//   1. Features and pair matching, measured on real 12 MP photos: MatchFlight
//      (the process_flight code) on the first --real-photos photos of a real
//      folder (default ../shared/data/uav_real_copr/images, 4272 x 2848),
//      every pair: CPU seconds of features per photo and wall seconds per
//      pair on --threads threads.
//   2. Orientation, measured on simulated blocks of 24 / 54 / 100 / 150 nadir
//      photos (4000 x 3000 px of 1.6 um behind 4.7 mm, 70 m above a rolling
//      slope: 80 % forward, 70 % side overlap, strips flown both ways),
//      consumer GNSS (3 m), a camera with 25 px of barrel distortion the
//      nominal model does not know, tie points with 0.5 px noise at the density
//      process_flight kept on copr (about 760 per photo, tracks of ~4 photos):
//      OrientFlight's start, growth and final self-calibrating adjustment with
//      covariance, timed as process_flight reports them, checked against the
//      truth (camera centres), with the process's peak memory.
// Then, per block size, the pairs PlanFlightPairs plans for that layout (all
// pairs up to 60 photos, GNSS footprints beyond) and the estimated total:
// features (per photo x photos) + matching (per pair x pairs) + orientation.
//
//   bench_flight_scaling [--photos DIR] [--real-photos N] [--threads N] [sizes...]
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/flight/flight_matching.h"
#include "slope_monitor/core/flight/flight_orientation.h"
#include "slope_monitor/core/flight/flight_photos.h"

namespace sm = slope_monitor;
namespace fl = slope_monitor::flight;

namespace {

constexpr int kWidth = 4000, kHeight = 3000;
constexpr double kPixelMm = 0.0016, kFocalMm = 4.7, kHeightM = 70.0;

double PeakGb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0 / 1024.0;
}

// CPU seconds of the process so far (user + system): load-independent,
// unlike wall time on a shared machine.
double CpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + 1e-6 * u.ru_utime.tv_usec + u.ru_stime.tv_sec +
         1e-6 * u.ru_stime.tv_usec;
}

double Terrain(double x, double y) {
  return 0.15 * y + 4.0 * std::sin(x / 35.0) + 2.5 * std::cos(y / 28.0);
}

sm::camera::CameraModel Truth() {
  std::array<double, sm::camera::kNumInterior> in{};
  in[sm::camera::kC] = 4.75;
  in[sm::camera::kX0] = 0.01;
  in[sm::camera::kY0] = -0.008;
  in[sm::camera::kK1] = -2.0e-3;  // ~25 px at the corners
  return sm::camera::CameraModel(sm::camera::Sensor{kWidth, kHeight, kPixelMm},
                                 sm::camera::DistortionModel::kRadial, in);
}

struct Block {
  fl::FlightPhotos photos;
  fl::FlightTies ties;
  std::vector<Eigen::Vector3d> centre;
  std::vector<std::optional<Eigen::Vector3d>> gnss;
};

// strips x per_strip photos; image height along the strip.
Block MakeBlock(int strips, int per_strip, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> px(0.0, 0.5), gnss(0.0, 3.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  const double gsd = kPixelMm / kFocalMm * kHeightM;                      // [m]
  const double along = kHeight * gsd * 0.2, across = kWidth * gsd * 0.3;  // 80 % / 70 % overlap
  const sm::camera::CameraModel truth = Truth();
  std::array<double, sm::camera::kNumInterior> nominal{};
  nominal[sm::camera::kC] = kFocalMm;
  Block b;
  b.photos.nominal =
      sm::camera::CameraModel(truth.sensor(), sm::camera::DistortionModel::kNone, nominal);
  std::vector<sm::camera::ExteriorOrientation> pose;
  const sm::capture::LocalTangentPlane ltp(sm::capture::Geodetic{35.0, 139.0, 0.0});
  for (int s = 0; s < strips; ++s) {
    for (int k = 0; k < per_strip; ++k) {
      const double x = across * s, y = s % 2 ? along * (per_strip - 1 - k) : along * k;
      sm::camera::ExteriorOrientation e;
      e.position = {x, y, Terrain(x, y) + kHeightM};
      e.angles.kappa = s % 2 ? M_PI / 2 + 0.03 : M_PI / 2 - 0.02;
      pose.push_back(e);
      b.centre.push_back(e.position);
      b.gnss.emplace_back(e.position + Eigen::Vector3d(gnss(rng), gnss(rng), 2.0 * gnss(rng)));
      fl::FlightPhoto p;
      p.name = "P" + std::to_string(10000 + static_cast<int>(pose.size()));
      p.width = kWidth;
      p.height = kHeight;
      const sm::capture::Geodetic g = ltp.ToGeodetic(Eigen::Vector3d(x, y, 0.0));
      p.exif.has_gps = true;
      p.exif.gps = g;
      p.exif.focal_length_mm = kFocalMm;
      p.attitude.has_pixel_size = true;
      p.attitude.pixel_size_mm = kPixelMm;
      p.attitude.has_yaw = true;
      p.attitude.yaw_deg = s % 2 ? 180.0 : 0.0;
      p.attitude.has_height_above_ground = true;
      p.attitude.height_above_ground_m = kHeightM;
      b.photos.photos.push_back(p);
    }
  }
  // Tie points: ~760 kept per photo, tracks of ~4 of the photos that see them.
  const double x0 = -0.5 * kWidth * gsd, x1 = across * (strips - 1) + 0.5 * kWidth * gsd;
  const double y0 = -0.5 * kHeight * gsd, y1 = along * (per_strip - 1) + 0.5 * kHeight * gsd;
  const double seen_by =
      (kWidth * gsd / across) * (kHeight * gsd / along);  // photos seeing a point inside
  const int n_points = static_cast<int>(760.0 * pose.size() / 4.0);
  std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1);
  std::map<std::pair<int, int>, int> pair_ties;
  for (int t = 0; t < n_points; ++t) {
    const double x = ux(rng), y = uy(rng);
    const Eigen::Vector3d X(x, y, Terrain(x, y));
    fl::FlightTrack track;
    for (size_t i = 0; i < pose.size(); ++i) {
      Eigen::Vector2d q;
      if (!truth.Project(pose[i], X, &q) || q.x() < 5 || q.y() < 5 || q.x() > kWidth - 6 ||
          q.y() > kHeight - 6)
        continue;
      if (u01(rng) > 4.0 / seen_by) continue;
      track.observations.emplace_back(static_cast<int>(i), q + Eigen::Vector2d(px(rng), px(rng)));
    }
    if (track.observations.size() < 2) continue;
    for (size_t a = 0; a < track.observations.size(); ++a)
      for (size_t c = a + 1; c < track.observations.size(); ++c)
        ++pair_ties[{track.observations[a].first, track.observations[c].first}];
    b.ties.tracks.push_back(std::move(track));
  }
  for (const auto& [ab, n] : pair_ties) {
    b.ties.pairs.push_back(fl::FlightPairStats{ab.first, ab.second, n, 0.5, ""});
    b.ties.tie_points += n;
    b.ties.pairs_tied += n >= 15;
  }
  return b;
}

struct RealCost {
  int photos = 0, pairs = 0;
  // CPU seconds per photo (features) and per tied pair (matching without
  // the features, which are computed inside it, over the pairs that tied: a
  // pair without a relation stops early, and a flight's footprint pairs
  // mostly tie; so an upper bound).
  double feature_cpu_per_photo = 0.0, cpu_per_pair = 0.0, wall = 0.0;
};

RealCost MeasureReal(const std::string& folder, int n, int threads) {
  std::vector<std::string> paths = fl::ListPhotoFolder(folder);
  if (static_cast<int>(paths.size()) > n) paths.resize(n);
  const fl::FlightPhotos photos = fl::ReadFlightPhotos(paths);
  fl::FlightMatchingOptions o;
  o.threads = threads;
  const double cpu0 = CpuSeconds();
  const fl::FlightTies ties = fl::MatchFlight(photos, o);
  const double cpu = CpuSeconds() - cpu0;
  RealCost c;
  c.photos = static_cast<int>(photos.photos.size());
  c.pairs = static_cast<int>(ties.pairs.size());
  c.feature_cpu_per_photo = ties.feature_seconds / std::max(1, c.photos);
  c.wall = ties.wall_seconds;
  c.cpu_per_pair = std::max(0.0, cpu - ties.feature_seconds) / std::max(1, ties.pairs_tied);
  std::printf(
      "real photos: %d of %s, %d pairs (%d tied, %ld tie points): features %.1f s CPU (%.2f s per "
      "photo), "
      "matching %.1f s CPU with the features (%.3f s per tied pair without them), %.1f s wall on "
      "%d threads, "
      "peak %.2f GB\n",
      c.photos, folder.c_str(), c.pairs, ties.pairs_tied, ties.tie_points, ties.feature_seconds,
      c.feature_cpu_per_photo, cpu, c.cpu_per_pair, ties.wall_seconds, threads, PeakGb());
  return c;
}

}  // namespace

int main(int argc, char** argv) {
  std::string folder = std::string(SM_SOURCE_DIR) + "/../shared/data/uav_real_copr/images";
  int real_photos = 12, threads = 2;
  std::vector<int> sizes;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--photos" && i + 1 < argc) {
      folder = argv[++i];
    } else if (a == "--real-photos" && i + 1 < argc) {
      real_photos = std::atoi(argv[++i]);
    } else if (a == "--threads" && i + 1 < argc) {
      threads = std::atoi(argv[++i]);
    } else if (a == "-h" || a == "--help") {
      std::printf(
          "bench_flight_scaling [--photos DIR] [--real-photos N] [--threads N] [sizes...]\n");
      return 0;
    } else if (std::atoi(a.c_str()) > 0) {
      sizes.push_back(std::atoi(a.c_str()));
    } else {
      std::fprintf(stderr, "bench_flight_scaling: unknown argument '%s'\n", a.c_str());
      return 1;
    }
  }
  if (sizes.empty()) sizes = {24, 54, 100, 150};
  try {
    const RealCost real = MeasureReal(folder, real_photos, threads);
    std::printf(
        "\n| photos | pairs planned | features (est.) | matching (est.) | start | growth | "
        "adjustment | "
        "orientation CPU | total (est.) | oriented | rms px | max centre error m | peak GB |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (int n : sizes) {
      const int strips = n <= 24 ? 4 : n <= 54 ? 6 : 10;
      const int per_strip = std::max(2, n / strips);
      Block b = MakeBlock(strips, per_strip, 7u + static_cast<unsigned>(n));
      const int photos = strips * per_strip;
      const size_t pairs = fl::PlanFlightPairs(b.photos, fl::FlightMatchingOptions{}).size();
      fl::FlightInput in;
      in.photos = &b.photos;
      in.ties = &b.ties;
      in.gnss_in_site = b.gnss;
      const double cpu0 = CpuSeconds();
      const fl::FlightResult r = fl::OrientFlight(in);
      const double orient = CpuSeconds() - cpu0;
      double worst = 0.0;
      for (size_t i = 0; i < r.scene.images.size(); ++i)
        worst = std::max(
            worst, (r.scene.images[i].exterior.position - b.centre[r.photo_of_image[i]]).norm());
      const auto sec = [&](const char* k) {
        const auto it = r.summary.seconds.find(k);
        return it == r.summary.seconds.end() ? 0.0 : it->second;
      };
      const double features = real.feature_cpu_per_photo * photos / std::max(1, threads);
      const double matching = real.cpu_per_pair * static_cast<double>(pairs) / std::max(1, threads);
      std::printf(
          "| %d | %zu | %.0f s | %.0f s | %.1f s | %.1f s | %.1f s | %.1f s | %.0f s | %d of %d | "
          "%.3f | %.2f | %.2f |\n",
          photos, pairs, features, matching, sec("start"), sec("growth"), sec("adjustment"), orient,
          features + matching + orient, r.summary.oriented, photos, r.summary.rms_px, worst,
          PeakGb());
      std::fflush(stdout);
    }
    std::printf(
        "\nTimes on idle cores, from CPU seconds (load-independent): features (est.) = photos x "
        "the real "
        "photos' feature CPU per photo / threads; matching (est.) = pairs planned x their CPU per "
        "tied pair / threads; "
        "orientation = OrientFlight's CPU (start, growth, adjustment: their wall times, as "
        "process_flight "
        "reports them); total (est.) = features + matching + orientation.\n");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_flight_scaling: %s\n", e.what());
    return 1;
  }
  return 0;
}
