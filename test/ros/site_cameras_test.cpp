// Issue 18: a site file's camera list (any names, any number; the kind a
// field) decides which cameras the bundle adjuster waits for and on which
// topics, and which of them the dense step pairs as UAV photos. What the
// replay and live graphs run with `site:=` (launch/include/processing_graph.xml).
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/param_files.h"
#include "slope_monitor/ros/parameters.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

using Strings = std::vector<std::string>;

// A site whose cameras are not named like the simulator's, the UAV not "uav".
std::string WriteSite() {
  const std::string path =
      "/tmp/slope_monitor_site_cameras_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(path) << "name: cameras_test\n"
                         "crs: EPSG:4979\n"
                         "origin: [8.0, 46.5, 1200.0]\n"
                         "cameras:\n"
                         "  - {name: north_mast, kind: fixed, pixel_size: 0.0039}\n"
                         "  - {name: drone, kind: uav, pixel_size: 0.0033}\n"
                         "  - {name: south_mast, kind: fixed, pixel_size: 0.0048}\n";
  return path;
}

XmlRpc::XmlRpcValue Defaults(const std::string& node) {
  return LoadParamFile(std::string(SM_SOURCE_DIR) + "/config/defaults/" + node + ".yaml");
}

TEST(SiteCameras, TheSiteDecidesTheAdjustersCamerasAndTopics) {
  const std::string site = WriteSite();
  XmlRpc::XmlRpcValue p = Defaults("bundle_adjuster");
  SetParam(&p, "site_file", site);
  SetParam(&p, "target_list",
           std::string(SM_SOURCE_DIR) + "/test/rostest/service_switches.targets.yaml");
  ParamReader r(p, "/bundle_adjuster");
  const AdjusterParameters a = ReadAdjusterParameters(r);
  EXPECT_TRUE(a.cameras_from_site);
  EXPECT_EQ(a.collector.cameras, (Strings{"north_mast", "drone", "south_mast"}));
  EXPECT_EQ(a.target_topics, (Strings{"/north_mast/targets", "/drone/targets", "/south_mast/targets"}));
  EXPECT_EQ(a.epoch_topics, (Strings{"/north_mast/camera/epoch", "/drone/camera/epoch",
                                     "/south_mast/camera/epoch"}));
  EXPECT_EQ(a.prior_topics, (Strings{"/drone/camera/position_prior"}));
  EXPECT_EQ(a.CameraInfoTopic("south_mast"), "/south_mast/camera/camera_info");
  ASSERT_TRUE(a.collector.uav_cameras.has_value());
  EXPECT_EQ(*a.collector.uav_cameras, (Strings{"drone"}));  // by kind, not by name
  EXPECT_DOUBLE_EQ(a.PixelSizeOf("north_mast"), 0.0039);
  EXPECT_DOUBLE_EQ(a.PixelSizeOf("drone"), 0.0033);
  ::unlink(site.c_str());
}

TEST(SiteCameras, WithoutASiteTheParametersAndRelativeTopicsStay) {
  XmlRpc::XmlRpcValue p = Defaults("bundle_adjuster");
  SetParam(&p, "target_list",
           std::string(SM_SOURCE_DIR) + "/test/rostest/service_switches.targets.yaml");
  ParamReader r(p, "/bundle_adjuster");
  const AdjusterParameters a = ReadAdjusterParameters(r);
  EXPECT_FALSE(a.cameras_from_site);
  EXPECT_EQ(a.target_topics, (Strings{"targets"}));
  EXPECT_EQ(a.epoch_topics, (Strings{"epoch"}));
  EXPECT_EQ(a.prior_topics, (Strings{"position_prior"}));
  EXPECT_EQ(a.CameraInfoTopic("fixed_cam_1"), "fixed_cam_1/camera_info");
}

TEST(SiteCameras, TheDenseStepPairsTheSitesUavCameras) {
  const std::string site = WriteSite();
  XmlRpc::XmlRpcValue p = Defaults("dense_epoch");
  SetParam(&p, "site_file", site);
  ParamReader r(p, "/dense/dense_matcher");
  const DenseEpochParameters d = ReadDenseEpochParameters(r);
  EXPECT_EQ(d.cameras, (Strings{"north_mast", "drone", "south_mast"}));
  EXPECT_EQ(d.uav_cameras, (Strings{"drone"}));
  EXPECT_EQ(d.photos.uav_cameras, (Strings{"drone"}));
  ::unlink(site.c_str());
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
