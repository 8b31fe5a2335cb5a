// The site file: the shipped demo reads back as the simulated demo survey;
// coordinates given in a projected site CRS land in `site` where a hand
// subtraction puts them; every mistake names the file and the key.
#include "slope_monitor/core/io/site_file.h"

#include <unistd.h>

#include <fstream>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace io {
namespace {

// UTM zone 32N with the `site` frame as the CRS's own coordinates minus the
// origin: a point's site coordinates are its easting, northing and height
// minus the origin's, checkable by hand.
constexpr char kUtmSite[] = R"(
name: utm_test
crs: EPSG:32632
origin: [500000.0, 5150000.0, 400.0]
frame: shifted_crs
cameras:
  - {name: uav_left, kind: fixed, pixel_size: 0.0039}
  - {name: north_cam, kind: fixed_targetless, calibration_url: "file:///site/north.yaml",
     pose_file: north.pose.yaml, dem: /data/dem.tif}
  - {name: drone, kind: uav, pixel_size: 0.0024}
targets:
  size: 0.5
  list:
    - {id: tag36h11/3, role: control, position: [500010.0, 5150020.0, 405.0], sigma: [0.02, 0.03]}
    - {id: circle/12, role: check, position: [500050.5, 5150075.25, 398.0]}
areas:
  outline: [[500000, 5150000], [500100, 5150000], [500100, 5150100], [500000, 5150100]]
  stable: [[[500000, 5150000], [500020, 5150000], [500020, 5150020]]]
thresholds: {unit: mm/h, alarm: 4}
notification: {hook: hooks/notify, timeout: 5, retries: 1}
)";

TEST(SiteFile, ProjectedCrsShiftedFrameByHand) {
  const SiteFile s = ParseSiteFile(kUtmSite, "utm.yaml", "/sites");
  EXPECT_EQ(s.name, "utm_test");
  ASSERT_EQ(s.cameras.size(), 3u);
  // The kind is the field, whatever the name says.
  EXPECT_EQ(s.cameras[0].kind, CameraKind::kFixed);
  EXPECT_EQ(s.cameras[1].kind, CameraKind::kFixedTargetless);
  EXPECT_EQ(s.cameras[2].kind, CameraKind::kUav);
  EXPECT_DOUBLE_EQ(s.cameras[0].pixel_size, 0.0039);
  EXPECT_EQ(s.cameras[1].calibration_url, "file:///site/north.yaml");
  EXPECT_EQ(s.cameras[1].pose_file, "/sites/north.pose.yaml");  // relative to the site file
  EXPECT_EQ(s.cameras[1].dem, "/data/dem.tif");
  EXPECT_EQ(s.cameras[1].stable_polygons, "");  // the site's areas.stable
  ASSERT_TRUE(s.targets.has_value());
  const TargetSpec* t = s.targets->Find("tag36h11", 3);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->role, TargetRole::kControl);
  EXPECT_DOUBLE_EQ(t->size, 0.5);
  EXPECT_NEAR((*t->position - Eigen::Vector3d(10.0, 20.0, 5.0)).norm(), 0.0, 1e-6);
  EXPECT_NEAR(t->sigma.y(), 0.03, 1e-12);
  const TargetSpec* c = s.targets->Find("circle", 12);
  ASSERT_NE(c, nullptr);
  EXPECT_NEAR((*c->position - Eigen::Vector3d(50.5, 75.25, -2.0)).norm(), 0.0, 1e-6);
  ASSERT_EQ(s.outline.size(), 4u);
  EXPECT_NEAR((s.outline[2] - Eigen::Vector2d(100.0, 100.0)).norm(), 0.0, 1e-6);
  ASSERT_EQ(s.stable_areas.size(), 1u);
  EXPECT_NEAR((s.stable_areas[0][1] - Eigen::Vector2d(20.0, 0.0)).norm(), 0.0, 1e-6);
  EXPECT_EQ(s.thresholds.unit, "mm/h");
  EXPECT_FALSE(s.thresholds.watch.has_value());
  EXPECT_DOUBLE_EQ(*s.thresholds.alarm, 4.0);
  EXPECT_EQ(s.notification.hook, "/sites/hooks/notify");  // relative to the site file's folder
  EXPECT_DOUBLE_EQ(s.notification.timeout, 5.0);
  EXPECT_EQ(s.notification.retries, 1);
  EXPECT_DOUBLE_EQ(s.notification.retry_delay, NotificationOptions().retry_delay);
  EXPECT_TRUE(s.radio_network.empty());  // radio is optional
}

// The shipped demo site matches config/sim/demo_site.yaml: origin 46.5 N 8 E
// 1200 m, cameras fixed_cam_1, fixed_cam_2 (fixed) and uav (uav), 4.8 um pixels.
TEST(SiteFile, ShippedDemoSite) {
  const SiteFile s = LoadSiteFile(std::string(SM_SOURCE_DIR) + "/config/sites/demo.yaml");
  EXPECT_EQ(s.name, "demo");
  EXPECT_EQ(s.crs.crs, "EPSG:4979");
  EXPECT_EQ(s.crs.origin, Eigen::Vector3d(8.0, 46.5, 1200.0));
  ASSERT_EQ(s.cameras.size(), 3u);
  EXPECT_EQ(s.FindCamera("fixed_cam_2")->kind, CameraKind::kFixed);
  EXPECT_EQ(s.FindCamera("uav")->kind, CameraKind::kUav);
  for (const SiteCamera& c : s.cameras) EXPECT_DOUBLE_EQ(c.pixel_size, 0.0048) << c.name;
  EXPECT_FALSE(s.targets.has_value());
  EXPECT_EQ(s.outline.size(), 4u);
  EXPECT_EQ(s.stable_areas.size(), 2u);
  EXPECT_EQ(s.aliases.size(), 3u);
  EXPECT_TRUE(s.notification.hook.empty());
  const SiteCrs crs(s.crs);
  const Eigen::Vector3d o = crs.origin_wgs84();
  EXPECT_NEAR(o.x(), 8.0, 1e-12);
  EXPECT_NEAR(o.y(), 46.5, 1e-12);
}

TEST(SiteFile, TargetCsvBesideTheSiteFile) {
  char tmpl[] = "/tmp/site_file_test_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  std::ofstream(dir + "/points.csv") << "# crs: site\nid,role,x,y,z,sigma_h,sigma_v\n"
                                     << "tag36h11/0,control,1.5,2.5,3.5,0.01,0.02\n";
  std::ofstream(dir + "/site.yaml") << "name: csv\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\n"
                                    << "targets: {file: points.csv, size: 2.0}\n";
  const SiteFile s = LoadSiteFile(dir + "/site.yaml");
  EXPECT_EQ(s.targets_file, dir + "/points.csv");
  ASSERT_TRUE(s.targets.has_value());
  ASSERT_EQ(s.targets->targets().size(), 1u);
  EXPECT_EQ(*s.targets->targets()[0].position, Eigen::Vector3d(1.5, 2.5, 3.5));
  EXPECT_DOUBLE_EQ(s.targets->targets()[0].size, 2.0);
  std::system(("rm -rf '" + dir + "'").c_str());
}

// A crew's ODM gcp_list.txt as the site's targets: family gcp, the ID the
// point's name ends in, roles from `check`, sigma from `sigma` (vertical
// 10 m when every height is 0), UTM turned into the shifted site frame by
// hand subtraction; mistakes name the file.
TEST(SiteFile, GcpListAsTargets) {
  char tmpl[] = "/tmp/site_file_test_XXXXXX";
  const std::string dir = mkdtemp(tmpl);
  std::ofstream(dir + "/gcp_list.txt") << "WGS84 UTM 32N\n"
                                       << "500010.0 5150020.0 0.0 100.5 200.5 IMG_1.JPG gcp07\n"
                                       << "500010.0 5150020.0 0.0 300.0 210.0 IMG_2.JPG gcp07\n"
                                       << "500030.0 5150005.0 0.0 50.0 60.0 IMG_2.JPG gcp2\n";
  const std::string head =
      "name: gcp\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\nframe: shifted_crs\n";
  std::ofstream(dir + "/site.yaml")
      << head << "targets: {file: gcp_list.txt, check: [gcp2], sigma: 0.5}\n";
  const SiteFile s = LoadSiteFile(dir + "/site.yaml");
  ASSERT_TRUE(s.targets.has_value());
  EXPECT_TRUE(s.targets->OnlyPicked());
  EXPECT_TRUE(SiteWithoutDetectableTargets(s, ""));
  const TargetSpec* g7 = s.targets->Find("gcp", 7);
  const TargetSpec* g2 = s.targets->Find("gcp", 2);
  ASSERT_TRUE(g7 && g2);
  EXPECT_EQ(g7->role, TargetRole::kControl);
  EXPECT_EQ(g2->role, TargetRole::kCheck);
  EXPECT_EQ(g7->Label(), "gcp07");  // the crew's name in messages, the key inside
  EXPECT_EQ(g7->Key(), "gcp/7");
  EXPECT_NEAR((*g7->position - Eigen::Vector3d(10.0, 20.0, 0.0)).norm(), 0.0, 1e-6);
  EXPECT_NEAR((*g2->position - Eigen::Vector3d(30.0, 5.0, 0.0)).norm(), 0.0, 1e-6);
  EXPECT_EQ(g7->sigma, Eigen::Vector2d(0.5, kNoHeightSigma));
  // Without `sigma`: the gcp list's default, vertical twice when heights are given.
  std::ofstream(dir + "/with_heights.txt") << "EPSG:32632\n500010 5150020 12.5 1 1 a.jpg p\n";
  std::ofstream(dir + "/site2.yaml") << head << "targets: {file: with_heights.txt}\n";
  const SiteFile h = LoadSiteFile(dir + "/site2.yaml");
  ASSERT_EQ(h.targets->targets().size(), 1u);
  EXPECT_EQ(h.targets->targets()[0].Key(), "gcp/0");  // no number in the name: its place
  EXPECT_EQ(h.targets->targets()[0].Label(), "p");
  EXPECT_EQ(h.targets->targets()[0].sigma,
            Eigen::Vector2d(kDefaultGcpSigma, 2.0 * kDefaultGcpSigma));
  EXPECT_NEAR(h.targets->targets()[0].position->z(), 12.5, 1e-9);
  // A check point the list does not have, and a gcp list that is not there.
  std::ofstream(dir + "/site3.yaml") << head << "targets: {file: gcp_list.txt, check: [gcp9]}\n";
  try {
    LoadSiteFile(dir + "/site3.yaml");
    ADD_FAILURE() << "a check point not in the list was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("gcp_list.txt: check point 'gcp9' is not in the list"),
              std::string::npos)
        << e.what();
  }
  std::ofstream(dir + "/site4.yaml") << head << "targets: {file: missing.txt}\n";
  try {
    LoadSiteFile(dir + "/site4.yaml");
    ADD_FAILURE() << "a missing gcp list was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.txt"), std::string::npos) << e.what();
  }
  std::system(("rm -rf '" + dir + "'").c_str());
}

// A UAV camera's photos carry their pixel pitch in EXIF (the capture reads
// FocalPlaneXResolution): its entry needs no pixel_size; a fixed camera's does.
TEST(SiteFile, UavCameraWithoutPixelSizeReadsItFromThePhotos) {
  const SiteFile s = ParseSiteFile(
      "name: x\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\n"
      "cameras: [{name: drone, kind: uav}, {name: toe, kind: fixed, pixel_size: 0.004}]\n",
      "uav.yaml", "/sites");
  ASSERT_EQ(s.cameras.size(), 2u);
  EXPECT_EQ(s.FindCamera("drone")->kind, CameraKind::kUav);
  EXPECT_EQ(s.FindCamera("drone")->pixel_size, 0.0);
  EXPECT_DOUBLE_EQ(s.FindCamera("toe")->pixel_size, 0.004);
}

std::string SiteFileErrorOf(const std::string& text) {
  try {
    ParseSiteFile(text, "bad.yaml", "/sites");
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(SiteFile, MistakesNameTheFileAndTheKey) {
  const std::string head = "name: x\ncrs: EPSG:32632\norigin: [500000, 5150000, 0]\n";
  auto expect = [&](const std::string& body, const std::vector<std::string>& parts) {
    const std::string e = SiteFileErrorOf(head + body);
    EXPECT_NE(e.find("bad.yaml"), std::string::npos) << e;
    for (const std::string& p : parts)
      EXPECT_NE(e.find(p), std::string::npos) << "'" << p << "' not in: " << e;
  };
  expect("cameras: [{name: c1, kind: drone, pixel_size: 0.004}]", {"cameras[0]", "kind", "drone"});
  expect("cameras: [{name: c1, kind: fixed}]", {"cameras[0]", "pixel_size"});
  expect(
      "cameras: [{name: c1, kind: fixed, pixel_size: 0.004}, {name: c1, kind: uav, pixel_size: "
      "0.004}]",
      {"cameras[1]", "c1", "twice"});
  expect("cameras: [{name: c1, kind: fixed_targetless, pixel_size: 0.004, dem: d.tif}]",
         {"cameras[0]", "pose_file"});
  expect("cameras: [{name: c1, kind: fixed, pixel_size: 0.004, dem: d.tif}]",
         {"cameras[0]", "dem", "fixed_targetless cameras only"});
  expect("thresholds: {alarn: 3}", {"alarn"});
  expect("thresholds: {watch: 20, warning: 10}", {"watch", "below warning"});
  expect("radio_network: nowhere.yaml", {"radio_network", "/sites/nowhere.yaml"});
  expect("areas: {outline: [[0, 0], [1, 1]]}", {"outline", "at least 3"});
  expect("targets: {list: [{id: tag36h11/x, position: [0, 0, 0]}]}", {"id", "tag36h11/x"});
  expect("notification: {hook: h, retries: 99}", {"retries"});
  expect("colour: red", {"colour"});
  EXPECT_NE(SiteFileErrorOf("name: x\ncrs: EPSG:999999\norigin: [0, 0, 0]\n").find("crs"),
            std::string::npos);
  EXPECT_NE(SiteFileErrorOf("name: x\ncrs: EPSG:32632\n").find("origin"), std::string::npos);
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
