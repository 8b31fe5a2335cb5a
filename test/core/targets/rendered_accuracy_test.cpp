// Accuracy of the centroider against exact renders (planar_target_renderer.h):
// AprilTag and circular targets 15, 20, 30, 45 and 60 px across, tilted 0,
// 20, 40 and 60 degrees, noise free and with realistic noise. Prints one
// table per target type and noise level (RMS centre error per coordinate,
// targets measured / rendered, normalised error) and checks:
//   * circles: every one measured; RMS <= 0.02 px in every cell;
//   * tags: every one of 30 px and more measured, and of 20 px up to 40 deg;
//     RMS <= 0.05 px in every cell where any was measured by the edge model
//     (tags whose edge-fit residual is over tag_refine_max_residual keep
//     libapriltag's corners: within 0.5 px, their RMS printed apart); every tag that
//     libapriltag detects is measured (none rejected by the refinement).
//     Smaller or more oblique tags (cells under ~1.5 px across) are detected
//     by libapriltag only in part: the rate per cell and the reason of every
//     miss are printed;
//   * the published covariance is consistent with the actual error: the
//     normalised error, RMS over the images of sqrt(e^T C^-1 e / 2) (1 for a
//     perfect covariance), is in [0.5, 2] over the noisy images of each size.
#include <cstdio>
#include <map>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "planar_target_renderer.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

using testing::Apply;
using testing::Plate;

constexpr double kAccuracyFocal = 500.0;  // [px] short focal length: strong perspective
constexpr double kAccuracyHeight = 10.0;  // [m] camera above the plate
constexpr int kTrials = 5;                // random sub-pixel positions / azimuths per cell
const std::vector<double> kSizes = {
    15.0, 20.0, 30.0, 45.0, 60.0};  // [px] tag border edge / disc diameter, facing the camera
const std::vector<double> kTiltsDeg = {0.0, 20.0, 40.0, 60.0};

struct Case {
  bool circle;
  bool noisy;
};

struct Stats {
  double sum_sq = 0;   // squared error per coordinate, summed
  double sum_nee = 0;  // e^T C^-1 e / 2, summed
  int n = 0;
  int rendered = 0;
  int by_detector = 0;  // tags measured with libapriltag's corners (not in sum_sq / n)
  void Add(const Stats& o) {
    by_detector += o.by_detector;
    sum_sq += o.sum_sq;
    sum_nee += o.sum_nee;
    n += o.n;
    rendered += o.rendered;
  }
  double Rms() const { return std::sqrt(sum_sq / std::max(1, n)); }
  double Nee() const { return std::sqrt(sum_nee / std::max(1, n)); }
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

Options CaseOptions(const Case& c) {
  Options opt;
  opt.quad_decimate = 1.0;
  opt.detect_circles = c.circle;
  if (c.circle) opt.families.clear();
  return opt;
}

// Renders one target and returns the error of the matching observation.
// `tag_centroider` measures tags (made once: building libapriltag's decode
// tables is slow); circles need the plate's position and normal in the
// target list, so their centroider is made per image (cheap without tags).
bool RunOne(const Case& c, double size_px, double tilt, const TargetCentroider* tag_centroider,
            std::mt19937* rng, Eigen::Vector2d* error, Eigen::Matrix2d* cov, std::string* why_not,
            CentreMethod* method) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double size_m = size_px * kAccuracyHeight / kAccuracyFocal;
  const double plate_half_px = (c.circle ? 1.0 : 0.625) * size_px;
  const int w = static_cast<int>(2 * (plate_half_px + 40)) + 1;
  const camera::CameraModel cam = testing::NadirCamera(w, w, kAccuracyFocal);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, kAccuracyHeight);
  // Off-axis by 15 px plus a random sub-pixel part.
  const Eigen::Vector3d centre((15.0 + uni(*rng)) * kAccuracyHeight / kAccuracyFocal,
                               (10.0 + uni(*rng)) * kAccuracyHeight / kAccuracyFocal, 0.0);
  const Plate plate =
      testing::TiltedPlate(centre, tilt, 2 * M_PI * uni(*rng), 2 * M_PI * uni(*rng));
  const Eigen::Matrix3d h = testing::PlaneToPixel(cam, pose, plate);
  const testing::RenderOptions ro = NoiseOptions(c.noisy, static_cast<unsigned>((*rng)()));
  cv::Mat f = testing::Background(w, w, ro);
  if (c.circle) {
    testing::RenderPlate(&f, h, testing::CirclePattern(size_m), size_m, ro);
  } else {
    testing::TagPattern tag(7, size_m);
    testing::RenderPlate(&f, h, tag.AsPattern(), tag.half_extent(), ro);
  }
  const cv::Mat img = testing::ToMono8(f, ro);

  io::TargetSpec spec;
  spec.id = c.circle ? 5 : 7;
  spec.family = c.circle ? "circle" : "tag36h11";
  spec.size = size_m;
  spec.role = io::TargetRole::kMonitoring;
  spec.position = plate.centre;
  spec.normal = plate.Normal();
  std::unique_ptr<TargetCentroider> circle_centroider;
  const TargetCentroider* centroider = tag_centroider;
  if (c.circle) {
    io::TargetList list;
    list.Add(spec);
    circle_centroider = std::make_unique<TargetCentroider>(CaseOptions(c), list);
    centroider = circle_centroider.get();
  }
  ViewGeometry view{cam, pose};
  const Result r = centroider->Detect(img, "mono8", &view);
  const Eigen::Vector2d truth = Apply(h, 0.0, 0.0);
  for (const auto& o : r.observations) {
    if (o.family != spec.family || o.id != spec.id) continue;
    *error = o.centre - truth;
    *method = o.method;
    *cov = o.covariance;
    return true;
  }
  *why_not = c.circle ? "not detected" : "not detected by libapriltag";
  for (const auto& rj : r.rejections) {
    if (rj.family == spec.family)
      *why_not = "rejected: " + RejectReasonName(rj.reason) + " (" + rj.detail + ")";
  }
  return false;
}

TEST(RenderedAccuracy, CirclesAndTagsMeetTheTargets) {
  std::mt19937 rng(20261122);
  for (const Case c :
       {Case{true, false}, Case{true, true}, Case{false, false}, Case{false, true}}) {
    const char* what = c.circle ? "circle" : "tag";
    const char* noise = c.noisy ? "noisy" : "noise-free";
    const double limit = c.circle ? 0.02 : 0.05;
    std::unique_ptr<TargetCentroider> tags;
    if (!c.circle) {
      io::TargetList list;
      io::TargetSpec spec;
      spec.id = 7;
      spec.family = "tag36h11";
      spec.size = 1.0;
      list.Add(spec);
      tags = std::make_unique<TargetCentroider>(CaseOptions(c), list);
    }
    std::printf(
        "\n%s centres, %s: RMS error per coordinate [px] (measured/rendered) normalised error; "
        "limit %.2f px\n",
        what, noise, limit);
    std::printf("  size \\ tilt |");
    for (double t : kTiltsDeg) std::printf("        %2.0f deg        |", t);
    std::printf("  all tilts\n");
    Stats all;
    std::vector<std::string> misses;
    Stats
        by_detector;  // tags whose edge model did not explain the pixels (tag_refine_max_residual)
    for (double size : kSizes) {
      std::printf("  %5.0f px   |", size);
      Stats row;
      for (double tilt_deg : kTiltsDeg) {
        Stats s;
        for (int t = 0; t < kTrials; ++t) {
          ++s.rendered;
          Eigen::Vector2d e;
          Eigen::Matrix2d cov;
          std::string why_not;
          CentreMethod method = CentreMethod::kDetector;
          if (!RunOne(c, size, tilt_deg * M_PI / 180.0, tags.get(), &rng, &e, &cov, &why_not,
                      &method)) {
            char buf[64];
            std::snprintf(buf, sizeof(buf), "%2.0f px, %2.0f deg: ", size, tilt_deg);
            misses.push_back(buf + why_not);
            continue;
          }
          if (!c.circle && method == CentreMethod::kDetector) {
            // libapriltag's corners: counted as measured, accuracy reported apart.
            by_detector.sum_sq += e.squaredNorm() / 2.0;
            ++by_detector.n;
            ++s.by_detector;
            EXPECT_LE(e.norm(), 0.5)
                << what << " " << noise << " size " << size << " tilt " << tilt_deg;
            continue;
          }
          s.sum_sq += e.squaredNorm() / 2.0;
          s.sum_nee += e.dot(cov.inverse() * e) / 2.0;
          ++s.n;
        }
        if (s.n > 0) {
          std::printf(" %.4f (%d/%d) %5.2f |", s.Rms(), s.n, s.rendered, s.Nee());
        } else {
          std::printf("   -    (%d/%d)   -   |", s.n, s.rendered);
        }
        // Accuracy wherever anything was measured; completeness for every
        // circle and every tag of 20 px and more.
        if (s.n > 0) {
          EXPECT_LE(s.Rms(), limit)
              << what << " " << noise << " size " << size << " tilt " << tilt_deg;
        }
        if (c.circle || size >= 30 || (size >= 20 && tilt_deg <= 40)) {
          EXPECT_EQ(s.n + s.by_detector, s.rendered)
              << what << " " << noise << " size " << size << " tilt " << tilt_deg;
        }
        row.Add(s);
      }
      std::printf(" %.4f (%d/%d) %5.2f\n", row.Rms(), row.n, row.rendered, row.Nee());
      if (c.noisy && row.n >= 10) {
        EXPECT_GE(row.Nee(), 0.5) << what << " size " << size;
        EXPECT_LE(row.Nee(), 2.0) << what << " size " << size;
      }
      all.Add(row);
    }
    std::printf("  all        | RMS %.4f px over %d of %d targets, normalised error %.2f\n",
                all.Rms(), all.n, all.rendered, all.Nee());
    if (by_detector.n > 0) {
      std::printf(
          "  detector's corners (edge residual over tag_refine_max_residual): %d tags, centre RMS "
          "%.4f px\n",
          by_detector.n, by_detector.Rms());
    }
    for (const auto& m : misses) {
      std::printf("  missed %s\n", m.c_str());
      // Every target the detector finds is measured: a miss is libapriltag's.
      EXPECT_EQ(m.find("rejected"), std::string::npos) << what << " " << noise << ": " << m;
    }
    EXPECT_LE(all.Rms(), limit);
    if (c.noisy) {
      EXPECT_GE(all.Nee(), 0.5);
      EXPECT_LE(all.Nee(), 2.0);
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
