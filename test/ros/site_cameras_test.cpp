// Issue 18: a site file's camera list (any names, any number; the kind a
// field) decides which cameras the bundle adjuster waits for and on which
// topics, and which of them the dense step pairs as UAV photos. What the
// replay and live graphs run with `site:=` (launch/include/processing_graph.xml).
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"
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
  // The UAV camera's picks (camera_capture with a gcp list) are target observations too.
  EXPECT_EQ(a.target_topics, (Strings{"/north_mast/targets", "/drone/targets",
                                      "/drone/camera/picks", "/south_mast/targets"}));
  EXPECT_EQ(a.epoch_topics, (Strings{"/north_mast/camera/epoch", "/drone/camera/epoch",
                                     "/south_mast/camera/epoch"}));
  EXPECT_EQ(a.prior_topics, (Strings{"/drone/camera/position_prior"}));
  EXPECT_EQ(a.tie_topics, (Strings{"/drone/tie_points"}));
  EXPECT_TRUE(a.collector.tie_point_cameras.empty());  // uav_tie_points off by default
  EXPECT_EQ(a.CameraInfoTopic("south_mast"), "/south_mast/camera/camera_info");
  EXPECT_EQ(a.collector.uav_cameras, (Strings{"drone"}));  // by kind, not by name
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
  EXPECT_EQ(a.tie_topics, (Strings{"tie_points"}));
  EXPECT_EQ(a.CameraInfoTopic("fixed_cam_1"), "fixed_cam_1/camera_info");
  EXPECT_EQ(a.collector.uav_cameras, (Strings{"uav"}));  // io::DefaultCameras()' kind uav
}

// Issue 36: the graph (launch/include/processing_graph.xml) names no camera:
// it sets graph_cameras, and without a site file the adjuster takes the
// default cameras (io::DefaultCameras()) with their topics as if a site file
// listed them; a site file's cameras still decide with it set.
TEST(SiteCameras, GraphCamerasAreTheSitesElseTheDefaultOnesOnTheirTopics) {
  XmlRpc::XmlRpcValue p = Defaults("bundle_adjuster");
  SetParam(&p, "target_list",
           std::string(SM_SOURCE_DIR) + "/test/rostest/service_switches.targets.yaml");
  SetParam(&p, "graph_cameras", true);
  ParamReader r(p, "/bundle_adjuster");
  const AdjusterParameters a = ReadAdjusterParameters(r);
  Strings cameras, targets, epochs, priors;
  for (const io::SiteCamera& c : io::DefaultCameras()) {
    cameras.push_back(c.name);
    targets.push_back("/" + c.name + "/targets");
    epochs.push_back("/" + c.name + "/camera/epoch");
    if (c.kind == io::CameraKind::kUav) {
      priors.push_back("/" + c.name + "/camera/position_prior");
      targets.push_back("/" + c.name + "/camera/picks");
    }
  }
  ASSERT_EQ(cameras.size(), 3u);
  ASSERT_EQ(priors.size(), 1u);
  EXPECT_TRUE(a.cameras_from_site);  // epochs in a replay wait only for the bag's cameras
  EXPECT_EQ(a.collector.cameras, cameras);
  EXPECT_EQ(a.target_topics, targets);
  EXPECT_EQ(a.epoch_topics, epochs);
  EXPECT_EQ(a.prior_topics, priors);
  EXPECT_EQ(a.CameraInfoTopic(cameras[0]), "/" + cameras[0] + "/camera/camera_info");

  const std::string site = WriteSite();
  SetParam(&p, "site_file", site);
  ParamReader rs(p, "/bundle_adjuster");
  const AdjusterParameters b = ReadAdjusterParameters(rs);
  EXPECT_EQ(b.collector.cameras, (Strings{"north_mast", "drone", "south_mast"}));
  EXPECT_EQ(b.prior_topics, (Strings{"/drone/camera/position_prior"}));
  ::unlink(site.c_str());
}

// uav_tie_points: the UAV cameras' photos wait for their tie points, the
// site's by kind (and the graph's `uav` without a site).
TEST(SiteCameras, UavTiePointsWaitForTheUavCamerasByKind) {
  const std::string site = WriteSite();
  XmlRpc::XmlRpcValue p = Defaults("bundle_adjuster");
  SetParam(&p, "site_file", site);
  SetParam(&p, "target_list",
           std::string(SM_SOURCE_DIR) + "/test/rostest/service_switches.targets.yaml");
  SetParam(&p, "uav_tie_points", true);
  ParamReader r(p, "/bundle_adjuster");
  EXPECT_EQ(ReadAdjusterParameters(r).collector.tie_point_cameras, (Strings{"drone"}));
  XmlRpc::XmlRpcValue q = Defaults("bundle_adjuster");
  SetParam(&q, "target_list",
           std::string(SM_SOURCE_DIR) + "/test/rostest/service_switches.targets.yaml");
  SetParam(&q, "uav_tie_points", true);
  ParamReader r2(q, "/bundle_adjuster");
  EXPECT_EQ(ReadAdjusterParameters(r2).collector.tie_point_cameras, (Strings{"uav"}));
  ::unlink(site.c_str());
}

// The ConfigError of hex_matcher parameters `p`; "" when they are accepted.
std::string HexMatcherError(const XmlRpc::XmlRpcValue& p) {
  ParamReader r(p, "/uav/hex_matcher");
  try {
    ReadHexMatcherParameters(r);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

// The hex_matcher in mode sequence serves the site's camera of kind uav on
// that camera's topics; a site without one, or a `camera` that is not one of
// several, is refused by name.
TEST(SiteCameras, TheSequenceMatcherTakesTheSitesUavCamera) {
  const std::string site = WriteSite();
  XmlRpc::XmlRpcValue p = Defaults("hex_matcher");
  SetParam(&p, "mode", std::string("sequence"));
  SetParam(&p, "site_file", site);
  ParamReader r(p, "/uav/hex_matcher");
  const HexMatcherParameters h = ReadHexMatcherParameters(r);
  EXPECT_EQ(h.camera, "drone");
  EXPECT_EQ(h.image_topic, "/drone/camera/image_raw");
  EXPECT_EQ(h.prior_topic, "/drone/camera/position_prior");
  EXPECT_EQ(h.tie_topic, "/drone/tie_points");
  // Without a site: the relative topics the launch remaps.
  XmlRpc::XmlRpcValue d = Defaults("hex_matcher");
  SetParam(&d, "mode", std::string("sequence"));
  ParamReader rd(d, "/uav/hex_matcher");
  const HexMatcherParameters plain = ReadHexMatcherParameters(rd);
  EXPECT_EQ(plain.camera, "uav");
  EXPECT_EQ(plain.image_topic, "image");
  EXPECT_EQ(plain.tie_topic, "tie_points");
  // In the graph (graph_cameras, issue 36): without a site, the default
  // cameras' UAV on its topics; with one, still the site's.
  SetParam(&d, "graph_cameras", true);
  ParamReader rg(d, "/hex_matcher");
  const HexMatcherParameters graph = ReadHexMatcherParameters(rg);
  const std::vector<std::string> default_uav =
      io::CameraNames(io::DefaultCameras(), io::CameraKind::kUav);
  ASSERT_EQ(default_uav.size(), 1u);
  EXPECT_EQ(graph.camera, default_uav[0]);
  EXPECT_EQ(graph.image_topic, "/" + default_uav[0] + "/camera/image_raw");
  EXPECT_EQ(graph.prior_topic, "/" + default_uav[0] + "/camera/position_prior");
  EXPECT_EQ(graph.tie_topic, "/" + default_uav[0] + "/tie_points");
  SetParam(&p, "graph_cameras", true);
  ParamReader rgs(p, "/hex_matcher");
  EXPECT_EQ(ReadHexMatcherParameters(rgs).tie_topic, "/drone/tie_points");

  const std::string two = site + ".two.yaml";
  std::ofstream(two) << "name: two_uavs\ncrs: EPSG:4979\norigin: [8.0, 46.5, 1200.0]\ncameras:\n"
                        "  - {name: drone_a, kind: uav, pixel_size: 0.0033}\n"
                        "  - {name: drone_b, kind: uav, pixel_size: 0.0033}\n";
  XmlRpc::XmlRpcValue t = Defaults("hex_matcher");
  SetParam(&t, "mode", std::string("sequence"));
  SetParam(&t, "site_file", two);
  const std::string two_error = HexMatcherError(t);  // two UAV cameras, camera 'uav'
  EXPECT_NE(two_error.find("/uav/hex_matcher/camera"), std::string::npos) << two_error;
  EXPECT_NE(two_error.find("drone_a, drone_b"), std::string::npos) << two_error;
  SetParam(&t, "camera", std::string("drone_b"));
  ParamReader rb(t, "/uav/hex_matcher");
  EXPECT_EQ(ReadHexMatcherParameters(rb).tie_topic, "/drone_b/tie_points");

  const std::string none = site + ".none.yaml";
  std::ofstream(none) << "name: no_uav\ncrs: EPSG:4979\norigin: [8.0, 46.5, 1200.0]\ncameras:\n"
                         "  - {name: mast, kind: fixed, pixel_size: 0.0039}\n";
  XmlRpc::XmlRpcValue n = Defaults("hex_matcher");
  SetParam(&n, "mode", std::string("sequence"));
  SetParam(&n, "site_file", none);
  const std::string none_error = HexMatcherError(n);
  EXPECT_NE(none_error.find("no camera of kind uav"), std::string::npos) << none_error;
  EXPECT_NE(none_error.find(none), std::string::npos) << none_error;
  ::unlink(site.c_str());
  ::unlink(two.c_str());
  ::unlink(none.c_str());
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
