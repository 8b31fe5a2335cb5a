// Accuracy of the centroider against exact renders (planar_target_renderer.h):
// AprilTag and circular targets 15-60 px across, tilted 0-60 degrees, noise
// free and with realistic noise. Prints the RMS centre error per size and
// angle, and checks RMS <= 0.02 px (circles) / 0.05 px (tag centres) and the
// normalised error e^T C^-1 e / 2 of the published covariance in [0.5, 2]
// (over the noisy images, where the covariance has noise to describe).
#include <cstdio>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "planar_target_renderer.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

using testing::Apply;
using testing::Plate;

constexpr double kFocal = 500.0;      // [px] short focal length: strong perspective
constexpr double kHeight = 10.0;      // [m] camera above the plate
constexpr int kTrials = 4;            // random sub-pixel positions / azimuths per case
const double kSizes[] = {15.0, 30.0, 60.0};       // [px] tag border edge / disc diameter, facing the camera
const double kTiltsDeg[] = {0.0, 30.0, 45.0, 60.0};

struct Case {
  bool circle;
  bool noisy;
};

struct Stats {
  double sum_sq = 0;
  double nee = 0;
  int n = 0;
  int missing = 0;
};

testing::RenderOptions NoiseOptions(bool noisy, unsigned seed) {
  testing::RenderOptions o;
  o.seed = seed;
  if (noisy) {
    o.read_noise = 1.0;       // [DN]
    o.photons_per_dn = 50.0;  // sigma 2.3 DN at the white level
  }
  return o;
}

// Renders one target and returns the error of the matching observation.
bool RunOne(const Case& c, double size_px, double tilt, std::mt19937* rng, Eigen::Vector2d* error,
            Eigen::Matrix2d* cov) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double size_m = size_px * kHeight / kFocal;
  const double plate_half_px = (c.circle ? 1.0 : 0.625) * size_px;
  const int w = static_cast<int>(2 * (plate_half_px + 40)) + 1;
  const camera::CameraModel cam = testing::NadirCamera(w, w, kFocal);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, kHeight);
  // Off-axis by 15 px plus a random sub-pixel part.
  const Eigen::Vector3d centre((15.0 + uni(*rng)) * kHeight / kFocal, (10.0 + uni(*rng)) * kHeight / kFocal, 0.0);
  const Plate plate = testing::TiltedPlate(centre, tilt, 2 * M_PI * uni(*rng), 2 * M_PI * uni(*rng));
  const Eigen::Matrix3d h = testing::PlaneToPixel(cam, pose, plate);
  const testing::RenderOptions ro = NoiseOptions(c.noisy, static_cast<unsigned>((*rng)()));
  cv::Mat f = testing::Background(w, w, ro);
  testing::TagPattern tag(7, size_m);
  if (c.circle) {
    testing::RenderPlate(&f, h, testing::CirclePattern(size_m), size_m, ro);
  } else {
    testing::RenderPlate(&f, h, tag.AsPattern(), tag.half_extent(), ro);
  }
  const cv::Mat img = testing::ToMono8(f, ro);

  io::TargetList list;
  io::TargetSpec spec;
  spec.id = c.circle ? 5 : 7;
  spec.family = c.circle ? "circle" : "tag36h11";
  spec.size = size_m;
  spec.role = io::TargetRole::kMonitoring;
  spec.position = plate.centre;
  spec.normal = plate.Normal();
  list.Add(spec);
  Options opt;
  opt.quad_decimate = 1.0;
  opt.detect_circles = c.circle;
  if (c.circle) opt.families.clear();
  TargetCentroider centroider(opt, list);
  ViewGeometry view{cam, pose};
  const Result r = centroider.Detect(img, "mono8", &view);
  const Eigen::Vector2d truth = Apply(h, 0.0, 0.0);
  for (const auto& o : r.observations) {
    if (o.family != spec.family || o.id != spec.id) continue;
    *error = o.centre - truth;
    *cov = o.covariance;
    return true;
  }
  for (const auto& rj : r.rejections) std::printf("  rejected %s/%d: %s (%s)\n", rj.family.c_str(), rj.id, RejectReasonName(rj.reason).c_str(), rj.detail.c_str());
  return false;
}

TEST(RenderedAccuracy, CirclesAndTagsMeetTheTargets) {
  std::mt19937 rng(20261122);
  for (const Case c : {Case{true, false}, Case{true, true}, Case{false, false}, Case{false, true}}) {
    const double limit = c.circle ? 0.02 : 0.05;
    Stats all;
    for (double size : kSizes) {
      for (double tilt_deg : kTiltsDeg) {
        Stats s;
        for (int t = 0; t < kTrials; ++t) {
          Eigen::Vector2d e;
          Eigen::Matrix2d cov;
          if (!RunOne(c, size, tilt_deg * M_PI / 180.0, &rng, &e, &cov)) {
            ++s.missing;
            continue;
          }
          s.sum_sq += e.squaredNorm() / 2.0;  // per coordinate
          s.nee += e.dot(cov.inverse() * e) / 2.0;
          ++s.n;
        }
        std::printf("%-6s %-10s size %4.0f px tilt %2.0f deg: RMS %.4f px per coordinate, NEE %.2f, found %d/%d\n",
                    c.circle ? "circle" : "tag", c.noisy ? "noisy" : "noise-free", size, tilt_deg,
                    std::sqrt(s.sum_sq / std::max(1, s.n)), s.nee / std::max(1, s.n), s.n, kTrials);
        // Known limitation: 15 px tags (cells under 2 px) are measured only in
        // part (edge fits on 1-cell borders fail); every larger one must be.
        if (c.circle || size >= 30) {
          EXPECT_EQ(s.missing, 0) << (c.circle ? "circle" : "tag") << " size " << size << " tilt " << tilt_deg;
        }
        all.sum_sq += s.sum_sq;
        all.nee += s.nee;
        all.n += s.n;
      }
    }
    const double rms = std::sqrt(all.sum_sq / std::max(1, all.n));
    const double nee = all.nee / std::max(1, all.n);
    std::printf("%-6s %-10s ALL: RMS %.4f px per coordinate (limit %.2f), NEE %.2f over %d targets\n",
                c.circle ? "circle" : "tag", c.noisy ? "noisy" : "noise-free", rms, limit, nee, all.n);
    EXPECT_LE(rms, limit);
    if (c.noisy) {
      EXPECT_GE(nee, 0.5);
      EXPECT_LE(nee, 2.0);
    }
  }
}

// The test renderer's homography agrees with the camera model.
TEST(RenderedAccuracy, RendererHomographyMatchesCameraModel) {
  const camera::CameraModel cam = testing::NadirCamera(201, 151, 700.0);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0.3, -0.2, 8.0);
  pose.angles.theta = 0.1;
  pose.angles.phi = -0.05;
  pose.angles.kappa = 0.3;
  const Plate plate = testing::TiltedPlate(Eigen::Vector3d(0.5, 0.1, 0.2), 0.7, 0.4, 1.1);
  const Eigen::Matrix3d h = testing::PlaneToPixel(cam, pose, plate);
  for (double u : {-0.3, 0.0, 0.2}) {
    for (double v : {-0.1, 0.25}) {
      Eigen::Vector2d px;
      ASSERT_TRUE(cam.Project(pose, plate.At(u, v), &px));
      EXPECT_NEAR((Apply(h, u, v) - px).norm(), 0.0, 1e-9);
    }
  }
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
