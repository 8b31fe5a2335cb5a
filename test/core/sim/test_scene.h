// The small simulated scene of the tests that render with the package's
// simulator (sim/render_test, dense/sim_test, matching/sim_tracking_test):
// a 40 m x 30 m slope, a landslide body moving south (down the slope), trees
// and boulders, seen by small cameras with lens distortion. Header only, so a
// test that includes it needs no CMake change; a test outside the sim module
// must link slope_monitor_core_sim (CMakeLists.txt names those tests).
//
// Each test states what differs from these pieces (seed, body size and
// speed, texture, obstacles, camera) beside its own scene.
#pragma once

#include <array>
#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace sim {
namespace testing {

// The slope: x 0..40 m, y 0..30 m, 0.5 m grid, 6 m relief with a 0.3 m
// undulation of 15 m wavelength. No body motion, no obstacles yet.
inline SceneSpec SmallSlope(unsigned int seed) {
  SceneSpec s;
  s.seed = seed;
  s.terrain.extent = Eigen::Vector4d(0, 40, 0, 30);
  s.terrain.grid_spacing = 0.5;
  s.terrain.relief = 6.0;
  s.terrain.undulation = 0.3;
  s.terrain.undulation_wavelength = 15.0;
  return s;
}

// A landslide body at `centre` [m], `length` x `width` [m], moving south
// (azimuth -90 deg, down the slope) with `plunge` [rad] at `metres_per_hour`
// from t = 0.
inline void SetSouthwardBody(SceneSpec* s, const Eigen::Vector2d& centre, double length,
                             double width, double plunge, double metres_per_hour) {
  s->landslide.centre = centre;
  s->landslide.length = length;
  s->landslide.width = width;
  s->landslide.azimuth = -M_PI / 2;
  s->landslide.plunge = plunge;
  s->landslide.velocity0 = metres_per_hour / 3600.0;
  s->landslide.reference_time = 0.0;
}

// A tree standing on the ground at (x, y) [m]: crown radius 1.5 m, 5 m high.
inline Obstacle Tree(double x, double y) {
  Obstacle tree;
  tree.kind = Obstacle::Kind::kTree;
  tree.base =
      Eigen::Vector3d(x, y, std::numeric_limits<double>::quiet_NaN());  // NaN: on the ground
  tree.radius = 1.5;
  tree.height = 5.0;
  return tree;
}

// A boulder lying on the ground at (x, y): radius and height [m].
inline Obstacle Boulder(double x, double y, double radius, double height) {
  Obstacle boulder;
  boulder.kind = Obstacle::Kind::kBoulder;
  boulder.base = Eigen::Vector3d(x, y, std::numeric_limits<double>::quiet_NaN());
  boulder.radius = radius;
  boulder.height = height;
  return boulder;
}

// A Brown-affinity camera with 0.01 mm pixels: principal distance c, principal
// point offset (x0, y0) [mm], radial k1, decentring p1 and affinity b1; the
// other terms 0.
inline camera::CameraModel SmallCamera(int width, int height, double c, double x0, double y0,
                                       double k1, double p1 = 0.0, double b1 = 0.0) {
  camera::Sensor sensor{width, height, 0.01};
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = c;
  in[camera::kX0] = x0;
  in[camera::kY0] = y0;
  in[camera::kK1] = k1;
  in[camera::kP1] = p1;
  in[camera::kB1] = b1;
  return camera::CameraModel(sensor, camera::DistortionModel::kBrownAffinity, in);
}

// Looking straight down from `position` (image up = north).
inline camera::ExteriorOrientation NadirFrom(const Eigen::Vector3d& position) {
  return LookAt(position, position - Eigen::Vector3d(0, 0, 1), Eigen::Vector3d::UnitY());
}

// An 8-bit photo of `state`: rendered with `options`, exposed with the
// default exposure (read noise 1.5 DN + shot noise) from noise seed `seed`.
inline cv::Mat Photo(const Renderer& renderer, const Scene::State& state,
                     const camera::ExteriorOrientation& pose, const RenderOptions& options,
                     unsigned seed) {
  const RenderResult rr = renderer.Render(state, pose, options);
  std::mt19937 rng(seed);
  return Expose(rr.radiance, ExposureOptions(), &rng);
}

}  // namespace testing
}  // namespace sim
}  // namespace slope_monitor
