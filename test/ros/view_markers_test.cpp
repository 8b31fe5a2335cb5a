// ros/view_markers.h: the camera frustums against a hand-checked pyramid
// (and the core camera model: the drawn corners project onto the image's
// corner pixels), the colour scale against rviz's rainbow at hand-checkable
// values, and the one place of the scale's limits: the defaults file, the
// options and rviz/slope_monitor.rviz's cloud display agree.
#include <string>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/param_files.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

using visualization_msgs::Marker;

// A nadir camera at (10, 20, 30): optical z down, x east, y south (a half
// turn about site x). Sensor 1000 x 800 px of 0.01 mm = 10 x 8 mm, c = 10 mm.
constexpr double kPixel = 0.01, kC = 10.0, kDepth = 5.0;
const camera::Sensor kSensor{1000, 800, kPixel};

slope_monitor::AdjustmentSolution NadirSolution(double x0, double y0) {
  slope_monitor::AdjustmentSolution s;
  s.header.frame_id = "site";
  s.header.stamp.fromSec(1700000000.0);
  slope_monitor::CameraEstimate e;
  e.camera_name = "uav";
  e.site_from_optical.position.x = 10.0;
  e.site_from_optical.position.y = 20.0;
  e.site_from_optical.position.z = 30.0;
  e.site_from_optical.orientation.x = 1.0;  // w = 0: half turn about x
  e.principal_distance = kC;
  e.x0 = x0;
  e.y0 = y0;
  s.cameras.push_back(e);
  return s;
}

camera::CameraModel Model(double x0, double y0) {
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = kC;
  interior[camera::kX0] = x0;
  interior[camera::kY0] = y0;
  return camera::CameraModel(kSensor, camera::DistortionModel::kNone, interior);
}

Eigen::Vector3d ToEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

TEST(FrustumMarkers, PyramidFromTheProjectionCentreToTheImageCorners) {
  const std::map<std::string, camera::CameraModel> models = {{"uav", Model(0.0, 0.0)}};
  FrustumOptions o;
  o.depth = kDepth;
  const visualization_msgs::MarkerArray a = ToFrustumMarkers(NadirSolution(0, 0), models, o);
  ASSERT_EQ(a.markers.size(), 2u);
  EXPECT_EQ(a.markers[0].action, Marker::DELETEALL);
  const Marker& m = a.markers[1];
  EXPECT_EQ(m.type, Marker::LINE_LIST);
  EXPECT_EQ(m.header.frame_id, "site");
  EXPECT_EQ(m.ns, "frustums");
  EXPECT_DOUBLE_EQ(m.scale.x, o.line_width);
  ASSERT_EQ(m.points.size(), 16u);  // 4 edges from the apex, 4 sides
  // Half sizes at 5 m: 5 m * 5 mm / 10 mm = 2.5 m across, 5 * 4 / 10 = 2 m along.
  // Image top-left (x = -5 mm, y = +4 mm) -> optical (-2.5, -2, 5) -> site
  // (10 - 2.5, 20 + 2, 30 - 5); clockwise in the image from there.
  const std::vector<Eigen::Vector3d> corners = {
      {7.5, 22.0, 25.0}, {12.5, 22.0, 25.0}, {12.5, 18.0, 25.0}, {7.5, 18.0, 25.0}};
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_TRUE(ToEigen(m.points[4 * k]).isApprox(Eigen::Vector3d(10, 20, 30), 1e-12)) << k;
    EXPECT_TRUE(ToEigen(m.points[4 * k + 1]).isApprox(corners[k], 1e-12)) << k;
    EXPECT_TRUE(ToEigen(m.points[4 * k + 2]).isApprox(corners[k], 1e-12)) << k;
    EXPECT_TRUE(ToEigen(m.points[4 * k + 3]).isApprox(corners[(k + 1) % 4], 1e-12)) << k;
  }
}

// The colour follows the camera kind (site file), not the name: a UAV named
// "drone" is orange, a fixed camera named "uav_mast" green.
TEST(FrustumMarkers, UavColourByTheSitesKind) {
  slope_monitor::AdjustmentSolution s = NadirSolution(0, 0);
  s.cameras.push_back(s.cameras[0]);
  s.cameras[0].camera_name = "drone";
  s.cameras[1].camera_name = "uav_mast";
  const std::map<std::string, camera::CameraModel> models = {{"drone", Model(0.0, 0.0)},
                                                             {"uav_mast", Model(0.0, 0.0)}};
  FrustumOptions o;
  o.uav_cameras = {"drone"};
  const visualization_msgs::MarkerArray a = ToFrustumMarkers(s, models, o);
  ASSERT_EQ(a.markers.size(), 3u);
  EXPECT_FLOAT_EQ(a.markers[1].color.r, 1.0f);  // orange
  EXPECT_FLOAT_EQ(a.markers[1].color.g, 0.55f);
  EXPECT_FLOAT_EQ(a.markers[2].color.g, 1.0f);  // green
  EXPECT_FLOAT_EQ(a.markers[2].color.r, 0.2f);
}

TEST(FrustumMarkers, CornersProjectOntoTheCornerPixelsWithAShiftedPrincipalPoint) {
  const double x0 = 1.0, y0 = -0.5;  // [mm]
  const std::map<std::string, camera::CameraModel> models = {{"uav", Model(x0, y0)}};
  FrustumOptions o;
  o.depth = kDepth;
  const slope_monitor::AdjustmentSolution s = NadirSolution(x0, y0);
  const Marker m = ToFrustumMarkers(s, models, o).markers.at(1);
  // Left edge: x - x0 = -6 mm -> -3 m; right: 4 mm -> 2 m (east of 10).
  EXPECT_NEAR(m.points[1].x, 7.0, 1e-12);
  EXPECT_NEAR(m.points[5].x, 12.0, 1e-12);
  // Top: y - y0 = 4.5 mm -> 2.25 m north of 20.
  EXPECT_NEAR(m.points[1].y, 22.25, 1e-12);
  const camera::ExteriorOrientation pose = camera::ExteriorOrientation::FromOpticalFromSite(
      FromPose(s.cameras[0].site_from_optical).Inverse());
  const std::vector<Eigen::Vector2d> pixel_corners = {
      {-0.5, -0.5}, {999.5, -0.5}, {999.5, 799.5}, {-0.5, 799.5}};
  for (size_t k = 0; k < 4; ++k) {
    Eigen::Vector2d pixel;
    ASSERT_TRUE(models.at("uav").Project(pose, ToEigen(m.points[4 * k + 1]), &pixel));
    EXPECT_NEAR(pixel.x(), pixel_corners[k].x(), 1e-9) << k;
    EXPECT_NEAR(pixel.y(), pixel_corners[k].y(), 1e-9) << k;
  }
}

TEST(FrustumMarkers, ACameraWithoutAModelIsLeftOut) {
  const visualization_msgs::MarkerArray a = ToFrustumMarkers(NadirSolution(0, 0), {}, {});
  ASSERT_EQ(a.markers.size(), 1u);
  EXPECT_EQ(a.markers[0].action, Marker::DELETEALL);
}

TEST(ChangeScale, RvizRainbowAtTheSegmentEnds) {
  const auto expect = [](double t, float r, float g, float b) {
    const std_msgs::ColorRGBA c = RvizRainbow(t);
    EXPECT_FLOAT_EQ(c.r, r) << t;
    EXPECT_FLOAT_EQ(c.g, g) << t;
    EXPECT_FLOAT_EQ(c.b, b) << t;
  };
  expect(-3.0, 1, 0, 1);  // clamped
  expect(0.0, 1, 0, 1);   // magenta
  expect(0.2, 0, 0, 1);   // blue
  expect(0.4, 0, 1, 1);   // cyan
  expect(0.5, 0, 1, 0.5);
  expect(0.6, 0, 1, 0);  // green
  expect(0.8, 1, 1, 0);  // yellow
  expect(1.0, 1, 0, 0);  // red
}

TEST(ChangeScale, BarOfCubesWithLabelsFromMinToMax) {
  std_msgs::Header h;
  h.frame_id = "site";
  const ChangeScaleOptions o;  // -1 .. +1 m, 10 cubes, 5 labels
  const visualization_msgs::MarkerArray a =
      ToChangeScaleMarkers(o, Eigen::Vector3d(200, 75, 10), 50.0, h);
  ASSERT_EQ(a.markers.size(), 1u + 10u + 5u + 1u);
  EXPECT_EQ(a.markers[0].action, Marker::DELETEALL);
  for (int k = 0; k < 10; ++k) {
    const Marker& cube = a.markers[1 + k];
    EXPECT_EQ(cube.type, Marker::CUBE);
    EXPECT_DOUBLE_EQ(cube.scale.z, 5.0);
    EXPECT_DOUBLE_EQ(cube.pose.position.z, 10.0 + 5.0 * k + 2.5);
  }
  // The lowest cube is the colour of -0.9 m (t = 0.05), the top one +0.9 m.
  EXPECT_EQ(a.markers[1].color, RvizRainbow(0.05));
  EXPECT_EQ(a.markers[10].color, RvizRainbow(0.95));
  const std::vector<std::string> labels = {"-1.0 m", "-0.5 m", "0.0 m", "+0.5 m", "+1.0 m"};
  for (int k = 0; k < 5; ++k) {
    const Marker& t = a.markers[11 + k];
    EXPECT_EQ(t.type, Marker::TEXT_VIEW_FACING);
    EXPECT_EQ(t.text, labels[k]);
    EXPECT_DOUBLE_EQ(t.pose.position.z, 10.0 + 12.5 * k);
    EXPECT_GT(t.pose.position.x, 200.0);  // beside the bar
  }
  EXPECT_EQ(a.markers.back().text, "change [m]");
}

TEST(ChangeScale, BadLimitsAreNamed) {
  XmlRpc::XmlRpcValue p =
      LoadParamFile(std::string(SM_SOURCE_DIR) + "/config/defaults/dense_epoch.yaml");
  SetParam(&p, "change_colour_min", 2.0);
  ParamReader r(p, "/dense/dense_matcher");
  try {
    ReadDenseEpochParameters(r);
    FAIL() << "min above max accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/dense/dense_matcher/change_colour_min"),
              std::string::npos)
        << e.what();
  }
}

// One place for the limits: the file documents the options' defaults, and
// the shipped rviz layout colours the cloud's `change` with the same numbers.
TEST(ChangeScale, DefaultsFileOptionsAndRvizLayoutAgree) {
  XmlRpc::XmlRpcValue p =
      LoadParamFile(std::string(SM_SOURCE_DIR) + "/config/defaults/dense_epoch.yaml");
  ParamReader r(p, "/dense/dense_matcher");
  const ChangeScaleOptions read = ReadDenseEpochParameters(r).change_scale, d;
  EXPECT_EQ(read.min, d.min);
  EXPECT_EQ(read.max, d.max);
  const YAML::Node rviz = YAML::LoadFile(std::string(SM_SOURCE_DIR) + "/rviz/slope_monitor.rviz");
  int clouds = 0;
  for (const YAML::Node& display : rviz["Visualization Manager"]["Displays"]) {
    if (!display["Topic"] || display["Topic"].as<std::string>() != "/dense/surface_cloud") continue;
    ++clouds;
    EXPECT_EQ(display["Channel Name"].as<std::string>(), "change");
    EXPECT_EQ(display["Color Transformer"].as<std::string>(), "Intensity");
    EXPECT_FALSE(display["Autocompute Intensity Bounds"].as<bool>());
    EXPECT_TRUE(display["Use rainbow"].as<bool>());
    EXPECT_TRUE(display["Invert Rainbow"].as<bool>());  // what RvizRainbow reproduces
    EXPECT_DOUBLE_EQ(display["Min Intensity"].as<double>(), d.min);
    EXPECT_DOUBLE_EQ(display["Max Intensity"].as<double>(), d.max);
  }
  EXPECT_EQ(clouds, 1);
}

// The dense step's LoD model (issue 35): the defaults file keeps the graph's
// global residual; lod_model slope_roughness with lod_bin_spread quantile is
// process_flight's (flight::FlightChangeOptions); a bad value is named.
TEST(DenseEpochParameters, LodModelSelectsProcessFlightsErrorModel) {
  const std::string path = std::string(SM_SOURCE_DIR) + "/config/defaults/dense_epoch.yaml";
  XmlRpc::XmlRpcValue p = LoadParamFile(path);
  {
    ParamReader r(p, "/dense/dense_matcher");
    const dense::SurfaceChangeOptions o = ReadDenseEpochParameters(r).change;
    EXPECT_FALSE(o.change.error_model.enabled);
    EXPECT_EQ(o.search_radius, 4.0);
  }
  SetParam(&p, "lod_model", std::string("slope_roughness"));
  SetParam(&p, "lod_bin_spread", std::string("quantile"));
  {
    ParamReader r(p, "/dense/dense_matcher");
    const dense::ErrorModelOptions e = ReadDenseEpochParameters(r).change.change.error_model;
    EXPECT_TRUE(e.enabled);
    EXPECT_EQ(e.spread, dense::ErrorModelOptions::Spread::kQuantile);
  }
  SetParam(&p, "lod_model", std::string("bins"));
  ParamReader r(p, "/dense/dense_matcher");
  try {
    ReadDenseEpochParameters(r);
    FAIL() << "lod_model 'bins' accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/dense/dense_matcher/lod_model"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
