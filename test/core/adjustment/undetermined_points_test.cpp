// Points that the solution leaves undetermined are dropped and named, the
// rest of the epoch is solved with its covariance.
//
// The planted pathological point: a fixed camera takes a second exposure
// from exactly the same pose (both images held, as a calibrated mast camera
// is), and a tie point is matched only between these two exposures. Its two
// rays come from one centre: the point slides along them, its 3x3 normal
// block is singular, and the reduced-camera covariance used to refuse the
// whole epoch ("point block N is not determined"). The planted point touches
// no free parameter, so dropping it must leave every other result exactly as
// the adjustment of the same scene without it gives.
#include <array>
#include <string>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/schur_covariance.h"
#include "synthetic_scene.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr char kPlanted[] = "tie/one_centre";

// The fixed-camera scene with the images held at their true poses and the
// second exposure of camera 0; optionally the planted point.
Scene MakeFixedScene(bool plant, Config* config) {
  testing::SceneSpec spec;
  spec.seed = 21;
  const testing::TruthScene ts = testing::MakeScene(spec);
  Scene scene = ts.observed;
  for (size_t i = 0; i < scene.images.size(); ++i) {
    scene.images[i].exterior = ts.truth.images[i].exterior;
    config->fixed_images.insert(static_cast<int>(i));
  }
  Image second = scene.images[0];
  second.name += "@second_exposure";
  const int image = static_cast<int>(scene.images.size());
  scene.images.push_back(second);
  config->fixed_images.insert(image);
  // The second exposure sees what the first sees (its own pixel noise).
  const size_t n = scene.observations.size();
  for (size_t k = 0; k < n; ++k) {
    if (scene.observations[k].image != 0) continue;
    Observation o = scene.observations[k];
    o.image = image;
    o.pixel += Eigen::Vector2d(0.05, -0.04);
    scene.observations.push_back(o);
  }
  if (!plant) return scene;
  // The planted point: 150 m in front of camera 0, seen by its two exposures only.
  const camera::CameraModel& model = scene.cameras[0].model;
  const camera::Ray ray = model.ImageToRay(second.exterior, Eigen::Vector2d(2100.0, 1700.0));
  ObjectPoint p;
  p.id = kPlanted;
  p.position = ray.origin + 150.0 * ray.direction.normalized();
  const int point = static_cast<int>(scene.points.size());
  scene.points.push_back(p);
  for (const int i : {0, image}) {
    Observation o;
    o.image = i;
    o.point = point;
    EXPECT_TRUE(model.Project(scene.images[i].exterior, p.position, &o.pixel));
    o.pixel += Eigen::Vector2d(0.08 * i, -0.06 * i);  // the two exposures disagree a little
    scene.observations.push_back(o);
  }
  return scene;
}

TEST(UndeterminedPointsTest, PlantedPointIsDroppedAndNamedAndTheRestSolved) {
  Config reference_config, config;
  Scene reference = MakeFixedScene(false, &reference_config);
  Scene scene = MakeFixedScene(true, &config);
  const Summary r = BundleAdjuster(Options(), reference_config).Solve(&reference);
  ASSERT_TRUE(r.IsSolutionUsable()) << r.BriefReport();
  ASSERT_TRUE(r.undetermined_points.empty()) << r.UndeterminedList();

  const Summary s = BundleAdjuster(Options(), config).Solve(&scene);
  ASSERT_TRUE(s.IsSolutionUsable()) << s.BriefReport();
  ASSERT_EQ(s.undetermined_points, std::vector<std::string>{kPlanted});
  EXPECT_NE(s.reason.find("1 undetermined point(s) dropped (tie/one_centre)"), std::string::npos)
      << s.reason;
  ASSERT_TRUE(s.precision.valid) << s.precision.message;
  const int planted = scene.FindPoint(kPlanted);
  EXPECT_FALSE(scene.points[planted].position_known);
  EXPECT_TRUE(s.precision.point_covariance[planted].isZero());
  // The rest: as if the point had never been there.
  EXPECT_EQ(s.num_parameters, r.num_parameters);
  EXPECT_EQ(s.num_observations, r.num_observations);
  for (size_t j = 0; j < reference.points.size(); ++j) {
    ASSERT_EQ(scene.points[j].id, reference.points[j].id);
    EXPECT_LT((scene.points[j].position - reference.points[j].position).norm(), 1e-6)
        << scene.points[j].id;
  }
}

TEST(UndeterminedPointsTest, FindUndeterminedPointsNamesTheSingularBlocksOnly) {
  // Two held cameras 10 m apart looking down from 50 m; point 0 seen by both,
  // point 1 by the first only (rank 2), point 2 by both from one centre.
  const camera::Sensor sensor{4000, 3000, 0.004};
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 24.0;
  std::array<double, 6> a{0.0, 0.0, 50.0, 0.0, 0.0, 0.0}, b{10.0, 0.0, 50.0, 0.0, 0.0, 0.0},
      a_again = a;
  std::array<std::array<double, 3>, 3> points{{{5.0, 1.0, 0.0}, {2.0, -3.0, 0.5}, {4.0, 4.0, 1.0}}};
  ceres::Problem problem;
  auto add = [&](std::array<double, 6>* exterior, std::array<double, 3>* point) {
    problem.AddResidualBlock(new CollinearityErrorAnalytic(sensor, Eigen::Vector2d(2000.0, 1500.0),
                                                           Eigen::Matrix2d::Identity()),
                             nullptr, exterior->data(), interior.data(), point->data());
  };
  add(&a, &points[0]);
  add(&b, &points[0]);
  add(&a, &points[1]);
  add(&a, &points[2]);
  add(&a_again, &points[2]);
  for (double* block : {a.data(), b.data(), a_again.data(), interior.data()})
    problem.SetParameterBlockConstant(block);
  const std::vector<double*> blocks = {points[0].data(), points[1].data(), points[2].data()};
  EXPECT_EQ(FindUndeterminedPoints(SchurCovarianceOptions(), blocks, &problem),
            (std::vector<int>{1, 2}));
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
