// dense::TargetlessCamera (issue 19): the WARN of a mast turned beyond the
// limit names the camera and the angle; the site-polygon areas need a
// polygon; a photo before the reference and one of the wrong size are named.
// A rendered pair of the simulator's small slope (as displacement_field_sim_test).
#include "slope_monitor/core/dense/targetless_camera.h"

#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"

#include "../sim/test_scene.h"

namespace slope_monitor {
namespace dense {
namespace {

constexpr double kTargetlessDeg = M_PI / 180.0;

TEST(TargetlessCamera, WarningNamesCameraAndAngle) {
  const sim::Scene scene(sim::testing::SmallSlope(5));
  const camera::CameraModel model = sim::testing::SmallCamera(640, 360, 25.0, 0.0, 0.0, 0.0);
  const Eigen::Vector3d look(20, 15, scene.AnalyticHeight(20, 15));
  const camera::ExteriorOrientation ref =
      sim::LookAt(Eigen::Vector3d(20, -120, look.z() + 70), look, Eigen::Vector3d::UnitZ());
  camera::ExteriorOrientation turned = ref;
  turned.angles.kappa += 0.1 * kTargetlessDeg;  // 0.1 deg about the optical axis
  const sim::Renderer renderer(scene, model);
  const sim::Scene::State s0 = scene.AtTime(0.0);
  const cv::Mat img0 = sim::testing::Photo(renderer, s0, ref, sim::RenderOptions(), 1);
  const cv::Mat img1 = sim::testing::Photo(renderer, s0, turned, sim::RenderOptions(), 2);

  TargetlessCameraOptions o;
  o.max_rotation_deg = 0.05;  // below the turn: a warning
  TargetlessCamera cam("mast_cam", model, ref, nullptr, ImageAreas(), o);
  EXPECT_THROW(cam.Process(img1, 10.0), InvalidArgument);  // no reference yet
  cam.SetReference(img0, 0.0);
  const TargetlessEpoch e = cam.Process(img1, 3600.0);
  ASSERT_TRUE(e.reorientation.success) << e.reorientation.message;
  // The turn within 3 sigma (a small 640 x 360 camera: sigma ~0.001 deg).
  std::printf("rotation %.5f deg, sigma max %.5f deg\n",
              e.reorientation.rotation_angle / kTargetlessDeg,
              e.reorientation.sigma.maxCoeff() / kTargetlessDeg);
  EXPECT_NEAR(e.reorientation.rotation_angle, 0.1 * kTargetlessDeg,
              3.0 * e.reorientation.sigma.maxCoeff());
  EXPECT_FALSE(e.has_field);  // no DEM: re-orientation only
  bool named = false;
  for (const std::string& w : e.warnings) {
    std::printf("warning: %s\n", w.c_str());
    if (w.find("mast_cam") != std::string::npos && w.find("kappa") != std::string::npos)
      named = true;
  }
  EXPECT_TRUE(named);

  // Within the default limit (0.5 deg): no warning.
  TargetlessCamera quiet("mast_cam", model, ref, nullptr, ImageAreas(), TargetlessCameraOptions());
  quiet.SetReference(img0, 0.0);
  EXPECT_TRUE(quiet.Process(img1, 3600.0).warnings.empty());

  // A photo of another size names the camera.
  try {
    cam.Process(cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)), 1.0);
    FAIL() << "a photo of the wrong size was accepted";
  } catch (const InvalidArgument& ex) {
    EXPECT_NE(std::string(ex.what()).find("camera 'mast_cam': photo is 100x100"), std::string::npos)
        << ex.what();
  }
  // Site areas need a polygon.
  io::GeoRaster dem(10, 10, 0.0, 10.0, 1.0);
  dem.AddBand("height", 0.0f);
  EXPECT_THROW(AreasFromSitePolygons(model, ref, dem, {}, {}, 1000.0), InvalidArgument);
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
