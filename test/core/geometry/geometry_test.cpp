// Geometry: resection (closed form + RANSAC), forward intersection with
// covariance, Helmert transform and relative orientation on synthetic scenes
// with known truth (fixed seeds).
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/geometry/intersection.h"
#include "slope_monitor/core/geometry/relative_orientation.h"
#include "slope_monitor/core/geometry/resection.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace geometry {
namespace {

camera::CameraModel FixedCamera() {
  // 6000 x 4000 px, 3.9 um pixels, c = 50 mm, a little radial distortion.
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 50.0;
  in[camera::kX0] = 0.03;
  in[camera::kY0] = -0.02;
  in[camera::kK1] = 2e-5;
  return camera::CameraModel(camera::Sensor{6000, 4000, 0.0039}, camera::DistortionModel::kRadial,
                             in);
}

// A pose at `position` looking at `target` (roll kappa).
// A wider lens (c = 24 mm) on the same sensor.
camera::CameraModel WideCamera() {
  camera::CameraModel m = FixedCamera();
  m.mutable_interior()[camera::kC] = 24.0;
  return m;
}

camera::ExteriorOrientation LookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& target,
                                   double kappa) {
  // Row 3 of M is the camera z axis in site; the camera looks along -z.
  const Eigen::Vector3d z = (position - target).normalized();
  camera::AttitudeAngles a;
  a.phi = std::asin(z.y());
  a.theta = std::atan2(z.x(), z.z());
  a.kappa = kappa;
  camera::ExteriorOrientation e;
  e.position = position;
  e.angles = a;
  return e;
}

// Points on a slope rising to the north, 100-200 m north of the camera.
std::vector<Eigen::Vector3d> SlopePoints(int n, unsigned seed, double half_width = 20.0,
                                         double y0 = 110.0, double y1 = 190.0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-half_width, half_width), uy(y0, y1);
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < n; ++i) {
    const double x = ux(rng), y = uy(rng);
    pts.emplace_back(x, y, 0.3 * (y - 100.0) + 2.0 * std::sin(0.1 * x));
  }
  return pts;
}

TEST(ResectionTest, ThreePointsReturnAllCandidatesIncludingTheTruth) {
  const camera::CameraModel cam = FixedCamera();
  const camera::ExteriorOrientation truth = LookAt({5, 0, 20}, {0, 150, 15}, 0.02);
  const std::vector<Eigen::Vector3d> pts = SlopePoints(4, 3);
  Eigen::Vector3d b[3], p[3];
  for (int i = 0; i < 3; ++i) {
    Eigen::Vector2d px;
    ASSERT_TRUE(cam.Project(truth, pts[i], &px));
    b[i] = BearingOfPixel(cam, px);
    p[i] = pts[i];
  }
  const auto candidates = ResectThreePoints(b, p);
  ASSERT_GE(candidates.size(), 1u);
  ASSERT_LE(candidates.size(), 4u);
  double best = 1e9;
  for (const auto& c : candidates) best = std::min(best, (c.position - truth.position).norm());
  EXPECT_LT(best, 1e-6) << candidates.size() << " candidates";
}

TEST(ResectionTest, AmbiguousConfigurationHasSeveralCandidatesAndTheFourthPointChooses) {
  // Three points forming an equilateral triangle seen from above its centre on
  // the axis: the classic configuration with more than one real solution
  // (the projection centre and its mirror-like alternatives).
  std::array<double, camera::kNumInterior> in{};
  in[camera::kC] = 20.0;
  const camera::CameraModel cam(camera::Sensor{4000, 4000, 0.005}, camera::DistortionModel::kNone,
                                in);
  camera::ExteriorOrientation truth;
  truth.position = Eigen::Vector3d(0.5, 0.3, 30.0);
  const std::vector<Eigen::Vector3d> pts = {
      {10, 0, 0}, {-5, 8.66, 0}, {-5, -8.66, 0}, {2, 3, 1.5}, {-3, -1, 0.5}};
  std::vector<Eigen::Vector2d> px(pts.size());
  for (size_t i = 0; i < pts.size(); ++i) ASSERT_TRUE(cam.Project(truth, pts[i], &px[i]));
  Eigen::Vector3d b[3], p[3];
  for (int i = 0; i < 3; ++i) {
    b[i] = BearingOfPixel(cam, px[i]);
    p[i] = pts[i];
  }
  const auto candidates = ResectThreePoints(b, p);
  ASSERT_GE(candidates.size(), 2u) << "this configuration is ambiguous";
  int matching = 0;
  for (const auto& c : candidates) matching += (c.position - truth.position).norm() < 1e-5;
  EXPECT_EQ(matching, 1);
  // With the extra points, Resect picks the true candidate.
  ResectionOptions opt;
  const ResectionResult r = Resect(cam, px, pts, opt);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_LT((r.exterior.position - truth.position).norm(), 1e-6);
  EXPECT_GE(r.num_candidates_best_sample, 1);
}

TEST(ResectionTest, SixControlPointsWithOnePixelNoiseAt100m) {
  camera::CameraModel cam = WideCamera();
  cam.mutable_interior()[camera::kC] = 16.0;  // a 16 mm lens: the control points fill the image
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 1.0);
  double worst = 0.0;
  std::vector<double> errors;
  for (int trial = 0; trial < 5; ++trial) {
    // Ten control points spread over the image, 60-140 m away on a slope.
    const camera::ExteriorOrientation truth =
        LookAt({3.0 * trial, 0, 10}, {0, 100, 0}, 0.01 * trial);
    std::vector<Eigen::Vector3d> pts = SlopePoints(10, 100 + trial, 40.0, 60.0, 140.0);
    std::vector<Eigen::Vector2d> px;
    std::vector<Eigen::Vector3d> used;
    for (const auto& x : pts) {
      Eigen::Vector2d p;
      if (!cam.Project(truth, x, &p) || p.x() < 0 || p.y() < 0 || p.x() > 5999 || p.y() > 3999)
        continue;
      px.push_back(p + Eigen::Vector2d(noise(rng), noise(rng)));
      used.push_back(x);
    }
    ASSERT_GE(px.size(), 6u);
    ResectionOptions opt;
    opt.pixel_sigma = 1.0;
    const ResectionResult r = Resect(cam, px, used, opt);
    ASSERT_TRUE(r.success) << r.message;
    const double err = (r.exterior.position - truth.position).norm();
    worst = std::max(worst, err);
    std::printf("  trial %d: %zu control points, position error %.4f m (sigma %.4f m)\n", trial,
                px.size(), err, std::sqrt(r.covariance.topLeftCorner<3, 3>().trace()));
    // Within 3.5 sigma of its own covariance, and within a few centimetres.
    const double sigma = std::sqrt(r.covariance.topLeftCorner<3, 3>().trace());
    EXPECT_LT(err, 3.5 * sigma + 1e-3) << "trial " << trial;
    errors.push_back(err);
    const double att = Eigen::AngleAxisd(camera::RotationFromAngles(r.exterior.angles) *
                                         camera::RotationFromAngles(truth.angles).transpose())
                           .angle();
    EXPECT_LT(att, 2e-3);
  }
  std::sort(errors.begin(), errors.end());
  EXPECT_LT(errors[errors.size() / 2], 0.08) << "median position error";
  std::printf(
      "resection, 6-8 control points, 1 px noise, ~100-200 m: worst position error %.4f m\n",
      worst);
}

TEST(ResectionTest, RejectsOutliersWithRansac) {
  const camera::CameraModel cam = FixedCamera();
  const camera::ExteriorOrientation truth = LookAt({0, 0, 25}, {0, 150, 20}, 0.0);
  const std::vector<Eigen::Vector3d> pts = SlopePoints(20, 5);
  std::vector<Eigen::Vector2d> px;
  std::vector<Eigen::Vector3d> used;
  for (const auto& x : pts) {
    Eigen::Vector2d p;
    if (!cam.Project(truth, x, &p) || p.x() < 0 || p.y() < 0 || p.x() > 5999 || p.y() > 3999)
      continue;
    px.push_back(p);
    used.push_back(x);
  }
  ASSERT_GE(px.size(), 12u);
  px[1] += Eigen::Vector2d(80, -40);  // misidentified targets
  px[4] += Eigen::Vector2d(-150, 20);
  const ResectionResult r = Resect(cam, px, used, ResectionOptions());
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_FALSE(r.inliers[1]);
  EXPECT_FALSE(r.inliers[4]);
  EXPECT_EQ(r.num_inliers, static_cast<int>(px.size()) - 2);
  EXPECT_LT((r.exterior.position - truth.position).norm(), 1e-4);
}

TEST(ResectionTest, BadInput) {
  const camera::CameraModel cam = FixedCamera();
  const camera::ExteriorOrientation truth = LookAt({0, 0, 25}, {0, 150, 20}, 0.0);
  std::vector<Eigen::Vector3d> line = {
      {0, 120, 5}, {5, 130, 5}, {10, 140, 5}, {15, 150, 5}, {20, 160, 5}};
  std::vector<Eigen::Vector2d> px;
  for (const auto& x : line) {
    Eigen::Vector2d p;
    cam.Project(truth, x, &p);
    px.push_back(p);
  }
  ResectionResult r = Resect(cam, px, line, ResectionOptions());
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("collinear"), std::string::npos) << r.message;
  r = Resect(cam, {px[0], px[1], px[2]}, {line[0], line[1], line[2]}, ResectionOptions());
  EXPECT_FALSE(r.success);
  EXPECT_NE(r.message.find("too few"), std::string::npos) << r.message;
  px[2].x() = std::nan("");
  EXPECT_THROW(Resect(cam, px, line, ResectionOptions()), InvalidArgument);
}

TEST(IntersectionTest, ThreeCamerasRecoverThePointWithinItsCovariance) {
  const camera::CameraModel cam = FixedCamera();
  const std::vector<camera::ExteriorOrientation> poses = {LookAt({-60, 0, 30}, {0, 150, 15}, 0),
                                                          LookAt({0, -10, 25}, {0, 150, 15}, 0),
                                                          LookAt({60, 0, 30}, {0, 150, 15}, 0)};
  const std::vector<Eigen::Vector3d> pts = SlopePoints(200, 9);
  std::mt19937 rng(21);
  const double sigma_px = 0.2;
  std::normal_distribution<double> noise(0.0, sigma_px);
  int within = 0, n = 0;
  for (const auto& x : pts) {
    std::vector<RayObservation> rays;
    for (const auto& e : poses) {
      RayObservation r;
      r.model = &cam;
      r.exterior = e;
      ASSERT_TRUE(cam.Project(e, x, &r.pixel));
      r.pixel += Eigen::Vector2d(noise(rng), noise(rng));
      r.covariance = Eigen::Matrix2d::Identity() * sigma_px * sigma_px;
      rays.push_back(r);
    }
    const IntersectionResult res = Intersect(rays);
    ASSERT_TRUE(res.success) << res.message;
    const Eigen::Vector3d err = res.position - x;
    ++n;
    bool ok = true;
    for (int k = 0; k < 3; ++k)
      ok = ok && std::abs(err(k)) <= 3.0 * std::sqrt(res.covariance(k, k));
    within += ok;
    EXPECT_LT(err.norm(), 0.03);
  }
  EXPECT_GE(within, static_cast<int>(0.97 * n)) << within << " of " << n;
  // Parallel rays are refused.
  std::vector<RayObservation> same(2);
  for (auto& r : same) {
    r.model = &cam;
    r.exterior = poses[1];
    cam.Project(poses[1], pts[0], &r.pixel);
  }
  EXPECT_FALSE(Intersect(same).success);
}

TEST(HelmertTest, RecoversSimilarityAndRejectsMovedPoints) {
  Similarity3 truth;
  truth.scale = 1.002;
  truth.rotation =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, -0.5, 1.0).normalized()).toRotationMatrix();
  truth.translation = Eigen::Vector3d(100, -50, 12);
  std::mt19937 rng(4);
  std::normal_distribution<double> noise(0.0, 0.002);
  std::vector<Eigen::Vector3d> src = SlopePoints(12, 8, 60.0, 60.0, 200.0), dst;
  for (const auto& x : src)
    dst.push_back(truth * x + Eigen::Vector3d(noise(rng), noise(rng), noise(rng)));
  dst[3] += Eigen::Vector3d(0.3, 0, -0.2);  // a "stable" point that moved
  HelmertOptions opt;
  opt.inlier_threshold = 0.02;
  const HelmertResult r = FitSimilarityRobust(src, dst, opt);
  ASSERT_TRUE(r.success) << r.message;
  EXPECT_FALSE(r.inliers[3]);
  EXPECT_EQ(r.num_inliers, 11);
  EXPECT_NEAR(r.target_from_source.scale, truth.scale, 5e-5);
  EXPECT_LT((r.target_from_source.rotation - truth.rotation).norm(), 1e-4);
  EXPECT_LT(r.rms, 0.006);
  const Similarity3 inv = r.target_from_source.Inverse();
  EXPECT_LT((inv * (r.target_from_source * src[0]) - src[0]).norm(), 1e-9);
  // Too few and collinear.
  EXPECT_FALSE(FitSimilarityRobust({src[0], src[1]}, {dst[0], dst[1]}, opt).success);
  std::vector<Eigen::Vector3d> line = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {3, 3, 3}};
  EXPECT_FALSE(FitSimilarityRobust(line, line, opt).success);
}

TEST(RelativeOrientationTest, FivePointRansacThenScaleFromControl) {
  const camera::CameraModel cam = WideCamera();
  const camera::ExteriorOrientation ea = LookAt({-40, 0, 30}, {0, 150, 15}, 0.01);
  const camera::ExteriorOrientation eb = LookAt({40, 5, 28}, {0, 150, 15}, -0.02);
  const std::vector<Eigen::Vector3d> pts = SlopePoints(150, 12, 35.0, 110.0, 190.0);
  std::mt19937 rng(2);
  std::normal_distribution<double> noise(0.0, 0.2);
  std::vector<Eigen::Vector2d> pa, pb;
  for (const auto& x : pts) {
    Eigen::Vector2d a, b;
    cam.Project(ea, x, &a);
    cam.Project(eb, x, &b);
    pa.push_back(a + Eigen::Vector2d(noise(rng), noise(rng)));
    pb.push_back(b + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  for (int i = 0; i < 15; ++i) pb[i * 10] += Eigen::Vector2d(60, -35);  // 10 % wrong matches
  RelativeOrientationOptions opt;
  const RelativeOrientationResult ro = RelativeOrientation(cam, pa, cam, pb, opt);
  ASSERT_TRUE(ro.success) << ro.message;
  for (int i = 0; i < 15; ++i) EXPECT_FALSE(ro.inliers[i * 10]) << i;
  // Truth: u_b = Mb Ma^T u_a + Mb (Xa - Xb).
  const Eigen::Matrix3d ma = camera::RotationFromAngles(ea.angles),
                        mb = camera::RotationFromAngles(eb.angles);
  const Eigen::Matrix3d r_true = mb * ma.transpose();
  const Eigen::Vector3d t_true = (mb * (ea.position - eb.position)).normalized();
  // The five-point RANSAC result is an initial value (no joint refinement here).
  EXPECT_LT(Eigen::AngleAxisd(ro.rotation * r_true.transpose()).angle(), 5e-3);
  EXPECT_LT((ro.translation - t_true).norm(), 3e-2);
  // Scale and datum from 6 control points.
  std::vector<Eigen::Vector2d> ca, cb;
  std::vector<Eigen::Vector3d> cx;
  for (int i = 1; i < 7; ++i) {
    ca.push_back(pa[i]);
    cb.push_back(pb[i]);
    cx.push_back(pts[i]);
  }
  HelmertOptions h;
  h.inlier_threshold = 0.2;
  const PairInSite pair = OrientPairInSite(ro, cam, cam, ca, cb, cx, h);
  ASSERT_TRUE(pair.success) << pair.message;
  // Initial values for the bundle adjustment: within a metre at ~150 m.
  EXPECT_LT((pair.exterior_a.position - ea.position).norm(), 1.0);
  EXPECT_LT((pair.exterior_b.position - eb.position).norm(), 1.0);
  // Too few tie points.
  EXPECT_FALSE(
      RelativeOrientation(cam, {pa[0], pa[1], pa[2]}, cam, {pb[0], pb[1], pb[2]}, opt).success);
}

}  // namespace
}  // namespace geometry
}  // namespace slope_monitor
