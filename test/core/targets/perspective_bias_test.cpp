// The perspective bias of circle centres: the centre of the imaged ellipse
// is not the image of the circle's centre. Exact renders
// (planar_target_renderer.h) of circular targets 30, 45 and 60 px across,
// tilted 60 degrees, at 4 azimuths, seen by a short-focal camera (strong
// perspective) with realistic noise; measured with the defaults a user gets,
// once with the correction (correct_perspective, the default: from the
// camera model, the pose and the listed position and normal) and once
// without. Prints both errors against the render truth and the size of the
// correction, and checks:
//   * every circle measured and identified, the correction applied;
//   * corrected: RMS error per coordinate <= 0.02 px (the accuracy target of
//     rendered_accuracy_test);
//   * uncorrected: the error is the bias (RMS > 0.05 px here) and the
//     reported correction equals the difference of the two centres.
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include "planar_target_renderer.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

constexpr double kBiasFocal = 400.0;  // [px]
constexpr double kBiasHeight = 10.0;  // [m]

struct Measured {
  Eigen::Vector2d error{0, 0};       // centre - truth [px]
  Eigen::Vector2d correction{0, 0};  // reported perspective correction [px]
  bool corrected = false;
};

// Renders one target and measures it with and without the correction.
bool Measure(double size_px, double azimuth, unsigned seed, Measured* with, Measured* without) {
  const double size_m = size_px * kBiasHeight / kBiasFocal;
  const int w = static_cast<int>(4 * size_px + 200) | 1;
  const camera::CameraModel cam = testing::NadirCamera(w, w, kBiasFocal);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, kBiasHeight);
  // Off-axis (the bias grows with the distance from the principal point).
  const Eigen::Vector3d centre(0.3 * w * kBiasHeight / kBiasFocal * std::cos(azimuth + 1.0),
                               0.3 * w * kBiasHeight / kBiasFocal * std::sin(azimuth + 1.0), 0.0);
  const testing::Plate plate = testing::TiltedPlate(centre, 60.0 * M_PI / 180.0, azimuth, 0.3);
  const Eigen::Matrix3d h = testing::PlaneToPixel(cam, pose, plate);
  testing::RenderOptions ro;
  ro.read_noise = 1.0;
  ro.photons_per_dn = 50.0;
  ro.seed = seed;
  cv::Mat f = testing::Background(w, w, ro);
  testing::RenderPlate(&f, h, testing::CirclePattern(size_m), size_m, ro);
  const cv::Mat img = testing::ToMono8(f, ro);
  io::TargetSpec spec;
  spec.id = 3;
  spec.family = "circle";
  spec.size = size_m;
  spec.role = io::TargetRole::kMonitoring;
  spec.position = plate.centre;
  spec.normal = plate.Normal();
  io::TargetList list;
  list.Add(spec);
  const ViewGeometry view{cam, pose};
  for (const bool correct : {true, false}) {
    Options o;           // the defaults a user gets, without tag families (no tag here;
    o.families.clear();  // libapriltag's decode tables take a while to build)
    o.correct_perspective = correct;
    const TargetCentroider centroider(o, list);
    const Result r = centroider.Detect(img, "mono8", &view);
    for (const auto& rj : r.rejections) std::printf("  rejected: %s\n", rj.detail.c_str());
    if (r.observations.size() != 1u || r.observations[0].id != 3) return false;
    Measured* m = correct ? with : without;
    m->error = r.observations[0].centre - testing::Apply(h, 0.0, 0.0);
    m->correction = r.observations[0].perspective_correction;
    m->corrected = r.observations[0].perspective_corrected;
  }
  return true;
}

TEST(PerspectiveBias, CorrectionRemovesTheBiasAt60Degrees) {
  std::printf("circles tilted 60 deg, focal %.0f px: RMS error per coordinate [px]\n", kBiasFocal);
  std::printf("  size | without correction | with correction | mean |correction|\n");
  double sum_with = 0, sum_without = 0;
  int n = 0;
  for (double size : {30.0, 45.0, 60.0}) {
    double s_with = 0, s_without = 0, s_corr = 0;
    int k = 0;
    for (int a = 0; a < 4; ++a) {
      const double azimuth = 2 * M_PI * a / 4 + 0.4;
      const unsigned seed = 100 + 10 * a + static_cast<unsigned>(size);
      Measured with, without;
      ASSERT_TRUE(Measure(size, azimuth, seed, &with, &without)) << size << " px, azimuth " << a;
      EXPECT_TRUE(with.corrected);
      EXPECT_FALSE(without.corrected);
      EXPECT_EQ(without.correction.norm(), 0.0);
      // The same image: the two centres differ by the reported correction.
      EXPECT_NEAR((without.error - with.error - with.correction).norm(), 0.0, 1e-9);
      s_with += with.error.squaredNorm() / 2;
      s_without += without.error.squaredNorm() / 2;
      s_corr += with.correction.norm();
      ++k;
    }
    std::printf("  %4.0f | %18.4f | %15.4f | %.4f\n", size, std::sqrt(s_without / k),
                std::sqrt(s_with / k), s_corr / k);
    EXPECT_LE(std::sqrt(s_with / k), 0.02) << size << " px";
    sum_with += s_with;
    sum_without += s_without;
    n += k;
  }
  const double rms_with = std::sqrt(sum_with / n), rms_without = std::sqrt(sum_without / n);
  std::printf("  all  | %18.4f | %15.4f |\n", rms_without, rms_with);
  EXPECT_LE(rms_with, 0.02);
  EXPECT_GT(rms_without, 0.05);
  EXPECT_LT(rms_with, 0.5 * rms_without);
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
