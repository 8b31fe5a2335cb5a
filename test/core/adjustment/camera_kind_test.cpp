// A camera's kind comes from the site file's list, never from its name;
// without a site file, from the graph's default cameras (io::DefaultCameras).
#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/site_options.h"

namespace slope_monitor {
namespace adjustment {
namespace {

TEST(CameraKind, TheSiteListDecidesNotTheName) {
  const std::vector<std::string> site = {"drone_north"};
  EXPECT_TRUE(IsUavCamera("drone_north", site));
  EXPECT_FALSE(IsUavCamera("uav_mast_cam", site));  // a fixed camera whose name contains "uav"
  EXPECT_FALSE(IsUavCamera("uav", std::vector<std::string>{}));  // a site without UAV cameras
  // No site file: the graph's default cameras, by their kind field.
  const EpochCollectorOptions defaults;
  EXPECT_EQ(defaults.uav_cameras, std::vector<std::string>{"uav"});
  EXPECT_EQ(BuildSceneOptions().uav_cameras, defaults.uav_cameras);
  EXPECT_FALSE(IsUavCamera("fixed_cam_1", defaults.uav_cameras));
  EXPECT_FALSE(IsUavCamera("uav_2", defaults.uav_cameras));  // no name rule
  const std::vector<io::SiteCamera> graph = io::DefaultCameras();
  ASSERT_EQ(graph.size(), 3u);
  EXPECT_EQ(io::CameraNames(graph, io::CameraKind::kFixed),
            (std::vector<std::string>{"fixed_cam_1", "fixed_cam_2"}));
}

TEST(CameraKind, FromTheShippedDemoSite) {
  const io::SiteFile site =
      io::LoadSiteFile(std::string(SM_SOURCE_DIR) + "/config/sites/demo.yaml");
  EpochCollectorOptions collector;
  BuildSceneOptions scene;
  const std::map<std::string, double> pixel_size = ApplySite(site, &collector, &scene);
  EXPECT_EQ(collector.uav_cameras, std::vector<std::string>{"uav"});
  EXPECT_EQ(scene.uav_cameras, collector.uav_cameras);
  EXPECT_EQ(pixel_size.size(), 3u);
  EXPECT_DOUBLE_EQ(pixel_size.at("fixed_cam_1"), 0.0048);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
