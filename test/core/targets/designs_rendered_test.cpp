// Every circle design (design_renderer.h), rendered exactly, facing the
// camera on its axis, realistic noise, light centre 12, 30 and 80 px
// across, found with the defaults (circle_design auto) as one target of its
// design (a concentric marker one target, not one per ring), centred within
// 0.02 px RMS of the projected centre.
// A named design accepts its own and refuses the others (reason "design").
#include <cstdio>

#include <gtest/gtest.h>

#include "design_renderer.h"

namespace slope_monitor {
namespace targets {
namespace {

struct Render {
  cv::Mat image;
  Eigen::Vector2d truth;
};

// Facing the camera on its axis (no pose given: nothing to correct).
Render RenderDesign(const testing::DesignCase& c, double centre_px, unsigned seed) {
  testing::DesignShotSpec s;
  s.design = c.design;
  s.centre_px = centre_px;
  s.seed = seed;
  const testing::DesignShot shot = testing::RenderDesignShot(s);
  return Render{shot.image, shot.truth};
}

Options CirclesOnly(CircleDesign d) {
  Options o;
  o.families.clear();
  o.circle_design = d;
  return o;
}

TEST(DesignsRendered, AutoFindsEachDesignOnceAndCentresIt) {
  const TargetCentroider c(CirclesOnly(CircleDesign::kAuto), io::TargetList());
  for (const testing::DesignCase& dc : testing::DesignCases()) {
    double ss = 0;
    int n = 0;
    for (const double px : {12.0, 30.0, 80.0}) {
      const Render rd = RenderDesign(dc, px, 5 + n);
      const Result r = c.Detect(rd.image, "mono8");
      ASSERT_EQ(r.observations.size(), 1u)
          << CircleDesignName(dc.design) << " " << px << " px: " << r.discarded.size()
          << " discarded, " << r.rejections.size() << " rejected"
          << (r.discarded.empty()
                  ? ""
                  : ": " + RejectReasonName(r.discarded[0].reason) + ": " + r.discarded[0].detail);
      const Observation& o = r.observations[0];
      EXPECT_EQ(o.design, dc.design) << CircleDesignName(o.design) << " at " << px << " px";
      ss += (o.centre - rd.truth).squaredNorm() / 2;
      ++n;
      std::printf("%-12s %4.0f px: seen %-12s ratio %.3f, error (%+.4f, %+.4f) px, sigma %.4f px\n",
                  CircleDesignName(dc.design).c_str(), px, CircleDesignName(o.design).c_str(),
                  o.ring_ratio, o.centre.x() - rd.truth.x(), o.centre.y() - rd.truth.y(),
                  std::sqrt(0.5 * o.covariance.trace()));
    }
    EXPECT_LE(std::sqrt(ss / n), 0.02) << CircleDesignName(dc.design);
  }
}

TEST(DesignsRendered, NamedDesignRefusesTheOthers) {
  for (const testing::DesignCase& named : testing::DesignCases()) {
    const TargetCentroider c(CirclesOnly(named.design), io::TargetList());
    for (const testing::DesignCase& shown : testing::DesignCases()) {
      const Render rd = RenderDesign(shown, 30.0, 3);
      const Result r = c.Detect(rd.image, "mono8");
      const bool same = named.design == shown.design;
      EXPECT_EQ(r.observations.size(), same ? 1u : 0u)
          << "named " << CircleDesignName(named.design) << ", shown "
          << CircleDesignName(shown.design);
    }
  }
}

// A small blurred plate (light centre 10 px, blur 1.2 px: its radius under
// 7 blur sigmas) unidentified (no pose): without circles in the list it is
// a speck of light (discarded, "design"); with the list holding circles it
// is measured, unidentified, for the adjuster to name.
TEST(DesignsRendered, BlurredSmallDiscStandsOnlyWithListedCircles) {
  testing::DesignShotSpec s;
  s.design = CircleDesign::kDiscInRing;
  s.centre_px = 10.0;
  s.blur_px = 1.2;
  s.seed = 4;
  const testing::DesignShot shot = testing::RenderDesignShot(s);
  const TargetCentroider bare(CirclesOnly(CircleDesign::kAuto), io::TargetList());
  const Result alone = bare.Detect(shot.image, "mono8");
  EXPECT_TRUE(alone.observations.empty());
  bool speck = false;
  for (const auto& d : alone.discarded)
    speck = speck || d.detail.find("a speck of light") != std::string::npos;
  EXPECT_TRUE(speck);
  const TargetCentroider listed(CirclesOnly(CircleDesign::kAuto), shot.list);
  const Result r = listed.Detect(shot.image, "mono8");
  ASSERT_EQ(r.observations.size(), 1u);
  EXPECT_EQ(r.observations[0].id, -1);
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
