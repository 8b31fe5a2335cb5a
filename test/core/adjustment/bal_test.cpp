// BAL: the reader reproduces the initial costs listed in
// ../shared/data/README.md, and the solver path (analytic and automatic
// Jacobians) converges on the small problems.
#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/bal.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {
namespace {

std::string Data(const std::string& name) { return std::string(SM_TEST_DATA_DIR) + "/bal/" + name; }

TEST(BalTest, InitialCostsMatchTheReference) {
  struct Case {
    const char* file;
    double cost;
    int cameras, points, observations;
  };
  const Case cases[] = {
      {"dubrovnik-1-1-pre.txt", 63.3164, 1, 1, 1},
      {"dubrovnik-3-7-pre.txt", 2764.2200, 3, 7, -1},
      {"dubrovnik-3-7-18-pre.txt", 2753.1739, 3, 7, 18},
      {"bal-ladybug-problem-49-7776-pre-shrink-1800.txt", 2.345198e+05, 49, 1800, 10863}};
  for (const Case& c : cases) {
    const BalProblem p = BalProblem::Load(Data(c.file));
    EXPECT_EQ(static_cast<int>(p.cameras.size()), c.cameras) << c.file;
    EXPECT_EQ(static_cast<int>(p.points.size()), c.points) << c.file;
    if (c.observations > 0)
      EXPECT_EQ(static_cast<int>(p.observations.size()), c.observations) << c.file;
    // The reference figures carry 6-7 significant digits.
    EXPECT_NEAR(p.Cost(), c.cost, 1e-6 * c.cost + 1e-4) << c.file;
  }
}

TEST(BalTest, AnalyticAndAutodiffConvergeToTheSameCost) {
  Options o;
  o.loss = "none";
  o.max_iterations = 50;
  for (const char* file : {"dubrovnik-3-7-pre.txt", "dubrovnik-3-7-18-pre.txt"}) {
    BalProblem a = BalProblem::Load(Data(file)), b = a;
    const double initial = a.Cost();
    const BalReport ra = SolveBal(&a, o, true);
    const BalReport rb = SolveBal(&b, o, false);
    EXPECT_FALSE(ra.solve.failed) << ra.solve.termination;
    EXPECT_LT(ra.solve.final_cost, 0.01 * initial) << file;
    EXPECT_NEAR(ra.solve.final_cost, rb.solve.final_cost, 1e-6 * initial) << file;
    EXPECT_NEAR(a.Cost(), ra.solve.final_cost, 1e-9 * initial);
  }
}

TEST(BalTest, MalformedFilesNameTheProblem) {
  EXPECT_THROW(BalProblem::Load(Data("no-such-file.txt")), IoError);
  try {
    BalProblem::Load(std::string(SM_TEST_DATA_DIR) + "/README.md");
    FAIL() << "expected IoError";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("README.md"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
