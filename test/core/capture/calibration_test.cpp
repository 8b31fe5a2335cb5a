#include "slope_monitor/core/capture/calibration.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

camera::CameraModel Model() {
  std::array<double, camera::kNumInterior> p{};
  p[camera::kC] = 8.8;
  p[camera::kX0] = 0.01;
  p[camera::kY0] = -0.02;
  p[camera::kK1] = -2e-3;
  p[camera::kK2] = 1e-5;
  p[camera::kP1] = 1e-5;
  p[camera::kP2] = -2e-5;
  p[camera::kB1] = 1e-4;
  return camera::CameraModel(camera::Sensor{640, 480, 0.0024},
                             camera::DistortionModel::kBrownAffinity, p);
}

TEST(Calibration, PackageParametersRoundTripThroughCameraInfo) {
  const camera::CameraModel m = Model();
  const camera::CameraInfoFields info = m.ToCameraInfo();
  // fy = c / pixel size = 8.8 / 0.0024 = 3666.67 px; cx = 319.5 + 0.01 / 0.0024.
  EXPECT_NEAR(info.k[4], 8.8 / 0.0024, 1e-9);
  EXPECT_NEAR(info.k[2], 319.5 + 0.01 / 0.0024, 1e-9);
  const camera::CameraModel back = CheckCameraInfo(info, 0.0024, 640, 480, "test camera_info");
  for (int i = 0; i < camera::kNumInterior; ++i) {
    EXPECT_NEAR(back.interior()[i], m.interior()[i], 1e-12 + 1e-9 * std::abs(m.interior()[i])) << i;
  }
}

TEST(Calibration, InconsistentCameraInfoNamesTheField) {
  camera::CameraInfoFields info = Model().ToCameraInfo();
  try {
    CheckCameraInfo(info, 0.0024, 800, 600, "file:///cal/cam.yaml");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("file:///cal/cam.yaml"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("800x600"), std::string::npos);
  }
  info.k[1] = 0.5;  // skew: not representable
  EXPECT_THROW(CheckCameraInfo(info, 0.0024, 640, 480, "c"), InvalidArgument);
  info = Model().ToCameraInfo();
  info.distortion_model = "equidistant";
  EXPECT_THROW(CheckCameraInfo(info, 0.0024, 0, 0, "c"), InvalidArgument);
}

TEST(Calibration, NominalModelFromExifFocalLength) {
  ExifInfo exif;
  exif.focal_length_mm = 8.8;
  const camera::CameraModel m = NominalModelFromExif(exif, 4000, 3000, 0.0024, "f.jpg");
  const camera::CameraInfoFields info = m.ToCameraInfo();
  EXPECT_NEAR(info.k[0], 8.8 / 0.0024, 1e-9);
  EXPECT_NEAR(info.k[2], 1999.5, 1e-12);
  EXPECT_NEAR(info.k[5], 1499.5, 1e-12);
  for (double d : info.d) EXPECT_EQ(d, 0.0);
  exif.focal_length_mm = 0.0;
  try {
    NominalModelFromExif(exif, 4000, 3000, 0.0024, "f.jpg");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("f.jpg"), std::string::npos);
  }
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
