// Renders a Scene::State through the package's own camera model by exact
// geometry.
//
// Every pixel's ray comes from CameraModel's inverse (UndistortMm) - the
// ideal image coordinates of each pixel centre are computed once per camera
// model (Renderer constructor) and interpolated bilinearly for sub-pixel
// samples (error < 1e-4 px for the distortions of real lenses). Each ray is
// intersected exactly with
//   * the height-field triangles: a z-buffer rasterisation of the projected
//     mesh picks the candidate triangle per pixel, then an exact ray-triangle
//     intersection (candidate and its neighbours) gives the hit;
//   * the target plates (planar squares / discs) and obstacles (spheres,
//     ellipsoid crowns, cylinder trunks) analytically.
// The nearest hit wins (a plate wins over the ground up to `plate_tolerance`
// behind it, because it lies on the ground). Pixels that may see a target
// are supersampled on a regular n x n grid, so that the intensity centroid of
// a rendered target agrees with the projection of its true centre; pixels
// near obstacles on a coarser grid; ground texture elsewhere is low-passed
// for the pixel footprint.
//
// The output is scene radiance (reflectance x lighting, ~[0, 1]); Expose()
// turns it into 8-bit images with exposure, vignetting and noise.
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/sim/scene.h"

namespace slope_monitor {
namespace sim {

struct RenderOptions {
  int target_supersampling = 8;  // samples per axis on pixels that may see a target plate, [1, 32]
  int obstacle_supersampling = 3;  // samples per axis near obstacles, [1, 16]
  int threads = 2;                 // worker threads (rows are split statically: deterministic)
  bool colour = false;             // CV_32FC3 (b, g, r) radiance instead of CV_32FC1
  double plate_tolerance =
      0.3;             // [m] a plate is seen when it is at most this far behind the ground hit
  int epoch_salt = 0;  // varies the foliage texture between epochs (wind)
};

struct RenderResult {
  cv::Mat radiance;                     // CV_32FC1 or CV_32FC3
  std::vector<double> target_coverage;  // [plate index] image area (px) where the plate was seen
};

class Renderer {
 public:
  // Precomputes the ray table of the camera model (throws InvalidArgument
  // when the model is invalid).
  Renderer(const Scene& scene, const camera::CameraModel& model);

  RenderResult Render(const Scene::State& state, const camera::ExteriorOrientation& pose,
                      const RenderOptions& options) const;

  // Ideal image coordinates [mm] (relative to the principal point) of the
  // pixel position (col, row), interpolated from the table.
  Eigen::Vector2d IdealAt(double col, double row) const;
  const camera::CameraModel& model() const { return model_; }

 private:
  const Scene& scene_;
  camera::CameraModel model_;
  int table_w_ = 0, table_h_ = 0;  // table covers pixels -1 .. W (one pixel margin)
  std::vector<double> ideal_;      // 2 per entry
};

// Exposure model: DN = gain * exposure * vignetting(r) * radiance + noise,
// vignetting(r) = 1 - vignetting * (r / r_corner)^2; noise Gaussian with
// sigma^2 = read_noise^2 + shot_noise * DN; rounded and clipped to [0, 255].
struct ExposureOptions {
  double gain = 230.0;       // [DN] for radiance 1 at exposure 1
  double exposure = 1.0;     // [-]
  double vignetting = 0.25;  // [-] fall-off at the corners, [0, 1)
  double read_noise = 1.5;   // [DN]
  double shot_noise = 0.05;  // [DN per DN]
  bool noise = true;
};

// Radiance (CV_32FC1 / CV_32FC3) -> CV_8UC1 / CV_8UC3 with a per-image
// generator (the caller seeds it: same seed -> identical bytes).
cv::Mat Expose(const cv::Mat& radiance, const ExposureOptions& options, std::mt19937* rng);

}  // namespace sim
}  // namespace slope_monitor
