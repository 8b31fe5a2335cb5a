// Surface change by hand: 3 x 2 cells of 2 m (4 m^2), uncertainties 0.1 m.
#include "slope_monitor/core/dense/change.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {
namespace {

io::GeoRaster ChangeModel(const std::vector<float>& z) {
  io::GeoRaster r(3, 2, 0.0, 4.0, 2.0);
  r.AddBand("height");
  r.AddBand("uncertainty", 0.1f);
  r.bands[0] = z;
  return r;
}

TEST(SurfaceChange, CutAndFillByHand) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const io::GeoRaster before = ChangeModel({10, 10, 10, 10, 10, nan});
  const io::GeoRaster after = ChangeModel({10.5f, 10.2f, 9.0f, 10.0f, 10.1f, 10.0f});
  ChangeOptions o;  // LoD = 1.96 * sqrt(0.01 + 0.01) = 0.2772 m
  const ChangeResult c = SurfaceChange(before, after, o);
  EXPECT_EQ(c.summary.cells_compared, 5);
  EXPECT_EQ(c.summary.cells_missing, 1);
  EXPECT_EQ(c.summary.cells_gain, 1);  // +0.5 (the +0.2 and +0.1 are below the LoD)
  EXPECT_EQ(c.summary.cells_loss, 1);  // -1.0
  EXPECT_NEAR(c.summary.volume_gain, 0.5 * 4.0, 1e-5);
  EXPECT_NEAR(c.summary.volume_loss, 1.0 * 4.0, 1e-5);
  EXPECT_NEAR(c.summary.volume_net, -2.0, 1e-5);
  EXPECT_NEAR(c.summary.volume_net_all, (0.5 + 0.2 - 1.0 + 0.0 + 0.1) * 4.0, 1e-5);
  EXPECT_NEAR(c.summary.sigma_gain, std::sqrt(0.02) * 4.0, 1e-6);
  EXPECT_NEAR(c.change.At(kLod, 0, 0), 1.96 * std::sqrt(0.02), 1e-6);
  EXPECT_EQ(c.change.At(kSignificant, 0, 0), 1.0f);
  EXPECT_EQ(c.change.At(kSignificant, 0, 2), -1.0f);
  EXPECT_EQ(c.change.At(kSignificant, 0, 1), 0.0f);
  EXPECT_TRUE(c.change.IsNoData(c.change.At(kDz, 1, 2)));  // hole stays a hole
  ASSERT_EQ(c.significant.size(), 2u);
  EXPECT_DOUBLE_EQ(c.significant[0].x_in_site.x(), 1.0);
  EXPECT_DOUBLE_EQ(c.significant[0].x_in_site.y(), 3.0);
  EXPECT_FLOAT_EQ(c.significant[0].x_in_site.z(), 10.5f);
}

TEST(SurfaceChange, DifferentGridsAreRejected) {
  io::GeoRaster a = ChangeModel({1, 1, 1, 1, 1, 1});
  io::GeoRaster b = a;
  b.origin_x = 1.0;
  EXPECT_THROW(SurfaceChange(a, b, ChangeOptions()), InvalidArgument);
  ChangeOptions bad;
  bad.lod_factor = -1;
  EXPECT_THROW(SurfaceChange(a, a, bad), ConfigError);
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
