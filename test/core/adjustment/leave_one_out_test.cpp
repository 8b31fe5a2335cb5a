// LeaveOneOut on the synthetic fixed-camera site (synthetic_scene.h: three
// cameras, ten control points surveyed to 3 mm, fixed seeds): a control
// point whose survey is 0.5 m off in x comes back with that error when it is
// left out (the other nine place it where the photos see it), every other
// point with its survey noise only; the input scene is not changed. With
// three control points, leaving one out leaves no datum: each is named with
// the reason.
#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/leave_one_out.h"
#include "slope_monitor/core/common/error.h"
#include "synthetic_scene.h"

namespace slope_monitor {
namespace adjustment {
namespace {

// The site's observed scene, adjusted as an epoch is (the epoch's options).
Scene Adjusted(Scene s, const EpochAdjustmentOptions& options) {
  const Summary sum = BundleAdjuster(options.adjustment, ConfigFor(s, options)).Solve(&s);
  EXPECT_TRUE(sum.IsSolutionUsable()) << sum.reason;
  return s;
}

testing::SceneSpec Site() {
  testing::SceneSpec spec;
  spec.perturb_initial = false;
  spec.true_interior_differs = false;
  return spec;
}

TEST(LeaveOneOut, AControlPointSurveyedWrongComesBackWithItsError) {
  Scene s = testing::MakeScene(Site()).observed;
  const int blunder = s.FindPoint("tag36h11/8");
  ASSERT_GE(blunder, 0);
  const Eigen::Vector3d error(0.5, 0.0, 0.0);
  *s.points[blunder].surveyed += error;
  const EpochAdjustmentOptions options;
  const Scene adjusted = Adjusted(s, options);
  const LeaveOneOutReport r = LeaveOneOut(adjusted, options, {{"tag36h11/8", "pillar_8"}});
  ASSERT_EQ(r.residuals.size(), 10u) << r.Brief();
  EXPECT_TRUE(r.failed.empty()) << r.Brief();
  double sum = 0.0;
  for (const SurveyResidual& p : r.residuals) {
    sum += p.residual.squaredNorm();
    if (p.id == "tag36h11/8") {
      EXPECT_EQ(p.name, "pillar_8");
      EXPECT_LT((p.residual + error).norm(), 0.01) << p.residual.transpose();
    } else {
      // The blunder is still held at 3 mm: it bends the block a little.
      EXPECT_LT(p.residual.norm(), 0.05) << p.id << ": " << p.residual.transpose();
    }
  }
  EXPECT_DOUBLE_EQ(r.rms, std::sqrt(sum / 10.0));
  EXPECT_EQ(r.Brief().rfind("leave-one-out rms ", 0), 0u) << r.Brief();
  EXPECT_NE(r.Brief().find(" m over 10 control points"), std::string::npos) << r.Brief();
  // The adjusted scene itself is left as it was.
  EXPECT_EQ(adjusted.points[blunder].role, PointRole::kControl);
}

TEST(LeaveOneOut, WithoutADatumEachPointIsNamedWithTheReason) {
  Scene s = testing::MakeScene(Site()).observed;
  for (ObjectPoint& p : s.points)
    if (p.role == PointRole::kControl && p.id != "tag36h11/0" && p.id != "tag36h11/2" &&
        p.id != "tag36h11/6") {
      p.role = PointRole::kTie;
      p.surveyed.reset();
    }
  const EpochAdjustmentOptions options;
  const LeaveOneOutReport r = LeaveOneOut(Adjusted(s, options), options);
  EXPECT_TRUE(r.residuals.empty());
  ASSERT_EQ(r.failed.size(), 3u) << r.Brief();
  EXPECT_EQ(r.failed[0].rfind("tag36h11/0 (", 0), 0u) << r.failed[0];
  EXPECT_NE(r.Brief().find("not adjusted without: tag36h11/0 ("), std::string::npos) << r.Brief();
  EXPECT_EQ(r.rms, 0.0);
}

TEST(LeaveOneOut, NoControlPointGivesAnEmptyReport) {
  EXPECT_EQ(LeaveOneOutReport().Brief(), "");
  EXPECT_THROW(LeaveOneOutOptions{0}.Check(), ConfigError);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
