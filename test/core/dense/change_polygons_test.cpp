// Polygons of significant change from hand-made DoDs: 20 x 20 cells of 0.5 m
// (origin x 100, northern edge y 210).
#include "slope_monitor/core/dense/change_polygons.h"

#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {
namespace {

constexpr double kCell = 0.5;

io::GeoRaster EmptyDoD() {
  io::GeoRaster r(20, 20, 100.0, 210.0, kCell);
  r.AddBand("change", 0.0f);
  r.AddBand("lod", 0.1f);
  r.AddBand("class", 0.0f);
  return r;
}

void Fill(io::GeoRaster* r, int row0, int col0, int rows, int cols, float dz, float cls) {
  for (int row = row0; row < row0 + rows; ++row)
    for (int col = col0; col < col0 + cols; ++col) {
      r->At(kChange, row, col) = dz;
      r->At(kClass, row, col) = cls;
    }
}

double ShoelaceArea(const Polygon& p) {
  double a = 0.0;
  for (size_t i = 0; i < p.size(); ++i) {
    const Eigen::Vector2d& u = p[i];
    const Eigen::Vector2d& v = p[(i + 1) % p.size()];
    a += u.x() * v.y() - v.x() * u.y();
  }
  return std::abs(a) / 2.0;
}

TEST(ChangePolygons, SquareOfChangeIsOnePolygonOfItsArea) {
  io::GeoRaster dod = EmptyDoD();
  Fill(&dod, 4, 6, 6, 6, 0.30f, 2.0f);  // 6 x 6 cells = 3 m x 3 m = 9 m^2, +0.30 m
  const std::vector<ChangePolygon> p = ChangePolygons(dod, ChangePolygonOptions());
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0].sign, +1);
  EXPECT_EQ(p[0].cells, 36);
  EXPECT_NEAR(p[0].area, 9.0, 1e-9);
  EXPECT_NEAR(ShoelaceArea(p[0].outline), 9.0, 1e-9);
  EXPECT_NEAR(p[0].volume, 9.0 * 0.30, 1e-5);
  EXPECT_NEAR(p[0].mean_change, 0.30, 1e-6);
  EXPECT_TRUE(p[0].holes.empty());
  // Its corners: columns 6..12 -> x 103..106, rows 4..10 -> y 208..205.
  double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
  for (const Eigen::Vector2d& v : p[0].outline) {
    x0 = std::min(x0, v.x()), x1 = std::max(x1, v.x());
    y0 = std::min(y0, v.y()), y1 = std::max(y1, v.y());
  }
  EXPECT_DOUBLE_EQ(x0, 103.0);
  EXPECT_DOUBLE_EQ(x1, 106.0);
  EXPECT_DOUBLE_EQ(y0, 205.0);
  EXPECT_DOUBLE_EQ(y1, 208.0);
}

TEST(ChangePolygons, SignsSeparateAndSmallRegionsDrop) {
  io::GeoRaster dod = EmptyDoD();
  Fill(&dod, 2, 2, 4, 4, -0.5f, -2.0f);  // loss, 4 m^2
  Fill(&dod, 2, 6, 4, 8, 0.2f, 1.0f);    // gain next to it (touching), 8 m^2
  Fill(&dod, 15, 15, 1, 1, 0.9f, 2.0f);  // one cell, 0.25 m^2 < min_area
  Fill(&dod, 17, 2, 2, 2, 0.05f, 0.0f);  // not significant
  const std::vector<ChangePolygon> p = ChangePolygons(dod, ChangePolygonOptions());
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].sign, +1);  // largest first
  EXPECT_NEAR(p[0].area, 8.0, 1e-9);
  EXPECT_NEAR(p[0].volume, 8.0 * 0.2, 1e-5);
  EXPECT_EQ(p[1].sign, -1);
  EXPECT_NEAR(p[1].area, 4.0, 1e-9);
  EXPECT_NEAR(p[1].volume, -4.0 * 0.5, 1e-5);
  EXPECT_NEAR(p[1].max_change, -0.5, 1e-6);

  ChangePolygonOptions only_strong;  // class +-2 only: the +1 gain is not traced
  only_strong.min_class = 2;
  const std::vector<ChangePolygon> strong = ChangePolygons(dod, only_strong);
  ASSERT_EQ(strong.size(), 1u);
  EXPECT_EQ(strong[0].sign, -1);
}

TEST(ChangePolygons, RingWithAHole) {
  io::GeoRaster dod = EmptyDoD();
  Fill(&dod, 4, 4, 8, 8, 0.4f, 2.0f);  // 16 m^2 ...
  Fill(&dod, 6, 6, 4, 4, 0.0f, 0.0f);  // ... less a 2 m x 2 m hole = 12 m^2
  const std::vector<ChangePolygon> p = ChangePolygons(dod, ChangePolygonOptions());
  ASSERT_EQ(p.size(), 1u);
  EXPECT_NEAR(p[0].area, 12.0, 1e-9);
  ASSERT_EQ(p[0].holes.size(), 1u);
  EXPECT_NEAR(ShoelaceArea(p[0].outline) - ShoelaceArea(p[0].holes[0]), 12.0, 1e-9);
}

TEST(ChangePolygons, BadInputIsNamed) {
  io::GeoRaster no_class(4, 4, 0.0, 4.0, 1.0);
  no_class.AddBand("change", 0.0f);
  try {
    ChangePolygons(no_class, ChangePolygonOptions());
    FAIL() << "no class band accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'class'"), std::string::npos) << e.what();
  }
  ChangePolygonOptions o;
  o.min_class = 3;
  EXPECT_THROW(ChangePolygons(EmptyDoD(), o), InvalidArgument);
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
