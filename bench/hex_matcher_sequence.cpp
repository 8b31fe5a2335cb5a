// Benchmark: hex_matcher sequence mode on full-size UAV photos (1280 x 960,
// c 8.8 mm, 4.8 um pixels, 60 m above the simulator's ground, 70 % forward
// overlap, flying north): time per pair (global shift + matching, one
// thread: cv::setNumThreads(1)), matches per pair and their error against
// the simulator's truth (a-point's ray intersected with the true terrain,
// projected into b with the true camera b), for the pairs 1-2 (70 % overlap)
// and 1-3 (40 %), with several settings:
//   defaults      the node's defaults, every interest point of a searched
//                 (the baseline: no `within` restriction);
//   within        only a's points that the global shift puts inside b (what
//                 sequence mode does);
//   within_mp<N>  the same with max_points N;
//   within_no2way the same without the two-way LSC check.
// Prints one line per setting and pair and `ratio ours/defaults = X`: time
// per pair of the sequence-mode defaults ("within_mp1000": the `within`
// restriction and sequence_max_points 1000) against the baseline.
//   bench_hex_matcher_sequence
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "slope_monitor/core/matching/global_shift.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"

#include "../test/core/sim/test_scene.h"

using namespace slope_monitor;

namespace {

constexpr int kW = 1280, kH = 960;

struct Flight {
  Flight() : scene(Spec()), model(Camera()), state(scene.AtTime(0.0)) {
    const double footprint_y = kH * 0.0048 / 8.8 * 60.0;
    const double base = 0.3 * footprint_y;
    const double z = scene.AnalyticHeight(30, 28) + 60.0;
    const sim::Renderer renderer(scene, model);
    for (int i = 0; i < 3; ++i) {
      poses.push_back(sim::testing::NadirFrom(Eigen::Vector3d(30, 18.5 + i * base, z)));
      images.push_back(
          sim::testing::Photo(renderer, state, poses.back(), sim::RenderOptions(), 100 + i));
    }
  }
  static sim::SceneSpec Spec() {
    sim::SceneSpec s = sim::testing::SmallSlope(11);
    s.terrain.extent = Eigen::Vector4d(0, 60, 0, 60);
    s.texture.coarsest_wavelength = 8.0;
    s.landslide.velocity0 = 0.0;
    s.scarp.depth = 0.0;
    return s;
  }
  static camera::CameraModel Camera() {
    std::array<double, camera::kNumInterior> in{};
    in[camera::kC] = 8.8;
    in[camera::kK1] = -1.0e-3;
    return camera::CameraModel(camera::Sensor{kW, kH, 0.0048},
                               camera::DistortionModel::kBrownAffinity, in);
  }
  bool Transfer(int i, int j, const Eigen::Vector2d& x, Eigen::Vector2d* xj) const {
    const camera::Ray ray = model.ImageToRay(poses[i], x);
    const Eigen::Vector3d d = ray.direction.normalized();
    const double t = state.grid.IntersectRay(ray.origin, d, 500.0);
    return std::isfinite(t) && model.Project(poses[j], ray.origin + t * d, xj);
  }
  sim::Scene scene;
  camera::CameraModel model;
  sim::Scene::State state;
  std::vector<camera::ExteriorOrientation> poses;
  std::vector<cv::Mat> images;
};

struct Setting {
  std::string name;
  bool within;
  int max_points;
  bool two_way;
};

}  // namespace

int main() {
  cv::setNumThreads(1);
  const auto r0 = std::chrono::steady_clock::now();
  const Flight f;
  std::printf("rendered 3 photos %dx%d in %.1f s\n", kW, kH,
              std::chrono::duration<double>(std::chrono::steady_clock::now() - r0).count());
  const std::vector<Setting> settings = {{"defaults", false, 2000, true},
                                         {"within", true, 2000, true},
                                         {"within_mp1000", true, 1000, true},
                                         {"within_mp500", true, 500, true},
                                         {"within_no2way", true, 2000, false}};
  double t_defaults = 0, t_within = 0;
  for (const Setting& s : settings) {
    matching::HexMatcherOptions o;  // the node's defaults (config/defaults/hex_matcher.yaml)
    o.interest.max_points = s.max_points;
    o.quality.two_way = s.two_way;
    const matching::HexMatcher matcher(o);
    double total = 0;
    int pairs = 0;
    for (const auto& ij : {std::make_pair(0, 1), std::make_pair(0, 2)}) {
      const int a = ij.first, b = ij.second;
      const auto t0 = std::chrono::steady_clock::now();
      const matching::GlobalShiftResult gs =
          matching::EstimateGlobalShift(f.images[a], f.images[b], matching::GlobalShiftOptions());
      const double t_shift =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      matching::MatchPrior prior;
      prior.shift = gs.shift;
      if (s.within) {
        prior.within = [&gs](const Eigen::Vector2d& x) {
          const Eigen::Vector2d y = x + gs.shift;
          return y.x() >= 12 && y.y() >= 12 && y.x() <= kW - 13 && y.y() <= kH - 13;
        };
      }
      const matching::HexMatchResult r = matcher.Match(f.images[a], f.images[b], prior);
      const double seconds =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      total += seconds;
      ++pairs;
      int normal = 0, gross = 0;
      double sum2 = 0;
      for (const auto& m : r.matches) {
        if (m.quality <= matching::kLowQuality) continue;
        Eigen::Vector2d truth;
        if (!f.Transfer(a, b, m.xa, &truth)) continue;
        const double e = (m.xb - truth).norm();
        if (e > 1.0) {
          ++gross;
          continue;
        }
        ++normal;
        sum2 += e * e;
      }
      std::printf(
          "%-14s pair %d-%d: shift (%.1f, %.1f) in %.3f s, %d candidates, %zu matches, %d normal "
          "within 1 px "
          "of the truth (RMS %.3f px), %d beyond 1 px; %.2f s per pair\n",
          s.name.c_str(), a + 1, b + 1, gs.shift.x(), gs.shift.y(), t_shift, r.summary.candidates,
          r.matches.size(), normal, std::sqrt(sum2 / std::max(1, normal)), gross, seconds);
    }
    std::printf("%-14s mean %.2f s per pair\n", s.name.c_str(), total / pairs);
    if (s.name == "defaults") t_defaults = total / pairs;
    if (s.name == "within_mp1000") t_within = total / pairs;
  }
  std::printf("ratio ours/defaults = %.2f\n", t_within / t_defaults);
  return 0;
}
