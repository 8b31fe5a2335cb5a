// The collinearity camera model: hand-computed projections, distortion round
// trips, agreement with OpenCV and CameraInfo, automatic-differentiation
// Jacobians, and clear errors for bad input.
#include "slope_monitor/core/camera/camera_model.h"

#include <cmath>
#include <limits>
#include <random>

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace camera {
namespace {

// A 1000 x 800 px sensor with 10 um pixels (10 x 8 mm), c = 50 mm.
CameraModel SimpleCamera() {
  std::array<double, kNumInterior> p{};
  p[kC] = 50.0;
  return CameraModel(Sensor{1000, 800, 0.01}, DistortionModel::kNone, p);
}

// A 4000 x 3000 px sensor with 3.9 um pixels and strong, realistic distortion.
CameraModel DistortedCamera(double b2 = 0.0) {
  std::array<double, kNumInterior> p{};
  p[kC] = 8.8;
  p[kX0] = 0.031;
  p[kY0] = -0.022;
  p[kK1] = -2.1e-3;  // ~ -37 px at the corner
  p[kK2] = 1.3e-5;
  p[kK3] = -4.0e-8;
  p[kP1] = 1.2e-4;
  p[kP2] = -0.8e-4;
  p[kB1] = 2.0e-4;
  p[kB2] = b2;
  return CameraModel(Sensor{4000, 3000, 0.0039}, DistortionModel::kBrownAffinity, p);
}

TEST(CameraModel, NadirProjectionByHand) {
  // Camera at (0, 0, 100) looking down; point (10, 5, 0):
  // u = (10, 5, -100), x = -c U / W = 5 mm, y = 2.5 mm,
  // col = 499.5 + 5 / 0.01 = 999.5, row = 399.5 - 2.5 / 0.01 = 149.5.
  const CameraModel cam = SimpleCamera();
  ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, 100);
  Eigen::Vector2d mm, px;
  ASSERT_TRUE(cam.ProjectMm(pose, Eigen::Vector3d(10, 5, 0), &mm));
  EXPECT_NEAR(mm.x(), 5.0, 1e-12);
  EXPECT_NEAR(mm.y(), 2.5, 1e-12);
  ASSERT_TRUE(cam.Project(pose, Eigen::Vector3d(10, 5, 0), &px));
  EXPECT_NEAR(px.x(), 999.5, 1e-9);
  EXPECT_NEAR(px.y(), 149.5, 1e-9);
  // A point above the camera is behind it.
  EXPECT_FALSE(cam.Project(pose, Eigen::Vector3d(0, 0, 150), &px));
}

TEST(CameraModel, HorizontalCameraByHand) {
  // phi = -90 deg turns the viewing direction (-z of the camera) to site +y
  // (north): row 3 of M = (0, sin phi, 0) = (0, -1, 0). A point 200 m north and
  // 4 m east, 2 m up: U = 4, V = 2 (m22 = cos kappa cos phi... with phi = -90:
  // M = [[1,0,0],[0,0,1],[0,-1,0]]), W = -200, so x = 50*4/200 = 1 mm, y = 0.5 mm.
  const CameraModel cam = SimpleCamera();
  ExteriorOrientation pose;
  pose.angles.phi = -M_PI / 2;
  Eigen::Vector2d mm;
  ASSERT_TRUE(cam.ProjectMm(pose, Eigen::Vector3d(4, 200, 2), &mm));
  EXPECT_NEAR(mm.x(), 1.0, 1e-12);
  EXPECT_NEAR(mm.y(), 0.5, 1e-12);
}

TEST(CameraModel, PrincipalPointAndDistortionByHand) {
  // k1 only: xd = xu (1 + k1 r^2). xu = 2, yu = 0, k1 = 0.01 -> xd = 2.08.
  std::array<double, kNumInterior> p{};
  p[kC] = 50.0;
  p[kX0] = 0.1;
  p[kY0] = -0.2;
  p[kK1] = 0.01;
  const CameraModel cam(Sensor{1000, 800, 0.01}, DistortionModel::kRadial, p);
  const Eigen::Vector2d d = cam.DistortMm(Eigen::Vector2d(2.0, 0.0));
  EXPECT_NEAR(d.x(), 0.1 + 2.08, 1e-12);
  EXPECT_NEAR(d.y(), -0.2, 1e-12);
}

TEST(CameraModel, DistortionRoundTripOverTheWholeImage) {
  const CameraModel cam = DistortedCamera(3.0e-5);
  double worst_px = 0.0;
  for (int row = 0; row < 3000; row += 50) {
    for (int col = 0; col < 4000; col += 50) {
      const Eigen::Vector2d px(col, row);
      const Eigen::Vector2d ideal = cam.UndistortMm(cam.PixelToMm(px));
      const Eigen::Vector2d back = cam.MmToPixel(cam.DistortMm(ideal));
      worst_px = std::max(worst_px, (back - px).norm());
    }
  }
  EXPECT_LT(worst_px, 1e-6);
}

TEST(CameraModel, RayThroughAProjectedPointHitsThePoint) {
  const CameraModel cam = DistortedCamera();
  ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(12, -40, 65);
  pose.angles = AttitudeAngles{0.1, -0.6, 0.05};
  const Eigen::Vector3d point(15, 10, 3);
  Eigen::Vector2d px;
  ASSERT_TRUE(cam.Project(pose, point, &px));
  const Ray ray = cam.ImageToRay(pose, px);
  const Eigen::Vector3d to_point = point - ray.origin;
  const double along = to_point.dot(ray.direction);
  EXPECT_GT(along, 0.0);
  EXPECT_LT((to_point - along * ray.direction).norm(), 1e-9);
}

TEST(CameraModel, AgreesWithOpenCvProjectPoints) {
  const CameraModel cam = DistortedCamera();
  ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(3, -120, 40);
  pose.angles = AttitudeAngles{0.05, -1.2, -0.03};
  const OpenCvCamera cvc = cam.ToOpenCv();

  const Rigid3 optical_from_site = pose.OpticalFromSite();
  cv::Mat r(3, 3, CV_64F), rvec, tvec(3, 1, CV_64F), k(3, 3, CV_64F);
  const Eigen::Matrix3d rm = optical_from_site.RotationMatrix();
  for (int i = 0; i < 3; ++i) {
    tvec.at<double>(i) = optical_from_site.translation(i);
    for (int j = 0; j < 3; ++j) {
      r.at<double>(i, j) = rm(i, j);
      k.at<double>(i, j) = cvc.k(i, j);
    }
  }
  cv::Rodrigues(r, rvec);

  std::mt19937 rng(42);
  std::vector<cv::Point3d> points;
  std::vector<Eigen::Vector2d> ours;
  while (points.size() < 500) {
    const Eigen::Vector3d x(std::uniform_real_distribution<double>(-80, 80)(rng),
                            std::uniform_real_distribution<double>(-20, 60)(rng),
                            std::uniform_real_distribution<double>(-10, 40)(rng));
    Eigen::Vector2d px;
    if (!cam.Project(pose, x, &px)) continue;
    if (px.x() < 0 || px.y() < 0 || px.x() > 3999 || px.y() > 2999) continue;
    points.emplace_back(x.x(), x.y(), x.z());
    ours.push_back(px);
  }
  std::vector<cv::Point2d> theirs;
  cv::projectPoints(points, rvec, tvec, k, cvc.distortion, theirs);
  double worst = 0.0;
  for (size_t i = 0; i < points.size(); ++i) {
    worst = std::max(worst, std::hypot(theirs[i].x - ours[i].x(), theirs[i].y - ours[i].y()));
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(CameraModel, OpenCvAndCameraInfoRoundTrip) {
  const CameraModel cam = DistortedCamera();
  const CameraModel back = CameraModel::FromOpenCv(cam.ToOpenCv(), cam.sensor().pixel_size);
  for (int i = 0; i < kNumInterior; ++i) {
    EXPECT_NEAR(back.interior()[i], cam.interior()[i],
                1e-12 * std::max(1.0, std::abs(cam.interior()[i])))
        << InteriorNames()[i];
  }
  const CameraInfoFields info = cam.ToCameraInfo();
  EXPECT_EQ(info.distortion_model, "plumb_bob");
  ASSERT_EQ(info.d.size(), 5u);
  EXPECT_DOUBLE_EQ(info.p[0], info.k[0]);
  const CameraModel from_info = CameraModel::FromCameraInfo(info, cam.sensor().pixel_size);
  EXPECT_NEAR(from_info.interior()[kK1], cam.interior()[kK1], 1e-15);
  EXPECT_EQ(from_info.model(), DistortionModel::kBrownAffinity);
}

// Projection to pixels as a Ceres functor, to check automatic differentiation.
struct ProjectFunctor {
  ProjectFunctor(Sensor s) : sensor(s) {}
  template <typename T>
  bool operator()(const T* exterior, const T* interior, const T* point, T* residual) const {
    T mm[2];
    ProjectToImageMm(exterior, interior, point, mm);
    MmToPixel(sensor, mm[0], mm[1], &residual[0], &residual[1]);
    return true;
  }
  Sensor sensor;
};

TEST(CameraModel, AutodiffJacobiansMatchNumericDifferences) {
  const CameraModel cam = DistortedCamera(1e-4);
  ceres::CostFunction* cost =
      new ceres::AutoDiffCostFunction<ProjectFunctor, 2, kNumExterior, kNumInterior, 3>(
          new ProjectFunctor(cam.sensor()));
  ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(5, -30, 60);
  pose.angles = AttitudeAngles{0.2, -0.5, 0.1};
  std::array<double, kNumExterior> e = pose.ToArray();
  std::array<double, kNumInterior> in = cam.interior();
  double point[3] = {10, 20, 2};
  std::vector<const double*> blocks = {e.data(), in.data(), point};
  ceres::NumericDiffOptions numeric;
  const std::vector<const ceres::Manifold*>* no_manifolds = nullptr;
  ceres::GradientChecker checker(cost, no_manifolds, numeric);
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(blocks.data(), 1e-6, &results)) << results.error_log;
  delete cost;
}

TEST(CameraModel, BadInputNamesTheValue) {
  EXPECT_THROW(DistortionModelFromName("fisheye"), InvalidArgument);
  try {
    DistortionModelFromName("fisheye");
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'fisheye'"), std::string::npos);
  }

  CameraModel nan_cam = SimpleCamera();
  nan_cam.mutable_interior()[kX0] = std::numeric_limits<double>::quiet_NaN();
  try {
    nan_cam.Check();
    FAIL() << "NaN x0 accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'x0'"), std::string::npos) << e.what();
  }

  CameraModel outside = SimpleCamera();  // model "none" with a k1
  outside.mutable_interior()[kK1] = 1e-3;
  EXPECT_THROW(outside.Check(), InvalidArgument);

  CameraInfoFields info = DistortedCamera().ToCameraInfo();
  info.distortion_model = "equidistant";
  try {
    CameraModel::FromCameraInfo(info, 1.0);
    FAIL() << "equidistant accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'equidistant'"), std::string::npos) << e.what();
  }

  info.distortion_model = "rational_polynomial";
  info.d = {0.1, 0.01, 0, 0, 0.001, 0.2, 0, 0};  // k4 != 0
  try {
    CameraModel::FromCameraInfo(info, 1.0);
    FAIL() << "k4 accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("k4"), std::string::npos) << e.what();
  }

  EXPECT_THROW(DistortedCamera(1e-3).ToOpenCv(), InvalidArgument);  // shear b2
}

}  // namespace
}  // namespace camera
}  // namespace slope_monitor
