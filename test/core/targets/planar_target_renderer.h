// Test renderer: an exact, area-correct image of a planar target (AprilTag or
// circular target) seen by a pinhole camera (camera::CameraModel without
// distortion, pixel size 1 so "mm" are pixels).
//
// A pixel's value is the mean reflectance over its square area (OpenCV
// convention: pixel (c, r) covers [c-0.5, c+0.5] x [r-0.5, r+0.5]), computed
// by mapping 16 x 16 sub-pixel sample points through the inverse plane
// homography; pixels whose 5 x 5 probe points all see the same reflectance
// are uniform and not supersampled. Then gain/offset, optional Gaussian
// noise sigma(I) = sqrt(read^2 + I / photons_per_dn) and rounding to 8 bit.
//
// Used by the targets tests and bench/targets_detect.cpp.
#pragma once

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace targets {
namespace testing {

// A target plate in the site frame: centre, in-plane right and up axes.
struct Plate {
  Eigen::Vector3d centre{0, 0, 0};
  Eigen::Vector3d right{1, 0, 0};
  Eigen::Vector3d up{0, 1, 0};
  Eigen::Vector3d Normal() const { return right.cross(up).normalized(); }
  Eigen::Vector3d At(double u, double v) const { return centre + u * right + v * up; }
};

// Plane (u, v) [m] -> pixel homography for a distortion-free camera model
// with pixel size 1 (see camera_model.h: col = (W-1)/2 + x, row = (H-1)/2 - y).
inline Eigen::Matrix3d PlaneToPixel(const camera::CameraModel& cam,
                                    const camera::ExteriorOrientation& pose, const Plate& plate) {
  const Eigen::Matrix3d m = camera::RotationFromAngles(pose.angles);
  const double c = cam.principal_distance();
  const double cx = 0.5 * (cam.sensor().width - 1) + cam.interior()[camera::kX0];
  const double cy = 0.5 * (cam.sensor().height - 1) - cam.interior()[camera::kY0];
  Eigen::Matrix3d a;
  a << c, 0, -cx, 0, -c, -cy, 0, 0, -1;
  Eigen::Matrix3d b;
  b.col(0) = m * plate.right;
  b.col(1) = m * plate.up;
  b.col(2) = m * (plate.centre - pose.position);
  return a * b;
}

inline Eigen::Vector2d Apply(const Eigen::Matrix3d& h, double u, double v) {
  const Eigen::Vector3d p = h * Eigen::Vector3d(u, v, 1.0);
  return p.head<2>() / p.z();
}

// Reflectance of the plate at (u, v) [m], or < 0 outside the plate.
using Pattern = std::function<double(double u, double v)>;

// Circular target: bright disc of diameter d on a dark ring out to ring_factor * d / 2.
inline Pattern CirclePattern(double diameter, double ring_factor = 2.0, double bright = 0.9,
                             double dark = 0.08) {
  return [=](double u, double v) {
    const double r2 = u * u + v * v, rd = 0.5 * diameter, rr = ring_factor * rd;
    if (r2 <= rd * rd) return bright;
    if (r2 <= rr * rr) return dark;
    return -1.0;
  };
}

// AprilTag tag36h11 `id`; `size` is the black border edge [m]; the plate is
// the tag's total width (white margin included).
class TagPattern {
 public:
  TagPattern(int id, double size, double bright = 0.9, double dark = 0.08)
      : bright_(bright), dark_(dark) {
    apriltag_family_t* fam = tag36h11_create();
    image_u8_t* im = apriltag_to_image(fam, id);
    total_ = fam->total_width;
    cell_ = size / fam->width_at_border;
    cells_.resize(total_ * total_);
    for (int r = 0; r < total_; ++r)
      for (int c = 0; c < total_; ++c) cells_[r * total_ + c] = im->buf[r * im->stride + c] > 127;
    free(im->buf);
    free(im);
    tag36h11_destroy(fam);
  }
  double operator()(double u, double v) const {
    const double half = 0.5 * total_ * cell_;
    if (std::abs(u) >= half || std::abs(v) >= half) return -1.0;
    const int c = static_cast<int>(std::floor((u + half) / cell_));
    const int r = static_cast<int>(std::floor((half - v) / cell_));
    return cells_[std::min(r, total_ - 1) * total_ + std::min(c, total_ - 1)] ? bright_ : dark_;
  }
  Pattern AsPattern() const {
    return [this](double u, double v) { return (*this)(u, v); };
  }
  double half_extent() const { return 0.5 * total_ * cell_; }

 private:
  double bright_, dark_;
  int total_ = 10;
  double cell_ = 0.1;
  std::vector<char> cells_;
};

struct RenderOptions {
  double background = 0.45;     // reflectance outside the plate
  double gain = 240.0;          // [DN] per unit reflectance
  double offset = 8.0;          // [DN]
  double read_noise = 0.0;      // [DN]
  double photons_per_dn = 0.0;  // shot noise: variance I / photons_per_dn (0 = none)
  int supersampling = 16;
  unsigned int seed = 1;
};

// Renders the plate into `image` (CV_32F, values in DN before noise); only
// pixels within the projected plate's bounding box are touched.
inline void RenderPlate(cv::Mat* image, const Eigen::Matrix3d& plane_to_pixel,
                        const Pattern& pattern, double plate_half_extent, const RenderOptions& o) {
  const Eigen::Matrix3d inv = plane_to_pixel.inverse();
  double xmin = 1e9, xmax = -1e9, ymin = 1e9, ymax = -1e9;
  for (int k = 0; k < 4; ++k) {
    const Eigen::Vector2d p = Apply(plane_to_pixel, (k & 1 ? 1 : -1) * plate_half_extent,
                                    (k & 2 ? 1 : -1) * plate_half_extent);
    xmin = std::min(xmin, p.x());
    xmax = std::max(xmax, p.x());
    ymin = std::min(ymin, p.y());
    ymax = std::max(ymax, p.y());
  }
  auto refl = [&](double x, double y) {
    const Eigen::Vector3d q = inv * Eigen::Vector3d(x, y, 1.0);
    const double r = pattern(q.x() / q.z(), q.y() / q.z());
    return r < 0 ? o.background : r;
  };
  const int n = o.supersampling;
  for (int r = std::max(0, int(std::floor(ymin)) - 1);
       r <= std::min(image->rows - 1, int(std::ceil(ymax)) + 1); ++r) {
    float* row = image->ptr<float>(r);
    for (int c = std::max(0, int(std::floor(xmin)) - 1);
         c <= std::min(image->cols - 1, int(std::ceil(xmax)) + 1); ++c) {
      const double first = refl(c - 0.5, r - 0.5);
      bool uniform = true;
      for (int j = 0; j < 5 && uniform; ++j)
        for (int i = 0; i < 5 && uniform; ++i)
          uniform = refl(c - 0.5 + 0.25 * i, r - 0.5 + 0.25 * j) == first;
      double value = first;
      if (!uniform) {
        double sum = 0;
        for (int j = 0; j < n; ++j)
          for (int i = 0; i < n; ++i) sum += refl(c - 0.5 + (i + 0.5) / n, r - 0.5 + (j + 0.5) / n);
        value = sum / (n * n);
      }
      row[c] = static_cast<float>(o.offset + o.gain * value);
    }
  }
}

// A float image of the background level.
inline cv::Mat Background(int width, int height, const RenderOptions& o) {
  return cv::Mat(height, width, CV_32F, cv::Scalar(o.offset + o.gain * o.background));
}

// Adds noise and rounds to mono8.
inline cv::Mat ToMono8(const cv::Mat& f, const RenderOptions& o) {
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> g(0.0, 1.0);
  cv::Mat out(f.size(), CV_8U);
  for (int r = 0; r < f.rows; ++r) {
    const float* in = f.ptr<float>(r);
    uint8_t* dst = out.ptr<uint8_t>(r);
    for (int c = 0; c < f.cols; ++c) {
      double v = in[c];
      const double var =
          o.read_noise * o.read_noise + (o.photons_per_dn > 0 ? v / o.photons_per_dn : 0.0);
      if (var > 0) v += std::sqrt(var) * g(rng);
      dst[c] = static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L));
    }
  }
  return out;
}

// A camera looking straight down from `height` above the origin (nadir,
// angles 0), focal length `focal` px, image width x height px.
inline camera::CameraModel NadirCamera(int width, int height, double focal) {
  camera::Sensor s;
  s.width = width;
  s.height = height;
  s.pixel_size = 1.0;
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = focal;
  return camera::CameraModel(s, camera::DistortionModel::kNone, interior);
}

// A plate at `centre` (on z = 0) tilted by `tilt` [rad] about an in-plane
// axis at azimuth `azimuth` [rad], rotated in its plane by `spin` [rad].
inline Plate TiltedPlate(const Eigen::Vector3d& centre, double tilt, double azimuth, double spin) {
  const Eigen::Vector3d axis(std::cos(azimuth), std::sin(azimuth), 0.0);
  const Eigen::Matrix3d r = Eigen::AngleAxisd(tilt, axis).toRotationMatrix() *
                            Eigen::AngleAxisd(spin, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Plate p;
  p.centre = centre;
  p.right = r * Eigen::Vector3d::UnitX();
  p.up = r * Eigen::Vector3d::UnitY();
  return p;
}

}  // namespace testing
}  // namespace targets
}  // namespace slope_monitor
