// The areas of surface change from the dense node to the estimator: a DoD's
// polygons -> ChangeAreaArray -> the estimator's AreaBatch keep every number
// and ring (a hand-made DoD: a 3 m x 3 m gain with a 1 m x 1 m hole).
#include "slope_monitor/ros/change_area_conversions.h"

#include <gtest/gtest.h>

namespace slope_monitor {
namespace {

TEST(ChangeAreaConversions, PolygonsReachTheEstimatorUnchanged) {
  io::GeoRaster dod(10, 10, 50.0, 80.0, 0.5);  // x 50..55, y 75..80
  dod.AddBand("change", 0.0f);
  dod.AddBand("lod", 0.1f);
  dod.AddBand("class", 0.0f);
  for (int r = 2; r < 8; ++r)
    for (int c = 2; c < 8; ++c) {
      const bool hole = r >= 4 && r < 6 && c >= 4 && c < 6;
      dod.At(dense::kChange, r, c) = hole ? 0.0f : 0.25f;
      dod.At(dense::kClass, r, c) = hole ? 0.0f : 2.0f;
    }
  const std::vector<dense::ChangePolygon> polygons =
      dense::ChangePolygons(dod, dense::ChangePolygonOptions());
  ASSERT_EQ(polygons.size(), 1u);
  std_msgs::Header h;
  h.stamp = ros::Time(1700021600.0);
  h.frame_id = "site";
  const slope_monitor::ChangeAreaArray msg = ros_adapters::ToChangeAreaMsg(polygons, 3, 0, h);
  ASSERT_EQ(msg.areas.size(), 1u);
  EXPECT_EQ(msg.areas[0].sign, 1);
  const deformation::AreaBatch b = ros_adapters::AreaBatchFromMsg(msg, "/dense/change_areas");
  EXPECT_EQ(b.epoch, 3u);
  EXPECT_EQ(b.reference_epoch, 0u);
  EXPECT_DOUBLE_EQ(b.stamp, 1700021600.0);
  EXPECT_EQ(b.source_name, "/dense/change_areas");
  ASSERT_EQ(b.areas.size(), 1u);
  const deformation::ChangeArea& a = b.areas[0];
  EXPECT_DOUBLE_EQ(a.area, 9.0 - 1.0);
  EXPECT_NEAR(a.volume, 8.0 * 0.25, 1e-5);
  EXPECT_EQ(a.sign, 1);
  ASSERT_EQ(a.outline.size(), polygons[0].outline.size());
  for (size_t k = 0; k < a.outline.size(); ++k)
    EXPECT_NEAR((a.outline[k] - polygons[0].outline[k]).norm(), 0.0, 1e-5);  // float32 in the msg
  ASSERT_EQ(a.holes.size(), 1u);
  EXPECT_EQ(a.holes[0].size(), polygons[0].holes[0].size());
}

}  // namespace
}  // namespace slope_monitor
