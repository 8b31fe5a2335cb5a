// adjustment::ReorientCamera (issue 19): the change of attitude of a fixed
// camera from tie points on stable ground.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "slope_monitor/core/adjustment/reorient_camera.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace {

constexpr double kDeg = M_PI / 180.0;

camera::CameraModel ReorientTestCamera() {
  camera::Sensor s;
  s.width = 4000;
  s.height = 3000;
  s.pixel_size = 0.004;
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 16.0;
  in[camera::kK1] = -2e-4;
  return camera::CameraModel(s, camera::DistortionModel::kRadial, in);
}

// The mast rotates by a random 0.02-0.2 deg between epochs (random axis); the
// stable ground's tie points are measured with 0.3 px noise, 10 % of them
// mismatched by 5-30 px.
TEST(ReorientCamera, RecoversAKnownMastRotationWithin0002Deg) {
  const camera::CameraModel model = ReorientTestCamera();
  camera::ExteriorOrientation ref;
  ref.position = Eigen::Vector3d(100, 200, 50);
  ref.angles = {0.3, 1.45, 0.02};
  std::mt19937 rng(19);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> g(0, 1);
  for (int epoch = 0; epoch < 5; ++epoch) {
    const double angle = (0.02 + 0.18 * u01(rng)) * kDeg;
    const Eigen::Vector3d axis = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const Eigen::Matrix3d m =
        Eigen::AngleAxisd(angle, axis).toRotationMatrix() * camera::RotationFromAngles(ref.angles);
    camera::ExteriorOrientation moved = ref;
    moved.angles = camera::AnglesFromRotation(m);
    std::vector<adjustment::StableTiePoint> ties;
    for (int i = 0; i < 300; ++i) {
      adjustment::StableTiePoint t;
      t.xa = Eigen::Vector2d(50 + 3900 * u01(rng), 50 + 2900 * u01(rng));
      const camera::Ray ray = model.ImageToRay(ref, t.xa);
      const Eigen::Vector3d x = ray.origin + (100 + 400 * u01(rng)) * ray.direction;
      ASSERT_TRUE(model.Project(moved, x, &t.xb));
      t.xb += 0.3 * Eigen::Vector2d(g(rng), g(rng));
      if (i % 10 == 0) t.xb += (5 + 25 * u01(rng)) * Eigen::Vector2d(g(rng), g(rng)).normalized();
      ties.push_back(t);
    }
    adjustment::ReorientOptions o;
    const auto s = adjustment::ReorientCamera(model, ref, ties, o);
    ASSERT_TRUE(s.success) << s.message;
    SCOPED_TRACE("epoch " + std::to_string(epoch) + ", rotation " + std::to_string(angle / kDeg) +
                 " deg");
    EXPECT_NEAR(s.rotation_angle / kDeg, angle / kDeg, 0.002);
    EXPECT_NEAR(s.exterior.angles.theta / kDeg, moved.angles.theta / kDeg, 0.002);
    EXPECT_NEAR(s.exterior.angles.phi / kDeg, moved.angles.phi / kDeg, 0.002);
    EXPECT_NEAR(s.exterior.angles.kappa / kDeg, moved.angles.kappa / kDeg, 0.002);
    // Every mismatch removed; of the good points at most 1 % (3.3 sigma of a
    // 2-D normal is exceeded with probability 0.4 %).
    for (int i = 0; i < 300; i += 10) EXPECT_FALSE(s.inliers[i]) << i;
    EXPECT_GE(s.num_outliers, 30);
    EXPECT_LE(s.num_outliers, 33);
    EXPECT_NEAR(s.rms_px, 0.3 * std::sqrt(2.0), 0.06);
    // The stated sigmas cover the error (theta and kappa are correlated for
    // a camera looking near horizontally).
    EXPECT_LT(std::abs(s.exterior.angles.theta - moved.angles.theta), 3 * s.sigma(0));
    EXPECT_LT(std::abs(s.exterior.angles.phi - moved.angles.phi), 3 * s.sigma(1));
    EXPECT_LT(std::abs(s.exterior.angles.kappa - moved.angles.kappa), 3 * s.sigma(2));
  }
}

TEST(ReorientCamera, TooFewPointsAndNonFiniteInput) {
  const camera::CameraModel model = ReorientTestCamera();
  camera::ExteriorOrientation ref;
  ref.angles = {0.3, 1.45, 0.02};
  std::vector<adjustment::StableTiePoint> ties(3);
  const auto s = adjustment::ReorientCamera(model, ref, ties, adjustment::ReorientOptions());
  EXPECT_FALSE(s.success);
  EXPECT_NE(s.message.find("too few stable tie points: 3"), std::string::npos) << s.message;
  ties[1].xb.x() = NAN;
  EXPECT_THROW(adjustment::ReorientCamera(model, ref, ties, adjustment::ReorientOptions()),
               InvalidArgument);
}

}  // namespace
}  // namespace slope_monitor
