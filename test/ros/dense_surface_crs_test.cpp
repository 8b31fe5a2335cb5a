// dense_surface's pair mode writes its rasters in the site's map CRS (issue
// 38 item 7): the synthetic stereo pair of the dense tests (an analytic
// hill, test/core/dense/synthetic_scene.h) written as pair.yaml and measured
// by the tool as the user runs it, georeferenced by an estimator overlay's
// geodetic_origin (46.5 N, 8 E: UTM zone 32, EPSG:32632). Truths: gdalsrsinfo
// names EPSG:32632 for dense_surface.tif, dense_ortho.tif and change.tif; the
// surface taken back to the site frame lies on the analytic ground; the same
// pair measured against itself as --reference (read back from the map CRS)
// shows no change. Without a georeference the tool says the rasters are in
// the local CRS 'site', and refuses a georeferenced reference naming it.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "../core/dense/synthetic_scene.h"
#include "run_command.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using run_command::CommandRun;

CommandRun DenseSurface(const std::string& args) {
  return run_command::Run(std::string(SM_TOOL_DIR) + "/dense_surface " + args);
}

// The image as a pair.yaml side: its PNG, sensor, interior and exterior.
std::string Side(const dense::OrientedImage& im, const fs::path& dir) {
  const std::string png = im.name + ".png";
  cv::imwrite((dir / png).string(), im.image);
  const camera::Sensor& s = im.camera.sensor();
  std::string out = "{image: " + png + ", sensor: [" + std::to_string(s.width) + ", " +
                    std::to_string(s.height) + ", " + std::to_string(s.pixel_size) +
                    "], distortion_model: " + camera::DistortionModelName(im.camera.model()) +
                    ", interior: [";
  for (size_t i = 0; i < im.camera.interior().size(); ++i)
    out += (i ? ", " : "") + std::to_string(im.camera.interior()[i]);
  out += "], exterior: [";
  const auto e = im.pose.ToArray();
  for (size_t i = 0; i < e.size(); ++i) out += (i ? ", " : "") + std::to_string(e[i]);
  return out + "]}";
}

std::string SrsInfo(const fs::path& tif) {
  return run_command::Run("gdalsrsinfo -o epsg " + tif.string()).output;
}

TEST(DenseSurfaceCrs, PairRastersInTheSitesMapCrsAndBack) {
  const fs::path dir = fs::temp_directory_path() / ("sm_dense_crs_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const dense::test_scene::Scene scene;
  std::ofstream(dir / "pair.yaml")
      << "left: " << Side(dense::test_scene::MakeImage(scene, "left", 16.0, -2e-3), dir)
      << "\nright: " << Side(dense::test_scene::MakeImage(scene, "right", 24.0, 0.0), dir) << "\n";
  std::ofstream(dir / "overlay.yaml") << "geodetic_origin: [46.5, 8.0, 1200.0]\n";
  const std::string config_keys =
      "final_grid_spacing: 4\nmin_depth: 30.0\nmax_depth: 50.0\nregion: [10.0, 30.0, 6.0, "
      "24.0]\n";
  // The georeference from the config file's site_config (as the node reads it).
  std::ofstream(dir / "config.yaml")
      << config_keys << "site_config: " << (dir / "overlay.yaml").string() << "\n";
  std::ofstream(dir / "local.yaml") << config_keys;
  const std::string pair = " --pair " + (dir / "pair.yaml").string();

  const CommandRun first = DenseSurface(pair + " --config " + (dir / "config.yaml").string() +
                                        " --out-dir " + (dir / "first").string());
  ASSERT_EQ(first.status, 0) << first.output;
  EXPECT_NE(first.output.find("rasters in EPSG:32632"), std::string::npos) << first.output;
  for (const char* name : {"dense_surface.tif", "dense_ortho.tif"})
    EXPECT_NE(SrsInfo(dir / "first" / name).find("EPSG:32632"), std::string::npos) << name;

  // Back in the site frame, on the analytic ground (10 m plus the 2 m hill).
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(46.5, 8.0, 1200.0);
  const io::GeoRaster map_dem = io::ReadGeoTiff((dir / "first" / "dense_surface.tif").string());
  EXPECT_EQ(map_dem.epsg, 32632);
  EXPECT_GT(map_dem.At(0, map_dem.height / 2, map_dem.width / 2), 1200.0);  // ellipsoidal
  const io::GeoRaster dem = io::SiteRasterFromMap(map_dem, &site);
  std::vector<double> err;
  for (int r = 0; r < dem.height; ++r)
    for (int c = 0; c < dem.width; ++c) {
      const float z = dem.At(0, r, c);
      const Eigen::Vector2d xy = dem.CellCentre(r, c);
      if (!dem.IsNoData(z)) err.push_back(std::abs(z - scene.Height(xy.x(), xy.y())));
    }
  ASSERT_GT(err.size(), 500u);
  std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
  EXPECT_LT(err[err.size() / 2], 0.05) << "median |z - truth| [m] of " << err.size() << " cells";
  std::printf("surface back in site: median |z - truth| %.4f m over %zu cells\n",
              err[err.size() / 2], err.size());

  // The same pair against its own surface (from the map CRS): no change.
  const std::string reference = " --reference " + (dir / "first" / "dense_surface.tif").string();
  const CommandRun second = DenseSurface(
      pair + reference + " --config " + (dir / "local.yaml").string() + " --site-config " +
      (dir / "overlay.yaml").string() + " --out-dir " + (dir / "second").string());
  ASSERT_EQ(second.status, 0) << second.output;
  EXPECT_NE(SrsInfo(dir / "second" / "change.tif").find("EPSG:32632"), std::string::npos);
  const io::GeoRaster change =
      io::SiteRasterFromMap(io::ReadGeoTiff((dir / "second" / "change.tif").string()), &site);
  std::vector<double> dz;
  int significant = 0;
  for (int r = 0; r < change.height; ++r)
    for (int c = 0; c < change.width; ++c) {
      const float v = change.At(dense::kDz, r, c), sig = change.At(dense::kSignificant, r, c);
      if (!change.IsNoData(v)) dz.push_back(std::abs(v));
      significant += !change.IsNoData(sig) && sig != 0.0f;
    }
  ASSERT_GT(dz.size(), 500u);
  std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
  EXPECT_LT(dz[dz.size() / 2], 0.005) << "median |dz| [m] of " << dz.size() << " cells";
  EXPECT_EQ(significant, 0);
  std::printf("against itself: median |dz| %.4f m over %zu cells, %d significant\n",
              dz[dz.size() / 2], dz.size(), significant);

  // No georeference: said so, and a reference in EPSG:32632 refused by name.
  const CommandRun local =
      DenseSurface(pair + reference + " --config " + (dir / "local.yaml").string() + " --out-dir " +
                   (dir / "local").string());
  EXPECT_EQ(local.status, 1) << local.output;
  EXPECT_NE(local.output.find("rasters in the local CRS 'site'"), std::string::npos)
      << local.output;
  EXPECT_NE(local.output.find("--reference " + (dir / "first" / "dense_surface.tif").string()),
            std::string::npos)
      << local.output;
  EXPECT_NE(local.output.find("EPSG:32632"), std::string::npos) << local.output;
  EXPECT_EQ(SrsInfo(dir / "local" / "dense_surface.tif").find("EPSG:32632"), std::string::npos);
  EXPECT_EQ(io::ReadGeoTiff((dir / "local" / "dense_surface.tif").string()).epsg, 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace slope_monitor
