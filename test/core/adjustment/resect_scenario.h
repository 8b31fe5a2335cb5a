// A camera 150-200 m across a slope and its surveyed, picked points, for the
// resection tests (core_adjustment_tests, the ROS service's in ros_tests, the
// simulator's surveyed points in replay_targetless_camera_test).
#pragma once

#include <array>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/resect_camera.h"
#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/io/surveyed_points.h"

namespace slope_monitor {
namespace resect_scenario {

// A 4000 x 3000 px camera with 4 um pixels (16 x 12 mm) and principal distance c_mm.
inline camera::CameraModel Camera(double c_mm) {
  camera::Sensor s;
  s.width = 4000;
  s.height = 3000;
  s.pixel_size = 0.004;  // 16 x 12 mm
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = c_mm;
  return camera::CameraModel(s, camera::DistortionModel::kNone, in);
}

inline camera::ExteriorOrientation TruePose() {
  camera::ExteriorOrientation e;
  e.position = Eigen::Vector3d(512.3, -170.4, 1032.0);
  e.angles.theta = 0.31;
  e.angles.phi = 1.42;  // looking almost horizontally across the slope
  e.angles.kappa = 0.04;
  return e;
}

// A surveyed-point list as a crew would have it: points on the slope 150-200 m
// away, surveyed with xyz_sigma noise and picked with pixel_sigma noise.
inline std::vector<io::PickedPoint> Survey(const camera::CameraModel& truth,
                                           const camera::ExteriorOrientation& pose, int n,
                                           double xyz_sigma, double pixel_sigma, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> col(100, truth.sensor().width - 100),
      row(100, truth.sensor().height - 100), range(150, 200);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<io::PickedPoint> points;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector2d px(col(rng), row(rng));
    const camera::Ray ray = truth.ImageToRay(pose, px);
    io::PickedPoint p;
    p.id = "p" + std::to_string(i);
    const Eigen::Vector3d x = ray.origin + range(rng) * ray.direction;
    p.xyz = x + xyz_sigma * Eigen::Vector3d(g(rng), g(rng), g(rng));
    Eigen::Vector2d projected;
    truth.Project(pose, x, &projected);
    p.pixel = projected + pixel_sigma * Eigen::Vector2d(g(rng), g(rng));
    points.push_back(p);
  }
  return points;
}

// The estimated sigma of the free parameter `name` ("theta", "c", "X0", ...).
inline double Sigma(const adjustment::ResectCameraSummary& s, const std::string& name) {
  for (const auto& p : s.parameters)
    if (p.name == name) return p.sigma;
  ADD_FAILURE() << "no parameter " << name;
  return 0.0;
}

}  // namespace resect_scenario
}  // namespace slope_monitor
