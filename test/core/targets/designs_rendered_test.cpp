// Every circle design, rendered exactly (planar_target_renderer.h), nadir
// view, realistic noise, light centre 12, 30 and 80 px across, found with
// the defaults (circle_design auto) as one target of its design, centred
// within 0.02 px RMS of the projected centre:
//   disc_in_ring  disc in a dark ring of 2 diameters on a grey ground;
//   dot           light dot on a dark plate of 6 dot diameters;
//   ring          dark ring to 1.6 centre radii on a light ground;
//   concentric    dark ring to 1.4, light ring to 1.8, dark ring to 2.3
//                 radii on a light ground (one target, not one per ring).
// A named design accepts its own and refuses the others (reason "design").
#include <cstdio>

#include <gtest/gtest.h>

#include "planar_target_renderer.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

constexpr double kDesignFocal = 1000.0, kDesignHeight = 10.0;
constexpr double kBright = 0.9, kDark = 0.08;

struct DesignCase {
  CircleDesign design;
  double background;
  double plate_radii;  // plate half extent in centre radii
};

// The pattern of a design; r: radius of the light centre [m].
testing::Pattern DesignPattern(CircleDesign d, double r) {
  return [=](double u, double v) {
    const double s = std::sqrt(u * u + v * v) / r;
    if (s <= 1.0) return kBright;
    switch (d) {
      case CircleDesign::kDiscInRing:
        return s <= 2.0 ? kDark : -1.0;
      case CircleDesign::kDot:
        return s <= 6.0 ? kDark : -1.0;
      case CircleDesign::kRing:
        return s <= 1.6 ? kDark : -1.0;
      case CircleDesign::kConcentric:
        return s <= 1.4 ? kDark : s <= 1.8 ? kBright : s <= 2.3 ? kDark : -1.0;
      default:
        return -1.0;
    }
  };
}

const std::vector<DesignCase>& Cases() {
  static const std::vector<DesignCase> c = {{CircleDesign::kDiscInRing, 0.45, 2.0},
                                            {CircleDesign::kDot, kBright, 6.0},
                                            {CircleDesign::kRing, kBright, 1.6},
                                            {CircleDesign::kConcentric, kBright, 2.3}};
  return c;
}

struct Render {
  cv::Mat image;
  Eigen::Vector2d truth;
};

Render RenderDesign(const DesignCase& c, double centre_px, unsigned seed) {
  const double r_px = 0.5 * centre_px;
  const int size = static_cast<int>(2 * (c.plate_radii + 1.2) * r_px + 40) | 1;
  const camera::CameraModel cam = testing::NadirCamera(size, size, kDesignFocal);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, kDesignHeight);
  testing::Plate plate;
  plate.centre = Eigen::Vector3d(0.0037, -0.0052, 0.0);
  testing::RenderOptions ro;
  ro.read_noise = 1.0;
  ro.photons_per_dn = 50.0;
  ro.seed = seed;
  ro.background = c.background;
  cv::Mat f = testing::Background(size, size, ro);
  const double r = r_px * kDesignHeight / kDesignFocal;
  testing::RenderPlate(&f, testing::PlaneToPixel(cam, pose, plate), DesignPattern(c.design, r),
                       c.plate_radii * r, ro);
  Render out;
  out.image = testing::ToMono8(f, ro);
  EXPECT_TRUE(cam.Project(pose, plate.centre, &out.truth));
  return out;
}

Options CirclesOnly(CircleDesign d) {
  Options o;
  o.families.clear();
  o.circle_design = d;
  return o;
}

TEST(DesignsRendered, AutoFindsEachDesignOnceAndCentresIt) {
  const TargetCentroider c(CirclesOnly(CircleDesign::kAuto), io::TargetList());
  for (const DesignCase& dc : Cases()) {
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
  for (const DesignCase& named : Cases()) {
    const TargetCentroider c(CirclesOnly(named.design), io::TargetList());
    for (const DesignCase& shown : Cases()) {
      const Render rd = RenderDesign(shown, 30.0, 3);
      const Result r = c.Detect(rd.image, "mono8");
      const bool same = named.design == shown.design;
      EXPECT_EQ(r.observations.size(), same ? 1u : 0u)
          << "named " << CircleDesignName(named.design) << ", shown "
          << CircleDesignName(shown.design);
    }
  }
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
