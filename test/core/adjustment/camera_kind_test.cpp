// A camera's kind comes from the site file's list when there is one, never
// from its name; without a list the graph's naming rule applies.
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/site_options.h"

namespace slope_monitor {
namespace adjustment {
namespace {

TEST(CameraKind, TheSiteListDecidesNotTheName) {
  const std::optional<std::vector<std::string>> site = std::vector<std::string>{"drone_north"};
  EXPECT_TRUE(IsUavCamera("drone_north", site));
  EXPECT_FALSE(IsUavCamera("uav_mast_cam", site));  // a fixed camera whose name contains "uav"
  EXPECT_FALSE(IsUavCamera("uav", std::vector<std::string>{}));  // a site without UAV cameras
  // No site list: the graph's names (fixed_cam_1, fixed_cam_2, uav).
  EXPECT_TRUE(IsUavCamera("uav", std::nullopt));
  EXPECT_FALSE(IsUavCamera("fixed_cam_1", std::nullopt));
}

TEST(CameraKind, FromTheShippedDemoSite) {
  const io::SiteFile site =
      io::LoadSiteFile(std::string(SM_SOURCE_DIR) + "/config/sites/demo.yaml");
  EpochCollectorOptions collector;
  BuildSceneOptions scene;
  const std::map<std::string, double> pixel_size = ApplySite(site, &collector, &scene);
  ASSERT_TRUE(collector.uav_cameras.has_value());
  EXPECT_EQ(*collector.uav_cameras, std::vector<std::string>{"uav"});
  EXPECT_EQ(scene.uav_cameras, collector.uav_cameras);
  EXPECT_EQ(pixel_size.size(), 3u);
  EXPECT_DOUBLE_EQ(pixel_size.at("fixed_cam_1"), 0.0048);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
