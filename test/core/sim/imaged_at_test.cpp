// sim::ImagedAt: a point far off the axis that the radial polynomial folds
// back into the image is not imaged (the bench_uav_block_scaling blocks of
// 150 photos had such "observations" 350 m from the photo, which the
// adjustment could not determine); a point in the field of view is, at the
// model's projection.
#include <gtest/gtest.h>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace sim {
namespace {

TEST(ImagedAtTest, PointFoldedBackByTheDistortionIsNotImaged) {
  const camera::Sensor sensor{5472, 3648, 0.0024};
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 8.8;
  interior[camera::kK1] = -1.5e-4;  // [mm^-2]: 1 + k1 r^2 = 0 at r = 81.6 mm
  const camera::CameraModel model(sensor, camera::DistortionModel::kRadial, interior);
  camera::ExteriorOrientation nadir;  // angles 0: looking down
  nadir.position = Eigen::Vector3d(0.0, 0.0, 100.0);

  // Ideal x = 8.8 mm * 944 / 100 = 83.07 mm: distorted to
  // 83.07 (1 - 1.5e-4 * 83.07^2) = -2.9 mm, inside the 13.1 mm wide sensor.
  const Eigen::Vector3d folded(944.0, 0.0, 0.0);
  Eigen::Vector2d px;
  ASSERT_TRUE(model.Project(nadir, folded, &px));
  ASSERT_TRUE(px.x() > 0.0 && px.x() < sensor.width - 1 && px.y() > 0.0 &&
              px.y() < sensor.height - 1)
      << px.transpose();
  EXPECT_FALSE(ImagedAt(model, nadir, folded, 20.0, &px));

  const Eigen::Vector3d seen(10.0, -5.0, 0.0);
  Eigen::Vector2d expected;
  ASSERT_TRUE(model.Project(nadir, seen, &expected));
  ASSERT_TRUE(ImagedAt(model, nadir, seen, 20.0, &px));
  EXPECT_EQ(px, expected);
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
