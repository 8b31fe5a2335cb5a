// ComputeSurveyResiduals on hand-made scenes: residuals and RMS checked by
// hand, a survey without height reported in x and y only, points the photos
// did not measure (seen once, or not adjusted) left out.
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/survey_residuals.h"
#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace adjustment {
namespace {

ObjectPoint Surveyed(const std::string& id, PointRole role, const Eigen::Vector3d& adjusted,
                     const Eigen::Vector3d& survey, double sigma_z = 0.1) {
  ObjectPoint p;
  p.id = id;
  p.role = role;
  p.position = adjusted;
  p.surveyed = survey;
  p.surveyed_covariance = Eigen::Vector3d(0.01, 0.01, sigma_z * sigma_z).asDiagonal();
  return p;
}

Scene TwoPhotos() {
  Scene s;
  s.images.resize(2);
  return s;
}

void SeenBy(Scene* s, int point, int images) {
  for (int i = 0; i < images; ++i) s->observations.push_back({i, point, {}, {}});
}

TEST(SurveyResiduals, HandCheckedResidualsAndRms) {
  Scene s = TwoPhotos();
  s.points.push_back(Surveyed("gcp/1", PointRole::kControl, {3, 4, 0}, {0, 0, 0}));    // 5 m
  s.points.push_back(Surveyed("gcp/2", PointRole::kControl, {10, 0, 1}, {10, 0, 1}));  // 0 m
  s.points.push_back(Surveyed("gcp/3", PointRole::kCheck, {1, 2, 5}, {1, 2, 3}));      // 2 m in z
  s.points.push_back(Surveyed("gcp/4", PointRole::kCheck, {9, 9, 9}, {0, 0, 0}));      // seen once
  ObjectPoint tie;
  tie.id = "tie/0";
  s.points.push_back(tie);
  SeenBy(&s, 0, 2);
  SeenBy(&s, 1, 2);
  SeenBy(&s, 2, 2);
  SeenBy(&s, 3, 1);
  SeenBy(&s, 4, 2);
  const SurveyResiduals r =
      ComputeSurveyResiduals(s, {"gcp/1", "gcp/2", "gcp/3", "gcp/4", "gcp/9"});
  ASSERT_EQ(r.control.size(), 2u);
  ASSERT_EQ(r.check.size(), 1u) << "a point seen in one photo is not measured";
  EXPECT_EQ(r.control[0].residual, Eigen::Vector3d(3, 4, 0));
  EXPECT_DOUBLE_EQ(r.control_rms, std::sqrt(25.0 / 2.0));
  EXPECT_DOUBLE_EQ(r.check_rms, 2.0);
  EXPECT_EQ(r.not_measured, (std::vector<std::string>{"gcp/4", "gcp/9"}));
  EXPECT_EQ(r.Brief(),
            "control rms 3.536 m over 2 points, check rms 2.000 m over 1 points; not measured (in "
            "fewer than two oriented photos): gcp/4, gcp/9");
  ASSERT_EQ(r.Lines().size(), 3u);
  EXPECT_EQ(r.Lines()[0], "check gcp/3 (0.000, 0.000, 2.000) m");
  // With the survey's names (a gcp list's gcp_name): the lines name them.
  const SurveyResiduals named = ComputeSurveyResiduals(s, {"gcp/1", "gcp/2", "gcp/3", "gcp/4"},
                                                       {{"gcp/3", "gcp03"}, {"gcp/4", "gcp04"}});
  EXPECT_EQ(named.check[0].id, "gcp/3");
  EXPECT_EQ(named.Lines()[0], "check gcp03 (0.000, 0.000, 2.000) m");
  EXPECT_EQ(named.Lines()[1], "control gcp/1 (3.000, 4.000, 0.000) m");
  EXPECT_EQ(named.not_measured, (std::vector<std::string>{"gcp04"}));
}

TEST(SurveyResiduals, ASurveyWithoutHeightGivesHorizontalResidualsOnly) {
  Scene s = TwoPhotos();
  s.points.push_back(
      Surveyed("gcp/1", PointRole::kCheck, {0.3, 0.4, 7.0}, {0, 0, 0}, io::kNoHeightSigma));
  SeenBy(&s, 0, 2);
  const SurveyResiduals r = ComputeSurveyResiduals(s);
  ASSERT_EQ(r.check.size(), 1u);
  EXPECT_FALSE(r.check[0].has_height);
  EXPECT_DOUBLE_EQ(r.check_rms, 0.5);
  EXPECT_EQ(r.Lines()[0], "check gcp/1 (0.300, 0.400, no height) m");
  EXPECT_NE(r.Brief().find("horizontal only"), std::string::npos) << r.Brief();
}

TEST(SurveyResiduals, APointNotAdjustedIsLeftOut) {
  Scene s = TwoPhotos();
  s.points.push_back(Surveyed("gcp/1", PointRole::kControl, {1, 1, 1}, {0, 0, 0}));
  s.points[0].position_known = false;
  SeenBy(&s, 0, 2);
  const SurveyResiduals r = ComputeSurveyResiduals(s);
  EXPECT_TRUE(r.control.empty());
  EXPECT_EQ(r.control_rms, 0.0);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
