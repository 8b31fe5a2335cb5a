// A simulated UAV flight for the sequence tests (uav_sequence_test.cpp,
// sequence_matcher_sim_test.cpp): three consecutive nadir photos 60 m above
// the ground with 70 % forward overlap, flying north, 640 x 480 (the UAV
// camera's field of view at half the resolution), rendered once, with the
// geometric truth (Transfer: where photo j sees what photo i sees at x).
// Header only; the test links slope_monitor_core_sim.
#pragma once

#include <cstdio>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"

#include "../sim/test_scene.h"  // the small simulated slope (header only)

namespace slope_monitor {
namespace matching {
namespace testing {

constexpr int kW = 640, kH = 480;
constexpr double kHeight = 60.0;  // [m] above the ground at the flight's centre
constexpr double kC = 9.1667;     // [mm] 8.8 mm x 10 um / 9.6 um: the UAV camera's field of view
constexpr double kOverlap = 0.7;  // forward overlap

// A 60 m x 60 m slope (6 m relief), texture as the matcher's simulator test,
// no body motion, no obstacles.
inline sim::SceneSpec Site() {
  sim::SceneSpec s = sim::testing::SmallSlope(11);
  s.terrain.extent = Eigen::Vector4d(0, 60, 0, 60);
  s.texture.coarsest_wavelength = 8.0;
  s.landslide.velocity0 = 0.0;
  s.scarp.depth = 0.0;
  return s;
}

struct Flight {
  Flight()
      : scene(Site()),
        model(sim::testing::SmallCamera(kW, kH, kC, 0.02, -0.01, -1.0e-3)),
        state(scene.AtTime(0.0)) {
    const double footprint_y = kH * 0.01 / kC * kHeight;  // [m] along track (image rows)
    const double base = (1.0 - kOverlap) * footprint_y;
    const double z = scene.AnalyticHeight(30, 28) + kHeight;
    const sim::Renderer renderer(scene, model);
    for (int i = 0; i < 3; ++i) {
      poses.push_back(sim::testing::NadirFrom(Eigen::Vector3d(30, 18.5 + i * base, z)));
      images.push_back(
          sim::testing::Photo(renderer, state, poses.back(), sim::RenderOptions(), 100 + i));
    }
    std::printf("flight: footprint %.1f m along track, base %.2f m, ground pixel %.3f m\n",
                footprint_y, base, kHeight * 0.01 / kC);
  }
  // Ground point seen by photo i at pixel x (false: misses the terrain).
  bool Ground(int i, const Eigen::Vector2d& x, Eigen::Vector3d* p) const {
    const camera::Ray ray = model.ImageToRay(poses[i], x);
    const Eigen::Vector3d d = ray.direction.normalized();
    const double t = state.grid.IntersectRay(ray.origin, d, 500.0);
    if (!std::isfinite(t)) return false;
    *p = ray.origin + t * d;
    return true;
  }
  // True position in photo j of what photo i sees at x.
  bool Transfer(int i, int j, const Eigen::Vector2d& x, Eigen::Vector2d* xj) const {
    Eigen::Vector3d p;
    return Ground(i, x, &p) && model.Project(poses[j], p, xj);
  }
  sim::Scene scene;
  camera::CameraModel model;
  sim::Scene::State state;
  std::vector<camera::ExteriorOrientation> poses;
  std::vector<cv::Mat> images;
};

inline const Flight& TheFlight() {
  static const Flight flight;
  return flight;
}

inline bool Inside(const Eigen::Vector2d& x, double margin) {
  return x.x() >= margin && x.y() >= margin && x.x() <= kW - 1 - margin && x.y() <= kH - 1 - margin;
}

}  // namespace testing
}  // namespace matching
}  // namespace slope_monitor
