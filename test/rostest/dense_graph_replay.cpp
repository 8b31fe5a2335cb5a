// Plays the dense_graph_replay survey through the whole graph and checks the
// dense_matcher's per-epoch cloud and GeoTIFFs (dense_graph_replay.test.in),
// and the orthophoto, cloud file and report of each epoch (issue 35 item 4).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <boost/function.hpp>

#include "slope_monitor/AdjustmentSolution.h"
#include "test_node.h"

namespace {

std::mutex mutex;
std::set<double> solutions;                                 // stamps of usable solutions
std::map<double, sensor_msgs::PointCloud2ConstPtr> clouds;  // by header stamp

TEST(DenseGraphReplay, ACloudPerEpochAndTheGeoTiffs) {
  ros::NodeHandle nh, pnh("~");
  const int epochs = static_cast<int>(slope_monitor::rostest_node::Param(pnh, "epochs", 2));
  const double timeout = slope_monitor::rostest_node::Param(pnh, "timeout", 500);
  const size_t min_points =
      static_cast<size_t>(slope_monitor::rostest_node::Param(pnh, "min_points", 10000));
  std::string report_dir;
  pnh.getParam("report_dir", report_dir);
  ros::Subscriber s1 = nh.subscribe<slope_monitor::AdjustmentSolution>(
      "/bundle_adjuster/solution", 10,
      boost::function<void(const slope_monitor::AdjustmentSolutionConstPtr&)>([](const auto& m) {
        std::lock_guard<std::mutex> lock(mutex);
        if (m->usable) solutions.insert(m->header.stamp.toSec());
      }));
  ros::Subscriber s2 = nh.subscribe<sensor_msgs::PointCloud2>(
      "/dense/surface_cloud", 10,
      boost::function<void(const sensor_msgs::PointCloud2ConstPtr&)>([](const auto& m) {
        std::lock_guard<std::mutex> lock(mutex);
        clouds[m->header.stamp.toSec()] = m;
      }));
  const bool done = slope_monitor::rostest_node::WaitFor(
      [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return static_cast<int>(clouds.size()) >= epochs;
      },
      timeout);
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_TRUE(done) << clouds.size() << " clouds for " << solutions.size()
                    << " usable solutions after " << timeout << " s";
  EXPECT_EQ(static_cast<int>(solutions.size()), epochs);
  int with_change = 0;
  for (const auto& [stamp, c] : clouds) {
    EXPECT_EQ(solutions.count(stamp), 1u) << "cloud at " << stamp << " without a solution";
    EXPECT_EQ(c->header.frame_id, "site");
    std::vector<std::string> names;
    for (const auto& f : c->fields) names.push_back(f.name);
    EXPECT_EQ(names, (std::vector<std::string>{"x", "y", "z", "rgb", "sigma_z", "change", "lod"}));
    const size_t n = static_cast<size_t>(c->width) * c->height;
    std::printf("cloud at %.1f: %zu points\n", stamp, n);
    EXPECT_GE(n, min_points);
    size_t finite_change = 0;
    for (sensor_msgs::PointCloud2ConstIterator<float> ch(*c, "change"); ch != ch.end(); ++ch)
      finite_change += std::isfinite(*ch);
    // A later epoch has a change wherever the reference surface exists (the
    // reference DEM covers about half of the later flights' cells); the
    // reference epoch has none.
    std::printf("  %zu points with a change\n", finite_change);
    with_change += finite_change > n / 4;
  }
  EXPECT_EQ(with_change, epochs - 1);  // every epoch but the reference
  int surfaces = 0, changes = 0, orthos = 0, clouds_written = 0, reports = 0;
  for (const auto& f : std::filesystem::directory_iterator(report_dir)) {
    const std::string name = f.path().filename().string();
    surfaces += name.rfind("surface_e", 0) == 0 && f.path().extension() == ".tif";
    changes += name.rfind("change_e", 0) == 0 && f.path().extension() == ".tif";
    // Issue 35 item 4: what process_flight writes per flight, per epoch.
    orthos += name.rfind("ortho_e", 0) == 0 && f.path().extension() == ".tif";
    clouds_written += name.rfind("cloud_e", 0) == 0 && f.path().extension() == ".ply";
    reports += name.rfind("surface_report_e", 0) == 0 && f.path().extension() == ".json";
    // Issue 38: in the map CRS of the launch's site_config (geodetic_origin
    // 46.5 N, 8.0 E: UTM zone 32), as GDAL's own tool reads it.
    if (f.path().extension() != ".tif" || name.rfind("deformation", 0) == 0) continue;
    std::string srs;
    if (FILE* p = popen(("gdalsrsinfo -o epsg '" + f.path().string() + "' 2>&1").c_str(), "r")) {
      char buf[256];
      while (fgets(buf, sizeof buf, p)) srs += buf;
      pclose(p);
    }
    EXPECT_NE(srs.find("EPSG:32632"), std::string::npos) << f.path() << ": " << srs;
  }
  EXPECT_EQ(surfaces, epochs);
  EXPECT_EQ(changes, epochs - 1);
  EXPECT_EQ(orthos, epochs);  // each in EPSG:32632 (above)
  EXPECT_EQ(clouds_written, epochs);
  EXPECT_EQ(reports, epochs);
}

}  // namespace

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "dense_graph_replay_test");
}
