// Markers of three or more dark rings on a light ground, rendered exactly
// (planar_target_renderer.h) under perspective, with blur and noise, and
// found with the defaults (circle_design auto, no pose, no list): ring
// designs of 3, 4 and 5 rings whose counts and widths the detector is not
// told. Checks:
//   * each render gives one observation, method ring_centre, with its ring
//     count; nothing else;
//   * its centre is the projected centre of the rings (the perspective bias
//     of the ellipses' centres removed without a pose) within 0.1 px, where
//     the innermost ellipse's own centre is off by more than 1 px at 50-60
//     deg;
//   * its sigma is honest: the median |error| / sigma over the renders is
//     within [0.2, 2];
//   * a band across the outer rings (light or dark, 10-15 % of the outer
//     ring's perimeter) does not hide the marker, centre within 0.1 px;
//   * small markers: three rings of 17 px outer radius, four of 20 px;
//   * a crowded board of 4 x 3 markers: each found once, nothing between;
//   * a marker whose outer ring the image border cuts is measured, one cut
//     in half is named "partial";
//   * one or two dark rings (a tyre, the two-ring design) are no ring marker;
//   * with a target list of ring markers (their edge radii), the ID is read
//     where one listed marker matches (the radii read within 0.015 of the
//     outer radius), -1 for a design not listed or two listed alike.
#include <cstdio>

#include <gtest/gtest.h>

#include "planar_target_renderer.h"

namespace slope_monitor {
namespace targets {
namespace ring_markers_rendered {

using testing::Apply;

constexpr double kLight = 0.9, kDark = 0.08;

// A ring design: the dark rings' (inner, outer) radii, in outer radii.
using Rings = std::vector<std::pair<double, double>>;

const std::vector<Rings>& Designs() {
  static const std::vector<Rings> d = {
      {{0.45, 0.55}, {0.65, 0.78}, {0.88, 1.0}},           // CCTag-like, 3 rings
      {{0.3, 0.42}, {0.5, 0.58}, {0.7, 0.8}, {0.9, 1.0}},  // 4 rings, unequal widths
      {{0.3, 0.36}, {0.44, 0.5}, {0.58, 0.64}, {0.72, 0.8}, {0.9, 1.0}}};  // 5 thin rings
  return d;
}

struct Shot {
  cv::Mat image;
  Eigen::Vector2d truth;  // the projected centre of the rings
  Eigen::Matrix3d h;      // plane [m] -> pixel
};

// A marker of outer radius 0.1 m, its normal tilted by tilt_deg from the
// line of sight, at `depth` [m] in front of a 640 x 480 camera of focal 600
// px, its centre imaged at `at` (+ a sub-pixel part from the seed).
// An occluder in front of the plate: a band across it (plate coordinates
// [m]: u from u0 to 0.2, |v| <= half), of reflectance `level`.
struct Occluder {
  double u0 = 1.0, half = 0.0, level = kLight;
};

Shot Render(const Rings& rings, double tilt_deg, double depth, double blur,
            const Eigen::Vector2d& at, unsigned seed, const Occluder& occ = Occluder()) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double f = 600.0, cx = 319.5, cy = 239.5, radius = 0.1;
  const Eigen::Vector2d px = at + Eigen::Vector2d(uni(rng), uni(rng));
  const Eigen::Vector3d centre((px.x() - cx) / f * depth, (px.y() - cy) / f * depth, depth);
  const double az = 2 * M_PI * uni(rng), t = tilt_deg * M_PI / 180.0;
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(t, Eigen::Vector3d(std::cos(az), std::sin(az), 0)).toRotationMatrix() *
      Eigen::AngleAxisd(2 * M_PI * uni(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  Eigen::Matrix3d k;
  k << f, 0, cx, 0, f, cy, 0, 0, 1;
  Eigen::Matrix3d rt;
  rt << r.col(0), r.col(1), centre;
  Shot s;
  s.h = k * rt;
  s.truth = Apply(s.h, 0, 0);
  testing::RenderOptions ro;
  ro.background = kLight;
  ro.read_noise = 1.0;
  ro.photons_per_dn = 50.0;
  ro.seed = seed;
  cv::Mat img = testing::Background(640, 480, ro);
  const testing::Pattern pattern = [=](double u, double v) {
    if (u >= occ.u0 && std::abs(v) <= occ.half) return occ.level;
    const double q = std::hypot(u, v) / radius;
    for (const auto& [a, b] : rings)
      if (q >= a && q <= b) return kDark;
    return q <= 1.2 ? kLight : q <= 2.0 && occ.half > 0 ? kLight : -1.0;
  };
  testing::RenderPlate(&img, s.h, pattern, 2.0 * radius, ro);
  if (blur > 0) cv::GaussianBlur(img, img, cv::Size(0, 0), blur, blur, cv::BORDER_REPLICATE);
  s.image = testing::ToMono8(img, ro);
  return s;
}

Options CirclesOnly() {
  Options o;
  o.families.clear();
  return o;
}

struct Case {
  double tilt, depth, blur;
};

TEST(RingMarkersRendered, EachDesignFoundOnceCentredWithoutAPose) {
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  std::vector<double> z;
  double worst = 0.0, worst_ellipse = 0.0;
  unsigned seed = 11;
  for (size_t d = 0; d < Designs().size(); ++d) {
    for (const Case& cs : {Case{0, 1.0, 0}, Case{50, 1.0, 0}, Case{50, 0.6, 0}, Case{60, 1.5, 0},
                           Case{40, 1.0, 1.5}}) {
      const Shot s = Render(Designs()[d], cs.tilt, cs.depth, cs.blur, {300, 230}, ++seed);
      const Result r = c.Detect(s.image, "mono8");
      const std::string what = std::to_string(Designs()[d].size()) + " rings, tilt " +
                               std::to_string(cs.tilt) + ", depth " + std::to_string(cs.depth) +
                               ", blur " + std::to_string(cs.blur);
      ASSERT_EQ(r.observations.size(), 1u) << what << ": " << r.rejections.size() << " rejected";
      const Observation& o = r.observations[0];
      EXPECT_EQ(o.method, CentreMethod::kRingCentre) << what;
      EXPECT_EQ(o.rings, static_cast<int>(Designs()[d].size())) << what;
      const Eigen::Vector2d e = o.centre - s.truth;
      worst = std::max(worst, e.norm());
      for (int k : {0, 1}) z.push_back(std::abs(e[k]) / std::sqrt(o.covariance(k, k)));
      // The innermost ellipse's centre: the projection of its circle's rim.
      const double r0 = 0.1 * Designs()[d][0].first;
      std::vector<cv::Point2f> rim;
      for (int i = 0; i < 72; ++i) {
        const Eigen::Vector2d p =
            Apply(s.h, r0 * std::cos(i * M_PI / 36), r0 * std::sin(i * M_PI / 36));
        rim.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
      }
      const cv::RotatedRect inner = cv::fitEllipse(rim);
      if (cs.tilt >= 50)
        worst_ellipse = std::max(
            worst_ellipse, (Eigen::Vector2d(inner.center.x, inner.center.y) - s.truth).norm());
      std::printf("%-40s error (%+.4f, %+.4f) px, sigma %.4f px\n", what.c_str(), e.x(), e.y(),
                  std::sqrt(0.5 * o.covariance.trace()));
    }
  }
  std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
  std::printf(
      "worst error %.4f px (innermost ellipse's centre at 50-60 deg: %.4f px), median "
      "|error| / sigma %.2f\n",
      worst, worst_ellipse, z[z.size() / 2]);
  EXPECT_LE(worst, 0.1);
  EXPECT_GT(worst_ellipse, 1.0);
  EXPECT_GE(z[z.size() / 2], 0.2);
  EXPECT_LE(z[z.size() / 2], 2.0);
}

// A target list of ring markers (id: the rings' edge radii).
io::TargetList RingList(const std::vector<std::pair<int, Rings>>& markers) {
  io::TargetList list;
  for (const auto& [id, rings] : markers) {
    io::TargetSpec s;
    s.id = id;
    s.family = "circle";
    s.size = 0.2;
    for (const auto& [a, b] : rings) {
      s.rings.push_back(a);
      s.rings.push_back(b);
    }
    list.Add(s);
  }
  return list;
}

TEST(RingMarkersRendered, IdReadFromTheRadiiWhenListedElseMinusOne) {
  const Rings other3 = {{0.4, 0.5}, {0.6, 0.74}, {0.86, 1.0}};  // 0.04-0.05 from the first
  const Rings unlisted = {{0.5, 0.6}, {0.7, 0.8}, {0.9, 1.0}};
  const TargetCentroider c(CirclesOnly(),
                           RingList({{7, Designs()[0]}, {8, other3}, {9, Designs()[1]}}));
  double worst = 0.0;
  unsigned seed = 40;
  for (const auto& [rings, id] : std::vector<std::pair<Rings, int>>{
           {Designs()[0], 7}, {other3, 8}, {Designs()[1], 9}, {unlisted, -1}, {Designs()[2], -1}}) {
    for (const Case& cs :
         {Case{0, 1.0, 0}, Case{50, 0.6, 0}, Case{60, 1.0, 0}, Case{40, 1.0, 1.5}}) {
      const Shot s = Render(rings, cs.tilt, cs.depth, cs.blur, {300, 230}, ++seed);
      const Result r = c.Detect(s.image, "mono8");
      const std::string what = std::to_string(id) + ", tilt " + std::to_string(cs.tilt) +
                               ", blur " + std::to_string(cs.blur);
      ASSERT_EQ(r.observations.size(), 1u) << what;
      const Observation& o = r.observations[0];
      EXPECT_EQ(o.id, id) << what;
      ASSERT_EQ(o.ring_radii.size(), 2 * rings.size()) << what;
      for (size_t k = 0; k < rings.size(); ++k) {
        worst = std::max(worst, std::abs(o.ring_radii[2 * k] - rings[k].first));
        worst = std::max(worst, std::abs(o.ring_radii[2 * k + 1] - rings[k].second));
      }
    }
  }
  std::printf("worst edge radius read: %.4f of the outer radius\n", worst);
  EXPECT_LE(worst, 0.015);
  // Two listed markers whose radii are 0.015 apart: neither is read.
  Rings near = Designs()[0];
  for (auto& [a, b] : near) {
    a += 0.015;
    b = std::min(b + 0.015, 1.0);
  }
  const TargetCentroider twins(CirclesOnly(), RingList({{7, Designs()[0]}, {10, near}}));
  const Result r = twins.Detect(Render(Designs()[0], 30, 1.0, 0, {300, 230}, 77).image, "mono8");
  ASSERT_EQ(r.observations.size(), 1u);
  EXPECT_EQ(r.observations[0].id, -1);
}

TEST(RingMarkersRendered, PartlyOccludedIsFound) {
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  // A light band across the two outer rings, a light and a dark one across
  // the outer ring (a dark one across two rings joins them: not found).
  for (const Occluder& occ : {Occluder{0.07, 0.03, kLight}, Occluder{0.085, 0.05, kLight},
                              Occluder{0.085, 0.05, kDark}}) {
    const Shot s = Render(Designs()[0], 30, 1.0, 0, {300, 230}, 9, occ);
    const Result r = c.Detect(s.image, "mono8");
    const std::string what = std::string(occ.level == kLight ? "light" : "dark") + " band from " +
                             std::to_string(occ.u0) + " m, half width " + std::to_string(occ.half) +
                             " m";
    ASSERT_EQ(r.observations.size(), 1u) << what;
    EXPECT_EQ(r.observations[0].method, CentreMethod::kRingCentre) << what;
    const Eigen::Vector2d e = r.observations[0].centre - s.truth;
    std::printf("occluded, %s: error (%+.4f, %+.4f) px\n", what.c_str(), e.x(), e.y());
    EXPECT_LE(e.norm(), 0.1) << what;
  }
}

TEST(RingMarkersRendered, SmallMarkersAreFound) {
  // 30 deg oblique, blurred by 0.7 px: three rings with an outer radius of
  // 17 px (rings and gaps 1.7-2.2 px wide), four rings of 20 px.
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  for (const auto& [d, depth] : std::vector<std::pair<size_t, double>>{{0, 3.5}, {1, 3.0}}) {
    for (unsigned seed = 1; seed <= 4; ++seed) {
      const Shot s = Render(Designs()[d], 30, depth, 0.7, {300, 230}, seed);
      const Result r = c.Detect(s.image, "mono8");
      ASSERT_EQ(r.observations.size(), 1u) << Designs()[d].size() << " rings, seed " << seed;
      EXPECT_EQ(r.observations[0].method, CentreMethod::kRingCentre);
      EXPECT_LE((r.observations[0].centre - s.truth).norm(), 0.15);
    }
  }
}

TEST(RingMarkersRendered, CrowdedBoardEveryMarkerOnce) {
  // 4 x 3 markers of three rings, 0.24 m apart (0.04 m of light between
  // neighbours' outer rings), 35 deg oblique at 2.5 m (outer radius ~24 px).
  const double pitch = 0.24, radius = 0.1, f = 600.0, depth = 2.5;
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(35 * M_PI / 180, Eigen::Vector3d(0.6, 0.8, 0)).toRotationMatrix();
  Eigen::Matrix3d k, rt;
  k << f, 0, 319.5, 0, f, 239.5, 0, 0, 1;
  rt << r.col(0), r.col(1), Eigen::Vector3d(0.013, -0.021, depth);
  const Eigen::Matrix3d h = k * rt;
  const Rings& rings = Designs()[0];
  const testing::Pattern pattern = [=](double u, double v) {
    const double iu = std::clamp(std::round(u / pitch + 1.5), 0.0, 3.0) - 1.5,
                 iv = std::clamp(std::round(v / pitch + 1.0), 0.0, 2.0) - 1.0;
    const double q = std::hypot(u - iu * pitch, v - iv * pitch) / radius;
    for (const auto& [a, b] : rings)
      if (q >= a && q <= b) return kDark;
    return kLight;
  };
  testing::RenderOptions ro;
  ro.background = kLight;
  ro.read_noise = 1.0;
  ro.photons_per_dn = 50.0;
  cv::Mat img = testing::Background(640, 480, ro);
  testing::RenderPlate(&img, h, pattern, 2.5 * pitch, ro);
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  const Result res = c.Detect(testing::ToMono8(img, ro), "mono8");
  int found = 0;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector2d truth = Apply(h, (i - 1.5) * pitch, (j - 1.0) * pitch);
      int here = 0;
      for (const Observation& o : res.observations)
        if ((o.centre - truth).norm() < 10) {
          ++here;
          EXPECT_EQ(o.method, CentreMethod::kRingCentre);
          EXPECT_LE((o.centre - truth).norm(), 0.15) << i << ", " << j;
        }
      EXPECT_EQ(here, 1) << "marker " << i << ", " << j;
      found += here;
    }
  }
  EXPECT_EQ(res.observations.size(), 12u);
  std::printf("crowded board: %d of 12 markers found once, %zu observations\n", found,
              res.observations.size());
}

TEST(RingMarkersRendered, OuterRingCutByTheBorderIsMeasured) {
  // Facing the camera, the centre 0.8 outer radii from the left border: a
  // tenth of the outer ring is outside the image.
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  const Shot s = Render(Designs()[0], 0, 1.0, 0, {47, 240}, 3);
  const Result r = c.Detect(s.image, "mono8");
  ASSERT_EQ(r.observations.size(), 1u) << r.rejections.size() << " rejected";
  EXPECT_EQ(r.observations[0].method, CentreMethod::kRingCentre);
  EXPECT_LE((r.observations[0].centre - s.truth).norm(), 0.15);
}

TEST(RingMarkersRendered, CutByTheBorderIsNamedPartial) {
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  const Shot s = Render(Designs()[0], 20, 1.0, 0, {2, 240}, 3);
  const Result r = c.Detect(s.image, "mono8");
  EXPECT_TRUE(r.observations.empty());
  ASSERT_EQ(r.rejections.size(), 1u);
  EXPECT_EQ(r.rejections[0].reason, RejectReason::kPartial) << r.rejections[0].detail;
  EXPECT_LT((r.rejections[0].where - s.truth).norm(), 10.0);
}

TEST(RingMarkersRendered, OneOrTwoRingsAreNoRingMarker) {
  const TargetCentroider c(CirclesOnly(), io::TargetList());
  for (const Rings& rings : {Rings{{0.4, 1.0}}, Rings{{0.55, 0.7}, {0.85, 1.0}}}) {
    const Shot s = Render(rings, 30, 1.0, 0, {300, 230}, 5);
    const Result r = c.Detect(s.image, "mono8");
    for (const Observation& o : r.observations)
      EXPECT_NE(o.method, CentreMethod::kRingCentre) << rings.size() << " rings";
  }
}

}  // namespace ring_markers_rendered
}  // namespace targets
}  // namespace slope_monitor
