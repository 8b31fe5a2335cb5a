// Test renderer of every circle design (targets::CircleDesign) seen by a
// pinhole camera: exact, area-correct renders (planar_target_renderer.h) of
// a design's plate, optionally tilted and off-axis (perspective), blurred by
// a Gaussian (optical blur, applied to the pixel-integrated image) and with
// realistic noise; returns the image, the truth (the projected centre of the
// light centre) and the view and target list a user with a pose would give,
// so the centroider can identify the target and remove the perspective bias.
//
// Designs (radii of the light centre, reflectance 0.9 light / 0.08 dark):
//   disc_in_ring  light disc, dark ring to 2 radii, on a 0.45 grey ground;
//   dot           light dot on a dark plate of 5 radii, on a light ground;
//   ring          dark ring to 1.6 radii on a light ground;
//   concentric    dark ring to 1.4, light ring to 1.8, dark ring to 2.3 radii
//                 on a light ground.
//
// Used by designs_rendered_test.cpp, design_sweep_test.cpp and
// bench/targets_design_sweep.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "planar_target_renderer.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace testing {

constexpr double kDesignBright = 0.9, kDesignDark = 0.08;

struct DesignCase {
  CircleDesign design;
  double background;   // reflectance of the ground around the plate
  double plate_radii;  // plate half extent in light-centre radii
};

inline const std::vector<DesignCase>& DesignCases() {
  static const std::vector<DesignCase> c = {{CircleDesign::kDiscInRing, 0.45, 2.0},
                                            {CircleDesign::kDot, kDesignBright, 5.0},
                                            {CircleDesign::kRing, kDesignBright, 1.6},
                                            {CircleDesign::kConcentric, kDesignBright, 2.3}};
  return c;
}

inline const DesignCase& DesignCaseOf(CircleDesign d) {
  for (const DesignCase& c : DesignCases())
    if (c.design == d) return c;
  return DesignCases()[0];
}

// The plate pattern of a design; r: radius of the light centre [m].
inline Pattern DesignPattern(const DesignCase& dc, double r) {
  return [=](double u, double v) {
    const double s = std::sqrt(u * u + v * v) / r;
    if (s <= 1.0) return kDesignBright;
    switch (dc.design) {
      case CircleDesign::kDiscInRing:
        return s <= 2.0 ? kDesignDark : -1.0;
      case CircleDesign::kDot:
        return s <= dc.plate_radii ? kDesignDark : -1.0;
      case CircleDesign::kRing:
        return s <= 1.6 ? kDesignDark : -1.0;
      case CircleDesign::kConcentric:
        return s <= 1.4 ? kDesignDark : s <= 1.8 ? kDesignBright : s <= 2.3 ? kDesignDark : -1.0;
      default:
        return -1.0;
    }
  };
}

// One render: a design, the light centre's apparent diameter (the major axis
// of its image) [px], the plate's obliquity (its normal tilted away from the
// line of sight about a random axis), the direction of the plate off the
// optical axis, optical blur and noise.
struct DesignShotSpec {
  CircleDesign design = CircleDesign::kDiscInRing;
  double centre_px = 30.0;    // [px] light-centre diameter: the major axis of its image
  double tilt_deg = 0.0;      // [deg] obliquity: plate normal vs the line of sight
  double off_axis_deg = 0.0;  // [deg] plate centre off the optical axis
  double blur_px = 0.0;       // [px] Gaussian optical blur sigma (0: the pixel area only)
  bool noisy = true;          // read noise 1 DN + shot noise (50 photons / DN)
  unsigned seed = 1;          // sub-pixel position, tilt azimuth, spin, noise
};

struct DesignShot {
  cv::Mat image;                // mono8
  Eigen::Vector2d truth{0, 0};  // [px] projected centre of the light centre
  camera::CameraModel camera;
  camera::ExteriorOrientation pose;
  io::TargetList list;  // the plate as circle/1 (position, normal, size)
};

constexpr double kDesignShotFocal = 500.0;  // [px]
constexpr double kDesignShotHeight = 10.0;  // [m]

// Renders one shot. The image is a crop around the plate: the principal
// point is moved so that the off-axis plate lands in the middle of it (the
// geometry is that of a plate `off_axis_deg` off the axis of a larger image).
inline DesignShot RenderDesignShot(const DesignShotSpec& s) {
  const DesignCase& dc = DesignCaseOf(s.design);
  std::mt19937 rng(s.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double r_px = 0.5 * s.centre_px;
  const double blur_margin = 4.0 * s.blur_px;
  const int size = static_cast<int>(2 * (dc.plate_radii + 1.0) * r_px + 2 * blur_margin + 24) | 1;
  // Plate centre: off the axis by off_axis_deg at a random azimuth, plus a
  // random sub-pixel part.
  const double off = kDesignShotFocal * std::tan(s.off_axis_deg * M_PI / 180.0);
  const double az = 2 * M_PI * uni(rng);
  const double ox = off * std::cos(az) + uni(rng), oy = off * std::sin(az) + uni(rng);
  const double depth = kDesignShotHeight / kDesignShotFocal;  // [m] per px on the ground
  // The plate's normal: the line of sight to the camera, tilted by tilt_deg
  // about a random axis across it; spun in its plane at random.
  Plate plate;
  plate.centre = Eigen::Vector3d(ox * depth, oy * depth, 0.0);
  const Eigen::Vector3d los =
      (Eigen::Vector3d(0, 0, kDesignShotHeight) - plate.centre).normalized();
  const Eigen::Vector3d e1 = los.unitOrthogonal(), e2 = los.cross(e1);
  const double tilt_az = 2 * M_PI * uni(rng), spin = 2 * M_PI * uni(rng);
  const Eigen::Matrix3d tilt =
      Eigen::AngleAxisd(s.tilt_deg * M_PI / 180.0, std::cos(tilt_az) * e1 + std::sin(tilt_az) * e2)
          .toRotationMatrix();
  plate.right = tilt * (std::cos(spin) * e1 + std::sin(spin) * e2);
  plate.up = tilt * los.cross(std::cos(spin) * e1 + std::sin(spin) * e2);
  // Principal point offset: the plate centre projects to the crop's middle
  // (to within the random sub-pixel part). Nadir camera: ground (X, Y)
  // projects to x = -c X / (-H) = c X / H, y likewise.
  camera::Sensor sensor;
  sensor.width = sensor.height = size;
  sensor.pixel_size = 1.0;
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = kDesignShotFocal;
  interior[camera::kX0] = -std::floor(ox);
  interior[camera::kY0] = -std::floor(oy);
  DesignShot out{cv::Mat(), Eigen::Vector2d::Zero(),
                 camera::CameraModel(sensor, camera::DistortionModel::kNone, interior),
                 camera::ExteriorOrientation(), io::TargetList()};
  out.pose.position = Eigen::Vector3d(0, 0, kDesignShotHeight);
  RenderOptions ro;
  ro.background = dc.background;
  ro.seed = static_cast<unsigned>(rng());
  if (s.noisy) {
    ro.read_noise = 1.0;
    ro.photons_per_dn = 50.0;
  }
  cv::Mat f = Background(size, size, ro);
  const Eigen::Matrix3d h = PlaneToPixel(out.camera, out.pose, plate);
  // The light centre's radius on the plate such that its image's major axis
  // is centre_px (off the axis and tilted, the image is larger or smaller
  // than facing the camera): the widest pair of 72 rim points' images.
  const double r0 = r_px * depth;  // [m] facing the camera on the axis
  double widest = 0.0;
  for (int i = 0; i < 72; ++i) {
    for (int j = i + 1; j < 72; ++j) {
      const double ai = 2 * M_PI * i / 72, aj = 2 * M_PI * j / 72;
      widest = std::max(widest, (Apply(h, r0 * std::cos(ai), r0 * std::sin(ai)) -
                                 Apply(h, r0 * std::cos(aj), r0 * std::sin(aj)))
                                    .norm());
    }
  }
  const double r = r0 * s.centre_px / widest;  // [m]
  RenderPlate(&f, h, DesignPattern(dc, r), dc.plate_radii * r, ro);
  if (s.blur_px > 0.0)
    cv::GaussianBlur(f, f, cv::Size(0, 0), s.blur_px, s.blur_px, cv::BORDER_REPLICATE);
  out.image = ToMono8(f, ro);
  out.truth = Apply(h, 0.0, 0.0);
  io::TargetSpec spec;
  spec.id = 1;
  spec.family = "circle";
  spec.size = 2.0 * r;
  spec.role = io::TargetRole::kMonitoring;
  spec.position = plate.centre;
  spec.normal = plate.Normal();
  out.list.Add(spec);
  return out;
}

// Errors of a set of measured centres: RMS per coordinate, and the median of
// |error| / sigma per coordinate (sigma from the covariance's diagonal; 0.674
// for an honest Gaussian covariance).
struct CentreErrors {
  double sum_sq = 0.0;
  std::vector<double> z;  // |e_x| / sigma_x and |e_y| / sigma_y
  int rendered = 0;
  void Add(const Eigen::Vector2d& e, const Eigen::Matrix2d& cov) {
    sum_sq += e.squaredNorm();
    z.push_back(std::abs(e.x()) / std::sqrt(std::max(cov(0, 0), 1e-30)));
    z.push_back(std::abs(e.y()) / std::sqrt(std::max(cov(1, 1), 1e-30)));
  }
  void Add(const CentreErrors& o) {
    sum_sq += o.sum_sq;
    z.insert(z.end(), o.z.begin(), o.z.end());
    rendered += o.rendered;
  }
  int measured() const { return static_cast<int>(z.size() / 2); }
  double Rms() const { return z.empty() ? 0.0 : std::sqrt(sum_sq / z.size()); }
  double MedianZ() const {
    if (z.empty()) return 0.0;
    std::vector<double> s = z;
    std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
    return s[s.size() / 2];
  }
};

}  // namespace testing
}  // namespace targets
}  // namespace slope_monitor
