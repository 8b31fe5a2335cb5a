// dense::IntersectDem, the window-straddle term and the options of the
// displacement field, checked by hand: rays against planes, the DEM's edge and
// nodata; three probes in a row.
#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/displacement_field.h"

namespace slope_monitor {
namespace dense {
namespace {

// A 100 m x 100 m DEM (1 m cells, x 0..100, y 0..100) of the plane z = a x + b.
io::GeoRaster Plane(double a, double b) {
  io::GeoRaster dem(100, 100, 0.0, 100.0, 1.0);
  dem.AddBand("height");
  for (int r = 0; r < 100; ++r)
    for (int c = 0; c < 100; ++c)
      dem.At(0, r, c) = static_cast<float>(a * dem.CellCentre(r, c).x() + b);
  return dem;
}

TEST(IntersectDem, RayMeetsAFlatPlaneWhereGeometrySays) {
  // From (10, 50, 30) down at 45 deg towards +x: meets z = 0 at x = 40, t = 30 sqrt(2).
  const io::GeoRaster dem = Plane(0.0, 0.0);
  double t = 0;
  ASSERT_TRUE(IntersectDem(dem, {10, 50, 30}, Eigen::Vector3d(1, 0, -1), 1000.0, &t));
  EXPECT_NEAR(t, 30 * std::sqrt(2.0), 1e-6);
}

TEST(IntersectDem, RayMeetsATiltedPlane) {
  // z = 0.5 x + 2; from (0, 50, 40) horizontally towards +x: 40 = 0.5 x + 2 -> x = 76.
  const io::GeoRaster dem = Plane(0.5, 2.0);
  double t = 0;
  ASSERT_TRUE(IntersectDem(dem, {0, 50, 40}, Eigen::Vector3d(1, 0, 0), 1000.0, &t));
  EXPECT_NEAR(t, 76.0, 1e-6);
}

TEST(IntersectDem, MissesBeyondTheEdgeAndOnNodata) {
  const io::GeoRaster dem = Plane(0.0, 0.0);
  double t = 0;
  // Upwards: never meets it.
  EXPECT_FALSE(IntersectDem(dem, {10, 50, 30}, Eigen::Vector3d(1, 0, 0.1), 1000.0, &t));
  // Would meet z = 0 at x = 130, outside the DEM.
  EXPECT_FALSE(IntersectDem(dem, {10, 50, 120}, Eigen::Vector3d(1, 0, -1), 1000.0, &t));
  // Beyond max_range.
  EXPECT_FALSE(IntersectDem(dem, {10, 50, 30}, Eigen::Vector3d(1, 0, -1), 20.0, &t));
  // A hole of nodata where it would meet: no surface there.
  io::GeoRaster holed = dem;
  for (int r = 40; r < 60; ++r)
    for (int c = 30; c < 50; ++c) holed.At(0, r, c) = std::numeric_limits<float>::quiet_NaN();
  EXPECT_FALSE(IntersectDem(holed, {10, 50, 30}, Eigen::Vector3d(1, 0, -1), 1000.0, &t));
}

TEST(DisplacementFieldOptions, CheckNamesTheField) {
  DisplacementFieldOptions o;
  EXPECT_NO_THROW(o.Check());
  o.min_incidence_deg = 90;
  try {
    o.Check();
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("min_incidence_deg"), std::string::npos) << e.what();
  }
}

// Three probes in a row, 32 px apart, sigma 1 cm in x and y; the third moved
// 0.1 m east. Probes 2 and 3 differ by 0.1 m > 3 x sqrt(2) x 1 cm: across a
// 10 px half window the motion changes by w = 0.1 x 10 / 32 m, variance
// w^2 / 3 along x. Probe 1's only neighbour (probe 2, within 1.5 x 32 px)
// moves as it does: no term.
TEST(WindowStraddleTerms, ChangeAcrossTheWindowFromSignificantNeighbours) {
  std::vector<FieldPoint> points(3);
  for (int i = 0; i < 3; ++i) {
    points[i].xa = Eigen::Vector2d(100 + 32 * i, 200);
    points[i].covariance = Eigen::Vector3d(1e-4, 1e-4, 1e-4).asDiagonal();
  }
  points[2].displacement = Eigen::Vector3d(0.1, 0, 0);
  const std::vector<Eigen::Matrix3d> t = WindowStraddleTerms(3.0, 10, points);
  ASSERT_EQ(t.size(), 3u);
  EXPECT_TRUE(t[0].isZero());
  const double w = 0.1 * 10.0 / 32.0;
  for (int i : {1, 2}) {
    EXPECT_NEAR(t[i](0, 0), w * w / 3.0, 1e-12) << i;
    EXPECT_NEAR(t[i].norm(), w * w / 3.0, 1e-12) << i;  // along x only
  }
  // A difference within noise (2 cm < 3 x sqrt(2) x 1 cm): no term; off: none.
  points[2].displacement = Eigen::Vector3d(0.02, 0, 0);
  for (const Eigen::Matrix3d& m : WindowStraddleTerms(3.0, 10, points)) EXPECT_TRUE(m.isZero());
  points[2].displacement = Eigen::Vector3d(0.1, 0, 0);
  for (const Eigen::Matrix3d& m : WindowStraddleTerms(0.0, 10, points)) EXPECT_TRUE(m.isZero());
  // A flagged probe neither gets nor gives a term.
  points[2].flag = "grazing";
  for (const Eigen::Matrix3d& m : WindowStraddleTerms(3.0, 10, points)) EXPECT_TRUE(m.isZero());
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
