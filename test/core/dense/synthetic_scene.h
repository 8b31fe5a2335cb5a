// A synthetic stereo scene for the dense tests: a textured height field seen
// by two nadir cameras of the package's camera model (with lens distortion),
// rendered by ray casting. Everything is analytic, so the true height of
// every site point is known.
//
// Site: x east, y north, z up. Ground: z = 10 m plus a Gaussian hill of 2 m
// (sigma 6 m) at (20, 15), plus optional epoch bumps. Cameras at 40 m above
// the ground, 320 x 240 px, f = 400 px (c = 4 mm, 0.01 mm pixels), 8 m
// baseline along x: ground sample 0.1 m, footprint 32 x 24 m.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/dense/rectify.h"

namespace slope_monitor {
namespace dense {
namespace test_scene {

struct Bump {
  double x, y, sigma, amplitude;  // [m]; volume = 2 pi sigma^2 amplitude
  double Volume() const { return 2.0 * M_PI * sigma * sigma * amplitude; }
};

struct Scene {
  std::vector<Bump> bumps;
  double Height(double x, double y) const {
    double z = 10.0 + 2.0 * std::exp(-((x - 20) * (x - 20) + (y - 15) * (y - 15)) / (2.0 * 36.0));
    for (const Bump& b : bumps)
      z += b.amplitude *
           std::exp(-((x - b.x) * (x - b.x) + (y - b.y) * (y - b.y)) / (2.0 * b.sigma * b.sigma));
    return z;
  }
};

// Deterministic lattice value noise in [0, 1).
inline double Lattice(int64_t i, int64_t j, uint32_t seed) {
  uint64_t h = static_cast<uint64_t>(i) * 0x9E3779B97F4A7C15ull ^
               (static_cast<uint64_t>(j) + 0x632BE59BD9B4E019ull) * 0xC2B2AE3D27D4EB4Full ^ seed;
  h ^= h >> 31;
  h *= 0xBF58476D1CE4E5B9ull;
  h ^= h >> 29;
  return static_cast<double>(h >> 11) / 9007199254740992.0;
}

inline double ValueNoise(double x, double y, double cell, uint32_t seed) {
  const double u = x / cell, v = y / cell;
  const int64_t i = static_cast<int64_t>(std::floor(u)), j = static_cast<int64_t>(std::floor(v));
  const double a = u - i, b = v - j;
  const double sa = a * a * (3 - 2 * a), sb = b * b * (3 - 2 * b);
  return (1 - sb) * ((1 - sa) * Lattice(i, j, seed) + sa * Lattice(i + 1, j, seed)) +
         sb * ((1 - sa) * Lattice(i, j + 1, seed) + sa * Lattice(i + 1, j + 1, seed));
}

// Ground texture (grey value) at site (x, y): three octaves.
inline double Texture(double x, double y) {
  return 30.0 + 90.0 * ValueNoise(x, y, 0.35, 11) + 60.0 * ValueNoise(x, y, 1.1, 23) +
         50.0 * ValueNoise(x, y, 3.7, 37);
}

inline camera::CameraModel MakeCamera(double k1) {
  camera::Sensor s;
  s.width = 320;
  s.height = 240;
  s.pixel_size = 0.01;
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 4.0;
  in[camera::kK1] = k1;
  return camera::CameraModel(s, camera::DistortionModel::kRadial, in);
}

// Renders the scene by ray casting from every pixel (2 x 2 supersampling).
inline cv::Mat Render(const Scene& scene, const camera::CameraModel& cam,
                      const camera::ExteriorOrientation& pose) {
  cv::Mat img(cam.sensor().height, cam.sensor().width, CV_8U);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      double acc = 0;
      for (int s = 0; s < 4; ++s) {
        const Eigen::Vector2d px(c - 0.25 + 0.5 * (s % 2), r - 0.25 + 0.5 * (s / 2));
        const camera::Ray ray = cam.ImageToRay(pose, px);
        double t = (10.0 - ray.origin.z()) / ray.direction.z();
        for (int it = 0; it < 30; ++it) {
          const Eigen::Vector3d p = ray.origin + t * ray.direction;
          t = (scene.Height(p.x(), p.y()) - ray.origin.z()) / ray.direction.z();
        }
        const Eigen::Vector3d p = ray.origin + t * ray.direction;
        acc += Texture(p.x(), p.y());
      }
      img.at<uchar>(r, c) = cv::saturate_cast<uchar>(acc / 4.0);
    }
  return img;
}

inline camera::ExteriorOrientation Pose(double x, double y, double z) {
  camera::ExteriorOrientation e;
  e.position = Eigen::Vector3d(x, y, z);
  return e;  // angles 0: nadir, image x east, image y north
}

inline OrientedImage MakeImage(const Scene& scene, const std::string& name, double x, double k1) {
  OrientedImage im;
  im.name = name;
  im.camera = MakeCamera(k1);
  im.pose = Pose(x, 15.0, 50.0);
  im.oriented = true;
  im.image = Render(scene, im.camera, im.pose);
  return im;
}

}  // namespace test_scene
}  // namespace dense
}  // namespace slope_monitor
