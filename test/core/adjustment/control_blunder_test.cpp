// Control point blunder naming (issue 22): a control point whose survey
// disagrees with the others is named as THE blunder (largest standardized
// residual after a robust fit), not its neighbours. The site and its
// surveyed control points come from the simulator (test/data/sim/tiny_site.yaml
// with more control points and a 4 mm survey); the photogrammetric
// positions are the simulator's truth in a free block's frame (shifted,
// turned, scaled) plus 3 mm noise.
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "slope_monitor/core/adjustment/control_check.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr double kSurveySigma = 0.004;    // [m] every axis
constexpr double kMeasuredSigma = 0.003;  // [m] every axis
constexpr double kBlunder = 0.05;         // [m]

std::string Replace(std::string text, const std::string& what, const std::string& with) {
  const size_t at = text.find(what);
  EXPECT_NE(at, std::string::npos) << what;
  return text.replace(at, what.size(), with);
}

// The tiny site with six more control points on stable ground and a 4 mm survey.
sim::SurveyTruth SimulatedSite() {
  std::ifstream in(std::string(SM_TEST_DATA_DIR) + "/sim/tiny_site.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml =
      Replace(text.str(), "survey_sigma: [0.03, 0.01]", "survey_sigma: [0.004, 0.004]");
  yaml = Replace(yaml, "  list:\n",
                 "  list:\n"
                 "    - {family: tag36h11, id: 4, role: control, position: [5, 5]}\n"
                 "    - {family: tag36h11, id: 5, role: control, position: [55, 5]}\n"
                 "    - {family: tag36h11, id: 6, role: control, position: [5, 40]}\n"
                 "    - {family: tag36h11, id: 7, role: control, position: [55, 40]}\n"
                 "    - {family: tag36h11, id: 8, role: control, position: [9, 22]}\n"
                 "    - {family: tag36h11, id: 9, role: control, position: [51, 22]}\n");
  return sim::SurveyGenerator(sim::SurveyConfig::Parse(yaml, "control_blunder_test"))
      .planned_truth();
}

// Survey (with its simulated error) and the block's measurement of every
// stable control / check point; `blunder_id` gets kBlunder added to its survey.
std::vector<ControlPointPair> Pairs(const sim::SurveyTruth& truth, const std::string& blunder_id,
                                    const geometry::Similarity3& block_from_site) {
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, kMeasuredSigma);
  std::vector<ControlPointPair> pairs;
  for (const sim::TargetTruth& t : truth.targets) {
    if (!t.surveyed) continue;
    ControlPointPair p;
    p.id = t.key;
    p.surveyed = *t.surveyed;
    if (t.key == blunder_id) p.surveyed += kBlunder * Eigen::Vector3d(0.6, 0.8, 0.0);
    p.surveyed_covariance = Eigen::Matrix3d::Identity() * kSurveySigma * kSurveySigma;
    p.measured =
        block_from_site * t.positions[0] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    p.measured_covariance = Eigen::Matrix3d::Identity() * kMeasuredSigma * kMeasuredSigma;
    pairs.push_back(p);
  }
  return pairs;
}

geometry::Similarity3 Block() {
  geometry::Similarity3 t;
  t.scale = 1.002;
  t.rotation = (Eigen::AngleAxisd(0.35, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  t.translation = Eigen::Vector3d(-1000.0, 500.0, 30.0);
  return t;
}

TEST(ControlBlunder, GoodControlPointsAgree) {
  const sim::SurveyTruth truth = SimulatedSite();
  const ControlCheckSummary s = CheckControlPoints(Pairs(truth, "", Block()));
  ASSERT_TRUE(s.success) << s.message;
  ASSERT_GE(s.points.size(), 11u);
  EXPECT_TRUE(s.blunders.empty()) << s.message;
  // The fit undoes the block's frame: the truth maps back within the noise.
  const geometry::Similarity3 site_from_block = Block().Inverse();
  EXPECT_NEAR(s.surveyed_from_measured.scale, site_from_block.scale, 2e-4);
  for (const ControlPointTest& p : s.points) EXPECT_LT(p.residual.norm(), 0.03) << p.id;
}

TEST(ControlBlunder, Planted5cmBlunderIsNamedAndNoNeighbour) {
  const sim::SurveyTruth truth = SimulatedSite();
  int tried = 0;
  for (const sim::TargetTruth& t : truth.targets) {
    if (!t.surveyed) continue;
    ++tried;
    const ControlCheckSummary s = CheckControlPoints(Pairs(truth, t.key, Block()));
    ASSERT_TRUE(s.success) << s.message;
    ASSERT_EQ(s.blunders.size(), 1u) << t.key << ": " << s.message;
    EXPECT_EQ(s.blunders[0], t.key) << s.message;
    ASSERT_EQ(s.notes.size(), 1u);
    EXPECT_NE(s.notes[0].find("control point " + t.key + " disagrees with the others by "),
              std::string::npos)
        << s.notes[0];
    for (const ControlPointTest& p : s.points) {
      EXPECT_EQ(p.blunder, p.id == t.key) << p.id;
      if (p.id == t.key) {
        // The planted 50 mm, give or take the survey and measurement noise (5 mm per axis).
        EXPECT_NEAR(p.residual.norm(), kBlunder, 0.015) << p.id;
      } else {
        EXPECT_LT(p.w, ControlCheckOptions().critical_value) << p.id;
      }
    }
  }
  EXPECT_GE(tried, 11);
}

TEST(ControlBlunder, RigidFitNamesTheBlunderToo) {
  const sim::SurveyTruth truth = SimulatedSite();
  geometry::Similarity3 block = Block();
  block.scale = 1.0;
  ControlCheckOptions rigid;
  rigid.estimate_scale = false;
  const ControlCheckSummary s = CheckControlPoints(Pairs(truth, "tag36h11/5", block), rigid);
  ASSERT_TRUE(s.success) << s.message;
  ASSERT_EQ(s.blunders.size(), 1u) << s.message;
  EXPECT_EQ(s.blunders[0], "tag36h11/5");
  EXPECT_DOUBLE_EQ(s.surveyed_from_measured.scale, 1.0);
}

TEST(ControlBlunder, OneKilometreBlunderIsNamed) {
  const sim::SurveyTruth truth = SimulatedSite();
  std::vector<ControlPointPair> pairs = Pairs(truth, "", Block());
  pairs[2].surveyed.x() += 1000.0;
  const ControlCheckSummary s = CheckControlPoints(pairs);
  ASSERT_TRUE(s.success) << s.message;
  ASSERT_EQ(s.blunders.size(), 1u) << s.message;
  EXPECT_EQ(s.blunders[0], pairs[2].id);
  for (size_t i = 0; i < pairs.size(); ++i)
    if (i != 2) {
      EXPECT_LT(s.points[i].residual.norm(), 0.03) << pairs[i].id;
    }
}

TEST(ControlBlunder, BadInputNamed) {
  const sim::SurveyTruth truth = SimulatedSite();
  std::vector<ControlPointPair> pairs = Pairs(truth, "", Block());
  pairs[1].surveyed_covariance(0, 1) = 1.0;
  try {
    CheckControlPoints(pairs);
    FAIL() << "an asymmetric covariance was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(pairs[1].id), std::string::npos) << e.what();
  }
  const ControlCheckSummary few = CheckControlPoints({pairs[0], pairs[2], pairs[3]});
  EXPECT_FALSE(few.success);
  EXPECT_NE(few.message.find("need >= 4"), std::string::npos) << few.message;
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
