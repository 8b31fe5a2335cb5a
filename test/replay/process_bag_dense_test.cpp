// process_bag's dense epoch step on a survey with a UAV flight (the demo site
// with its UAV strip, two epochs: test/replay/dense_graph_replay.sim.yaml,
// rendered at build time): a cloud of the expected size and fields in `site`
// for every adjusted epoch in --output-bag, a change on the later epoch,
// surface_eNN.tif and change_eNN.tif in --report-dir, every oriented photo
// used, and the DEMs against the simulator's true surfaces on bare ground.
// The rviz outputs: the colour scale of `change` beside every cloud, the
// camera frustums of every usable solution (apex at each camera's adjusted
// projection centre) and the UAV centroider's debug image of the last photo.
// Issue 35 item 4: per epoch also ortho_eNN.tif (EPSG:32632, warped to WGS
// 84), cloud_eNN.ply and surface_report_eNN.json (co-registration, volumes),
// as process_flight writes per flight. --no-dense turns the step off.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <visualization_msgs/MarkerArray.h>
#include <nlohmann/json.hpp>

#include "replay_test_util.h"
#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;

const std::string kSurvey = "dense_graph_replay";

std::string Survey(const std::string& ext) {
  return std::string(SM_ROSTEST_DATA_DIR) + "/" + kSurvey + "/" + kSurvey + ext;
}

std::string ReadFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

fs::path Scratch(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("process_bag_dense_test_" + std::to_string(getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// process_bag on the survey with `extra` flags; outputs in `dir`.
int RunProcessBag(const fs::path& dir, const std::string& extra) {
  const std::string cmd =
      std::string(SM_PROCESS_BAG) + " --bag " + Survey(".bag") + " --site-config " +
      Survey(".site.yaml") + " --database " + (dir / "history.db").string() + " --report-dir " +
      (dir / "reports").string() + " --output-bag " + (dir / "out.bag").string() + " " + extra +
      " > " + (dir / "stdout").string() + " 2> " + (dir / "stderr").string();
  const int status = std::system(cmd.c_str());
  if (status != 0) std::cerr << ReadFile(dir / "stderr");
  return status;
}

// A GDAL command line tool on `args` (outputs in `dir`/`name`): its exit
// status and what it printed.
std::pair<int, std::string> Gdal(const std::string& args, const fs::path& dir,
                                 const std::string& name) {
  const fs::path out = dir / name;
  const int status = std::system((args + " > " + out.string() + " 2>&1").c_str());
  return {status, ReadFile(out)};
}

struct Outputs {
  std::map<double, int> solutions;                                       // usable: stamp -> epoch
  std::map<double, slope_monitor::AdjustmentSolution::ConstPtr> usable;  // stamp -> solution
  std::map<double, sensor_msgs::PointCloud2::ConstPtr> clouds;
  std::map<double, visualization_msgs::MarkerArray::ConstPtr> legends, frustums;
  std::vector<sensor_msgs::Image::ConstPtr> uav_debug_images;
};

Outputs ReadOutputs(const fs::path& bag_path) {
  Outputs out;
  rosbag::Bag bag(bag_path.string(), rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (const auto s = m.instantiate<slope_monitor::AdjustmentSolution>())
      if (s->usable) {
        out.solutions[s->header.stamp.toSec()] = static_cast<int>(s->epoch);
        out.usable[s->header.stamp.toSec()] = s;
      }
    if (const auto a = m.instantiate<visualization_msgs::MarkerArray>(); a && !a->markers.empty()) {
      if (m.getTopic() == "/dense/change_legend")
        out.legends[a->markers.back().header.stamp.toSec()] = a;
      if (m.getTopic() == "/bundle_adjuster/frustums")
        out.frustums[a->markers.front().header.stamp.toSec()] = a;
    }
    if (m.getTopic() == "/uav/debug_image")
      if (const auto i = m.instantiate<sensor_msgs::Image>()) out.uav_debug_images.push_back(i);
    if (m.getTopic() == "/dense/surface_cloud")
      if (const auto c = m.instantiate<sensor_msgs::PointCloud2>())
        out.clouds[c->header.stamp.toSec()] = c;
  }
  return out;
}

// |height error| of the DEM's cells on bare ground (not unmatchable in the
// truth) against the true surface, sorted.
std::vector<double> BareGroundErrors(const io::GeoRaster& dem, const io::GeoRaster& truth_dem,
                                     const sim::SurveyTruth& truth) {
  std::vector<double> e;
  for (int r = 0; r < dem.height; ++r)
    for (int c = 0; c < dem.width; ++c) {
      const float z = dem.At(dense::kHeight, r, c);
      if (dem.IsNoData(z)) continue;
      const Eigen::Vector2d xy = dem.CellCentre(r, c);
      const double zt = truth_dem.Interpolate(0, xy.x(), xy.y());
      if (std::isnan(zt) || truth.Unmatchable(Eigen::Vector3d(xy.x(), xy.y(), zt))) continue;
      e.push_back(std::abs(z - zt));
    }
  std::sort(e.begin(), e.end());
  return e;
}

double Quantile(const std::vector<double>& sorted, double q) {
  return sorted.empty() ? NAN : sorted[static_cast<size_t>(q * (sorted.size() - 1))];
}

// The markers rviz/slope_monitor.rviz shows beside the clouds.
void ExpectViewMarkers(const Outputs& out) {
  ASSERT_EQ(out.legends.size(), out.clouds.size());
  for (const auto& [stamp, legend] : out.legends) {
    EXPECT_EQ(out.clouds.count(stamp), 1u) << "legend at " << stamp << " without a cloud";
    std::vector<std::string> labels;
    int cubes = 0;
    for (const visualization_msgs::Marker& m : legend->markers) {
      cubes += m.type == visualization_msgs::Marker::CUBE;
      if (m.type == visualization_msgs::Marker::TEXT_VIEW_FACING) labels.push_back(m.text);
      if (m.action == visualization_msgs::Marker::ADD) {
        EXPECT_EQ(m.header.frame_id, "site");
      }
    }
    EXPECT_EQ(cubes, 10);  // config/defaults/dense_epoch.yaml: -1 .. +1 m
    EXPECT_EQ(labels, (std::vector<std::string>{"-1.0 m", "-0.5 m", "0.0 m", "+0.5 m", "+1.0 m",
                                                "change [m]"}));
  }
  ASSERT_EQ(out.frustums.size(), out.usable.size());
  for (const auto& [stamp, solution] : out.usable) {
    ASSERT_EQ(out.frustums.count(stamp), 1u) << "no frustums for the solution at " << stamp;
    const auto& markers = out.frustums.at(stamp)->markers;
    ASSERT_EQ(markers.size(), solution->cameras.size() + 1);  // DELETEALL, one per camera
    EXPECT_EQ(markers.front().action, visualization_msgs::Marker::DELETEALL);
    for (size_t i = 1; i < markers.size(); ++i) {
      const auto& apex = markers[i].points.at(0);
      const auto& centre = solution->cameras[markers[i].id].site_from_optical.position;
      EXPECT_NEAR(apex.x, centre.x, 1e-9);
      EXPECT_NEAR(apex.y, centre.y, 1e-9);
      EXPECT_NEAR(apex.z, centre.z, 1e-9);
      EXPECT_EQ(markers[i].points.size(), 16u);
    }
  }
  ASSERT_EQ(out.uav_debug_images.size(), 1u);  // the last photo's
  EXPECT_EQ(out.uav_debug_images[0]->encoding, "bgr8");
  EXPECT_EQ(out.uav_debug_images[0]->width, 1280u);
}

// Issue 35 item 4: what process_flight writes per flight, the graph's dense
// step writes per UAV epoch (dense::SurfaceSeries): the orthophoto on the
// DEM (RGB bands; the simulator's UAV photos are mono8, so red = green =
// blue), the cloud as PLY (the points of the PointCloud2), and
// surface_report_eNN.json with, for a later epoch, the co-registration on
// stable ground and the volumes. Truth for the co-registration: both epochs
// are tied by the same control points (3 cm survey noise), so no datum
// difference: the whole-cell search finds none and the shift is within 3
// sigma of 0.
void ExpectProcessFlightProducts(const fs::path& reports, int epoch, bool later,
                                 const io::GeoRaster& dem_in_map,
                                 const sensor_msgs::PointCloud2::ConstPtr& cloud) {
  const io::GeoRaster ortho =
      io::ReadGeoTiff((reports / dense::EpochOrthoFileName(epoch)).string());
  EXPECT_EQ(ortho.epsg, 32632);
  ASSERT_EQ(ortho.band_names, (std::vector<std::string>{"red", "green", "blue"}));
  EXPECT_NEAR(ortho.cell_size, dem_in_map.cell_size / 4, 1e-9);  // 4 x 4 cells per DEM cell
  size_t valid = 0, grey = 0;
  for (size_t i = 0; i < ortho.bands[0].size(); ++i) {
    if (ortho.IsNoData(ortho.bands[0][i])) continue;
    ++valid;
    grey += ortho.bands[0][i] == ortho.bands[1][i] && ortho.bands[1][i] == ortho.bands[2][i];
  }
  size_t dem_filled = 0;
  for (float z : dem_in_map.bands[dense::kHeight]) dem_filled += !dem_in_map.IsNoData(z);
  std::printf("epoch %d orthophoto: %d x %d cells of %.3f m, %zu with a colour (DEM: %zu of %zu)\n",
              epoch, ortho.width, ortho.height, ortho.cell_size, valid, dem_filled,
              dem_in_map.bands[0].size());
  EXPECT_EQ(grey, valid);
  // Where the DEM has a height the orthophoto has a colour (16 cells each).
  EXPECT_GE(valid, 16 * dem_filled * 9 / 10) << "epoch " << epoch;

  std::ifstream ply(reports / dense::EpochCloudFileName(epoch), std::ios::binary);
  ASSERT_TRUE(ply.good()) << dense::EpochCloudFileName(epoch);
  std::string header, line;
  while (std::getline(ply, line) && line != "end_header") header += line + "\n";
  EXPECT_NE(header.find("element vertex " +
                        std::to_string(static_cast<size_t>(cloud->width) * cloud->height) + "\n"),
            std::string::npos)
      << header;
  EXPECT_NE(header.find("property float sigma_z"), std::string::npos) << header;

  char name[64];
  std::snprintf(name, sizeof name, "surface_report_e%02d.json", epoch);
  const std::string report = ReadFile(reports / name);
  std::snprintf(name, sizeof name, "surface_report_e%02d.md", epoch);
  EXPECT_TRUE(fs::exists(reports / name)) << name;
  EXPECT_EQ(report.find("\"change\"") != std::string::npos, later) << report;
  if (!later) return;
  const nlohmann::json change = nlohmann::json::parse(report).at("change");
  auto pair = [&](const std::string& key) {
    const nlohmann::json& v = change.at(key);
    return Eigen::Vector2d(v.at(0).get<double>(), v.at(1).get<double>());
  };
  const Eigen::Vector2d shift = pair("shift_m"), sigma = pair("shift_sigma_m");
  const Eigen::Vector2d searched = pair("searched_shift_m");
  const Eigen::Vector2d gain = pair("gain_m3"), loss = pair("loss_m3");
  std::printf(
      "epoch %d co-registration: shift (%.4f +- %.4f, %.4f +- %.4f) m, gain %.2f +- %.2f "
      "m3, loss %.2f +- %.2f m3\n",
      epoch, shift.x(), sigma.x(), shift.y(), sigma.y(), gain.x(), gain.y(), loss.x(), loss.y());
  EXPECT_EQ(searched, Eigen::Vector2d::Zero());
  for (int k = 0; k < 2; ++k) {
    EXPECT_GT(sigma[k], 0.0);
    EXPECT_LE(std::abs(shift[k]), 3 * sigma[k]) << "axis " << k;
  }
  EXPECT_GE(gain.x(), 0.0);
  EXPECT_GE(loss.x(), 0.0);
  EXPECT_GT(gain.y(), 0.0);
  EXPECT_GT(loss.y(), 0.0);
}

TEST(ProcessBagDense, ACloudPerEpochTheGeoTiffsAndTheTruth) {
  const fs::path dir = Scratch("dense");
  ASSERT_EQ(RunProcessBag(dir, ""), 0);
  const sim::SurveyTruth truth = sim::SurveyTruth::Load(Survey(".truth.yaml"));
  const std::string err = ReadFile(dir / "stderr");
  // Every photo the adjustment oriented was measured (collected by message).
  EXPECT_EQ(err.find("not used"), std::string::npos) << err;

  const Outputs out = ReadOutputs(dir / "out.bag");
  ASSERT_EQ(out.solutions.size(), truth.surfaces.size()) << err;  // every epoch adjusted
  ASSERT_EQ(out.clouds.size(), out.solutions.size()) << err;      // and measured
  const int reference = out.solutions.begin()->second;
  for (const auto& [stamp, cloud] : out.clouds) {
    ASSERT_EQ(out.solutions.count(stamp), 1u) << "cloud at " << stamp << " without a solution";
    const int epoch = out.solutions.at(stamp);
    EXPECT_EQ(cloud->header.frame_id, "site");
    std::vector<std::string> names;
    for (const auto& f : cloud->fields) names.push_back(f.name);
    EXPECT_EQ(names, (std::vector<std::string>{"x", "y", "z", "rgb", "sigma_z", "change", "lod"}));
    const size_t n = static_cast<size_t>(cloud->width) * cloud->height;
    EXPECT_GE(n, 100000u) << "epoch " << epoch;  // 4..7 pairs of 1280 x 960 photos
    size_t finite_change = 0, positive_sigma = 0;
    for (sensor_msgs::PointCloud2ConstIterator<float> ch(*cloud, "change"), sz(*cloud, "sigma_z");
         ch != ch.end(); ++ch, ++sz) {
      finite_change += std::isfinite(*ch);
      positive_sigma += *sz > 0.0f;
    }
    EXPECT_EQ(positive_sigma, n) << "epoch " << epoch;
    std::printf("epoch %d: %zu points, %zu with a change\n", epoch, n, finite_change);
    // A later epoch has a change wherever the reference surface exists (it
    // covers about half of the later flight's cells); the reference none.
    if (epoch == reference)
      EXPECT_EQ(finite_change, 0u);
    else
      EXPECT_GT(finite_change, n / 4) << "epoch " << epoch;
  }

  ExpectViewMarkers(out);

  // The GeoTIFFs, and each DEM against the true surface on bare ground.
  // Issue 38: they carry the EPSG code of the site's map CRS: this local_enu
  // site's (--site-config geodetic_origin 46.5 N, 8.0 E, 1200 m) UTM zone 32,
  // EPSG:32632 (they were in the local CRS "site"), GDAL's tools read and warp
  // them, and the DEM is read back into the site frame through SiteCrs.
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(46.5, 8.0, 1200.0);
  for (const auto& [stamp, epoch] : out.solutions) {
    const fs::path surface = dir / "reports" / dense::EpochSurfaceFileName(epoch);
    const fs::path change = dir / "reports" / dense::EpochChangeFileName(epoch);
    const fs::path ortho = dir / "reports" / dense::EpochOrthoFileName(epoch);
    ASSERT_TRUE(fs::exists(surface)) << surface;
    ASSERT_TRUE(fs::exists(ortho)) << ortho;
    EXPECT_EQ(fs::exists(change), epoch != reference) << epoch;
    for (const fs::path& tif : {surface, change, ortho}) {
      if (!fs::exists(tif)) continue;
      const std::string stem = tif.stem().string();
      const auto [srs_status, srs] =
          Gdal("gdalsrsinfo -o epsg " + tif.string(), dir, stem + ".srsinfo");
      EXPECT_EQ(srs_status, 0) << srs;
      EXPECT_NE(srs.find("EPSG:32632"), std::string::npos) << tif << ": " << srs;
      const fs::path warped = dir / (stem + "_wgs84.tif");
      const auto [warp_status, warp] = Gdal(
          "gdalwarp -t_srs EPSG:4326 " + tif.string() + " " + warped.string(), dir, stem + ".warp");
      EXPECT_EQ(warp_status, 0) << warp;
      // The warped raster's centre is on the surveyed slope: about 100 m east
      // and 80 m north of the origin (dense_graph_replay.sim.yaml), i.e.
      // 8.0 E + 100 / (111 320 cos 46.5 deg) = 8.0013, 46.5 N + 80 / 111 150 = 46.5007.
      const auto [info_status, info] = Gdal("gdalinfo " + warped.string(), dir, stem + ".info");
      EXPECT_EQ(info_status, 0) << info;
      std::smatch m;
      ASSERT_TRUE(
          std::regex_search(info, m, std::regex(R"(Center\s*\(\s*([-0-9.]+),\s*([-0-9.]+)\))")))
          << info;
      EXPECT_NEAR(std::stod(m[1]), 8.0013, 0.0010) << info;
      EXPECT_NEAR(std::stod(m[2]), 46.5007, 0.0006) << info;
    }
    const sim::SurfaceTruth* t = nullptr;
    for (const sim::SurfaceTruth& s : truth.surfaces)
      if (s.epoch == epoch) t = &s;
    ASSERT_NE(t, nullptr) << "no true surface for epoch " << epoch;
    const io::GeoRaster truth_dem =
        io::ReadGeoTiff((fs::path(Survey(".truth.yaml")).parent_path() / t->geotiff).string());
    const io::GeoRaster in_map = io::ReadGeoTiff(surface.string());
    EXPECT_EQ(in_map.epsg, 32632);
    // The DEM back in the site frame (SiteRasterFromMap: a north-up site grid
    // of its cell size covering it).
    const std::vector<double> e =
        BareGroundErrors(io::SiteRasterFromMap(in_map, &site), truth_dem, truth);
    std::printf("epoch %d DEM vs truth, bare ground: %zu cells, median |e| %.3f m, p90 %.3f m\n",
                epoch, e.size(), Quantile(e, 0.5), Quantile(e, 0.9));
    EXPECT_GE(e.size(), 5000u);
    EXPECT_LE(Quantile(e, 0.5), 0.10) << "epoch " << epoch;
    EXPECT_LE(Quantile(e, 0.9), 0.30) << "epoch " << epoch;
    ExpectProcessFlightProducts(dir / "reports", epoch, epoch != reference, in_map,
                                out.clouds.at(stamp));
  }
  // Every JSON and GeoJSON of the run (surface reports, deformation.geojson, ...).
  replay_test::ExpectStrictJson(dir / "reports");
}

TEST(ProcessBagDense, NoDenseTurnsTheStepOff) {
  const fs::path dir = Scratch("no_dense");
  ASSERT_EQ(RunProcessBag(dir, "--no-dense"), 0);
  const Outputs out = ReadOutputs(dir / "out.bag");
  EXPECT_EQ(out.solutions.size(), 2u);
  EXPECT_TRUE(out.clouds.empty());
  for (const auto& f : fs::directory_iterator(dir / "reports"))
    EXPECT_EQ(f.path().filename().string().rfind("surface_e", 0), std::string::npos) << f.path();
}

}  // namespace
}  // namespace slope_monitor
