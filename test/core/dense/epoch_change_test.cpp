// The epoch surface (dense/epoch_surface.h) and the DoD with co-registration
// and level of detection (dense/dem_change.h) on the package's simulator: the
// small slope of sim_test.cpp (moving body, head scarp, a tree) photographed
// by two overlapping nadir UAV photos per epoch, plus a third photo 22 m
// away whose footprint overlaps too little (it must be skipped, named).
//
// Epoch 0 carries the true orientations. Epoch 1 carries orientations with a
// datum error, as an adjustment with a slightly wrong datum would give: the
// whole epoch (cameras and adjusted points) moved by a rigid transform D
// (0.1 / -0.06 / 0.15 m and a 2 mrad tilt). The photos are rendered with the
// true poses, so epoch 1's DEM is the true surface moved by D, and only
// co-registration on the stable strips outside the monitored outline brings
// it back. Truth: sim::Scene::AtTime's height grid (the mesh the renderer
// intersects), the same surface as the simulator's surface_eNN.tif.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/dense/surface_series.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/truth.h"

#include "../sim/test_scene.h"

namespace slope_monitor {
namespace dense {
namespace {

constexpr double kEpochChangeTime = 3600.0;  // [s] the body travels 2 m by then
const Eigen::Vector4d kEpochChangeRegion(10.0, 30.0, 6.0, 24.0);

sim::SceneSpec EpochChangeSite() {
  sim::SceneSpec s = sim::testing::SmallSlope(11);
  sim::testing::SetSouthwardBody(&s, Eigen::Vector2d(20, 15), 7.0, 5.0, 0.3, 2.0);
  s.scarp.depth = 1.0;
  s.obstacles.push_back(sim::testing::Tree(13.0, 20.0));
  return s;
}

camera::CameraModel EpochChangeCamera() {
  return sim::testing::SmallCamera(640, 480, 8.0, 0.01, -0.006, -1.0e-3);
}

// The datum error of epoch 1: x_adjusted = D x_true.
Rigid3 DatumError(const sim::Scene& scene) {
  const Eigen::Vector3d p0(20.0, 15.0, scene.AnalyticHeight(20.0, 15.0));
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(0.002, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  return Rigid3(r, p0 - r * p0 + Eigen::Vector3d(0.10, -0.06, 0.15));
}

// The monitored outline: an ellipse 2 m / 3 m beyond the body's semi-axes.
Polygon Outline() {
  Polygon p;
  for (int k = 0; k < 48; ++k) {
    const double a = 2 * M_PI * k / 48;
    p.emplace_back(20.0 + 7.0 * std::cos(a), 15.0 + 10.0 * std::sin(a));
  }
  return p;
}

// As sim_test.cpp: within 1.5 m of what sim::SurveyTruth::Unmatchable flags.
bool EpochChangeNear(const sim::SurveyTruth& truth, const Eigen::Vector3d& x_ref) {
  if (truth.Unmatchable(x_ref)) return true;
  for (double r : {0.75, 1.5})
    for (int k = 0; k < 12; ++k) {
      const double a = 2 * M_PI * k / 12;
      if (truth.Unmatchable(x_ref + r * Eigen::Vector3d(std::cos(a), std::sin(a), 0))) return true;
    }
  return false;
}

double Rms(const std::vector<double>& e) {
  double s = 0;
  for (double v : e) s += v * v;
  return e.empty() ? NAN : std::sqrt(s / e.size());
}

EpochSurfaceOptions EpochChangeOptions() {
  EpochSurfaceOptions o;
  o.surface.cell_size = 0.5;
  o.surface.min_points_per_cell = 2;
  o.surface.correlation.final_grid_spacing = 2;
  o.region = kEpochChangeRegion;
  return o;
}

class EpochChangeTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = new sim::Scene(EpochChangeSite());
    states_[0] = new sim::Scene::State(scene_->AtTime(0.0));
    states_[1] = new sim::Scene::State(scene_->AtTime(kEpochChangeTime));
    truth_ = new sim::SurveyTruth();
    truth_->landslide = scene_->spec().landslide;
    truth_->scarp = scene_->spec().scarp;
    truth_->obstacles = scene_->obstacles();
    const camera::CameraModel model = EpochChangeCamera();
    const sim::Renderer renderer(*scene_, model);
    sim::RenderOptions ro;
    ro.threads = 2;
    const double z = scene_->AnalyticHeight(20.0, 15.0) + 35.0;
    const Rigid3 datum = DatumError(*scene_);
    for (int e = 0; e < 2; ++e) {
      EpochSurfaceInput in;
      in.epoch = e;
      const Rigid3 d = e == 0 ? Rigid3() : datum;
      for (int i = 0; i < 2; ++i) {
        const camera::ExteriorOrientation truth_pose =
            sim::testing::NadirFrom(Eigen::Vector3d(16.0 + 8 * i, 15, z));
        EpochImage im;
        im.camera = "uav";
        im.image.name = Message("uav/e", e, "_", i);
        im.image.image = sim::testing::Photo(renderer, *states_[e], truth_pose, ro, 1 + 2 * e + i);
        im.image.camera = model;
        im.image.pose = camera::ExteriorOrientation::FromOpticalFromSite(
            truth_pose.OpticalFromSite() * d.Inverse());
        im.image.oriented = true;
        in.images.push_back(im);
      }
      EpochImage far = in.images[0];  // 22 m east of the first: too little overlap
      far.image.name = Message("uav/e", e, "_far");
      far.image.pose.position.x() += 22.0;
      in.images.push_back(far);
      for (double x : {12.0, 20.0, 28.0})
        for (double y : {8.0, 15.0, 22.0})
          in.adjusted_points.push_back(d * Eigen::Vector3d(x, y, states_[e]->grid.HeightAt(x, y)));
      surfaces_[e] = new EpochSurfaceResult(MeasureEpochSurface(in, EpochChangeOptions()));
      inputs_[e] = new EpochSurfaceInput(in);
      std::printf("%s\n", surfaces_[e]->summary.BriefReport().c_str());
    }
    const std::vector<uint8_t> stable = StableMask(surfaces_[0]->dem, {Outline()}, {}, "test");
    change_ = new DemChangeResult(
        DemChange(surfaces_[0]->dem, surfaces_[1]->dem, {Outline()}, stable, {}));
    std::printf("%s\n", change_->summary.BriefReport().c_str());
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete states_[0];
    delete states_[1];
    delete truth_;
    delete surfaces_[0];
    delete surfaces_[1];
    delete change_;
    delete inputs_[0];
    delete inputs_[1];
  }
  // Height errors of a DEM on bare ground (not near the tree / scarp).
  static std::vector<double> BareErrors(const io::GeoRaster& dem, const sim::Scene::State& st,
                                        int* bare_cells) {
    std::vector<double> e;
    *bare_cells = 0;
    for (int r = 0; r < dem.height; ++r)
      for (int c = 0; c < dem.width; ++c) {
        const Eigen::Vector2d xy = dem.CellCentre(r, c);
        const double zt = st.grid.HeightAt(xy.x(), xy.y());
        const Eigen::Vector3d x_ref =
            truth_->landslide.ReferencePositionOf(Eigen::Vector3d(xy.x(), xy.y(), zt), st.t);
        if (EpochChangeNear(*truth_, x_ref)) continue;
        ++*bare_cells;
        const float z = dem.At(kHeight, r, c);
        if (!dem.IsNoData(z)) e.push_back(z - zt);
      }
    return e;
  }
  static double TrueChange(const Eigen::Vector2d& xy) {
    return states_[1]->grid.HeightAt(xy.x(), xy.y()) - states_[0]->grid.HeightAt(xy.x(), xy.y());
  }
  static sim::Scene* scene_;
  static sim::Scene::State* states_[2];
  static sim::SurveyTruth* truth_;
  static EpochSurfaceResult* surfaces_[2];
  static EpochSurfaceInput* inputs_[2];  // as measured (photos, orientations, adjusted points)
  static DemChangeResult* change_;
};
sim::Scene* EpochChangeTest::scene_ = nullptr;
sim::Scene::State* EpochChangeTest::states_[2] = {nullptr, nullptr};
sim::SurveyTruth* EpochChangeTest::truth_ = nullptr;
EpochSurfaceResult* EpochChangeTest::surfaces_[2] = {nullptr, nullptr};
EpochSurfaceInput* EpochChangeTest::inputs_[2] = {nullptr, nullptr};
DemChangeResult* EpochChangeTest::change_ = nullptr;

TEST_F(EpochChangeTest, PairsAreChosenByFootprintOverlap) {
  for (int e = 0; e < 2; ++e) {
    const EpochSurfaceSummary& s = surfaces_[e]->summary;
    EXPECT_EQ(s.pairs_measured, 1);
    ASSERT_EQ(s.pair_errors.size(), 2u);  // both pairs with the far photo
    for (const std::string& why : s.pair_errors) {
      EXPECT_NE(why.find("_far"), std::string::npos) << why;
      EXPECT_NE(why.find("min_pair_overlap 60 %"), std::string::npos) << why;
    }
    EXPECT_EQ(surfaces_[e]->dem.width, 40);
    EXPECT_EQ(surfaces_[e]->dem.height, 36);
    EXPECT_EQ(static_cast<int>(surfaces_[e]->points.size()), s.points);
  }
}

TEST_F(EpochChangeTest, DemOfBareGroundWithin5cmOfTheTruth) {
  int bare = 0;
  const std::vector<double> e0 = BareErrors(surfaces_[0]->dem, *states_[0], &bare);
  std::printf("epoch 0 DEM: bare ground %zu/%d cells, RMS %.4f m\n", e0.size(), bare, Rms(e0));
  EXPECT_GT(e0.size(), 0.95 * bare);
  EXPECT_LT(Rms(e0), 0.05);
  // Epoch 1 as measured carries the datum error; co-registered it is the truth.
  const std::vector<double> raw = BareErrors(surfaces_[1]->dem, *states_[1], &bare);
  const std::vector<double> e1 = BareErrors(change_->after_coregistered, *states_[1], &bare);
  std::printf(
      "epoch 1 DEM: bare ground RMS %.4f m as measured (datum error), %.4f m co-registered (%zu/%d "
      "cells)\n",
      Rms(raw), Rms(e1), e1.size(), bare);
  EXPECT_GT(Rms(raw), 0.10);
  EXPECT_GT(e1.size(), 0.90 * bare);
  EXPECT_LT(Rms(e1), 0.05);
}

TEST_F(EpochChangeTest, CoregistrationRemovesTheDatumErrorOnStableGround) {
  const Coregistration& c = change_->summary.coregistration;
  EXPECT_GT(c.stable_cells, 300);
  EXPECT_GT(c.residual_before, 0.10);
  EXPECT_LT(c.residual, 0.05);
  // D moves the ground near the centre up by about 0.15 m.
  EXPECT_NEAR(c.vertical, 0.15, 0.05);
}

TEST_F(EpochChangeTest, DodErrorAndLevelOfDetection) {
  const io::GeoRaster& g = change_->change;
  std::vector<double> bare_error;
  int stable = 0, stable_below = 0, large = 0, large_flagged = 0;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) {
      const float dz = g.At(kChange, r, c);
      if (g.IsNoData(dz)) continue;
      const Eigen::Vector2d xy = g.CellCentre(r, c);
      const double t = TrueChange(xy);
      const float lod = g.At(kLodBand, r, c), cls = g.At(kClass, r, c);
      const double zt = states_[1]->grid.HeightAt(xy.x(), xy.y());
      const Eigen::Vector3d x_ref =
          truth_->landslide.ReferencePositionOf(Eigen::Vector3d(xy.x(), xy.y(), zt), states_[1]->t);
      if (!EpochChangeNear(*truth_, x_ref)) bare_error.push_back(dz - t);
      if (std::abs(t) < 1e-3) {
        ++stable;
        stable_below += cls == 0.0f;
      }
      if (std::abs(t) > 2 * lod) {
        ++large;
        large_flagged += cls != 0.0f;
      }
    }
  std::printf(
      "DoD: bare ground error RMS %.4f m over %zu cells; truly stable below LoD %d/%d; true change "
      "> 2 LoD "
      "flagged %d/%d\n",
      Rms(bare_error), bare_error.size(), stable_below, stable, large_flagged, large);
  EXPECT_LT(Rms(bare_error), 0.05);
  ASSERT_GT(stable, 200);
  EXPECT_GE(stable_below, 0.95 * stable);
  ASSERT_GT(large, 100);
  EXPECT_GE(large_flagged, 0.90 * large);
}

TEST_F(EpochChangeTest, NetVolumeWithin5PercentAndTheTruthInsideItsUncertainty) {
  const io::GeoRaster& g = change_->change;
  const std::vector<uint8_t> outside = StableMask(g, {Outline()}, {}, "outline");
  double truth = 0;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c)
      if (!outside[static_cast<size_t>(r) * g.width + c])
        truth += TrueChange(g.CellCentre(r, c)) * 0.25;
  const DemChangeSummary& s = change_->summary;
  std::printf(
      "net volume inside the outline: %.2f +- %.2f m3 (1 sigma), truth %.2f m3, error %.2f %%\n",
      s.volume_net, s.sigma_net, truth, 100 * (s.volume_net - truth) / std::abs(truth));
  ASSERT_LT(truth, -20.0);  // the body's surface drops
  EXPECT_NEAR(s.volume_net, truth, 0.05 * std::abs(truth));
  EXPECT_LE(std::abs(s.volume_net - truth), 1.96 * s.sigma_net);
  EXPECT_GT(s.volume_cut, 0.8 * std::abs(truth));
  EXPECT_LT(s.volume_fill, 0.05 * std::abs(truth));
}

TEST_F(EpochChangeTest, GeoTiffsSurfaceAndChange) {
  const std::string dir = ::testing::TempDir() + "/epoch_change_test";
  std::filesystem::create_directories(dir);
  io::WriteGeoTiff(dir + "/" + EpochSurfaceFileName(1), surfaces_[1]->dem);
  io::WriteGeoTiff(dir + "/" + EpochChangeFileName(1), change_->change);
  const io::GeoRaster back = io::ReadGeoTiff(dir + "/change_e01.tif");
  ASSERT_EQ(back.num_bands(), 3);
  EXPECT_EQ(back.band_names, (std::vector<std::string>{"change", "lod", "class"}));
  EXPECT_EQ(io::ReadGeoTiff(dir + "/surface_e01.tif").width, 40);
}

// Issue 35, must-show on the simulator: a second epoch oriented by a
// consumer GNSS alone is off by metres. Such a block is the true block moved
// rigidly (one receiver bias for the whole flight), so its DEM is the true
// surface moved by that offset: epoch 1's photos, as rendered, with every
// photo's orientation and every adjusted point moved by kGnss on top of its
// datum error D. That epoch goes through the graph's path (SurfaceSeries, the
// dense_epoch nodelet's and process_bag's) against epoch 0: the whole-cell
// search and the Nuth-Kaab co-registration on the stable strips outside the
// outline must bring it back within the shift's sigma, and the stable ground
// must stay within its LoD. The series writes what process_flight writes per
// flight: DEM, orthophoto, cloud, change and the report.
TEST_F(EpochChangeTest, ShiftedGnssEpochIsCoregisteredWithinItsSigmaByTheSeries) {
  const Eigen::Vector3d kGnss(2.3, -1.7, 0.9);  // [m] a consumer receiver's bias
  EpochSurfaceInput shifted = *inputs_[1];
  for (EpochImage& im : shifted.images) im.image.pose.position += kGnss;
  for (Eigen::Vector3d& p : shifted.adjusted_points) p += kGnss;
  const std::string dir = ::testing::TempDir() + "/epoch_change_test_series";
  std::filesystem::remove_all(dir);
  SurfaceSeriesOptions o;
  o.surface = EpochChangeOptions();
  o.outlines = {Outline()};
  o.report_dir = dir;
  SurfaceSeries series(o);
  const SeriesEpoch e0 = series.Measure(*inputs_[0]);
  ASSERT_TRUE(e0.errors.empty()) << e0.errors.front();
  const SeriesEpoch e1 = series.Measure(shifted);
  ASSERT_TRUE(e1.errors.empty()) << e1.errors.front();
  ASSERT_TRUE(e1.change && e1.change_summary);
  const SurfaceChangeSummary& s = *e1.change_summary;
  const Coregistration& c = s.dem.coregistration;
  // The truth at the stable cells' centre: D and then kGnss move it by e.
  const Eigen::Vector3d centre(c.centre.x(), c.centre.y(),
                               states_[1]->grid.HeightAt(c.centre.x(), c.centre.y()));
  const Eigen::Vector3d e = DatumError(*scene_) * centre - centre + kGnss;
  std::printf(
      "shifted GNSS epoch: %s\n  applied (%.3f, %.3f, %.3f) m at the stable centre (%.1f, %.1f); "
      "stable RMS %.3f -> %.3f m\n",
      s.BriefReport().c_str(), e.x(), e.y(), e.z(), c.centre.x(), c.centre.y(), c.residual_before,
      c.residual);
  // The linearised Nuth-Kaab alone (the graph's co-registration before the
  // search), for the record: x off by 0.38 m (2.6 sigma), the body's loss
  // 39.6 m3 (doc/real_surfaces.md).
  SurfaceChangeInput plain;
  plain.reference = &e0.surface->dem;
  plain.after = &e1.surface->dem;
  plain.moving = {Outline()};
  SurfaceChangeOptions no_search;
  no_search.search_radius = 0;
  std::printf("  without the search: %s\n",
              CompareSurfaces(plain, no_search).summary.BriefReport().c_str());
  EXPECT_GT(c.residual_before, 0.5);  // metres of false change before co-registration
  for (int k = 0; k < 2; ++k) {
    EXPECT_GT(c.shift_sigma[k], 0.0);
    EXPECT_LT(c.shift_sigma[k], 0.1);  // a sigma that says something
    EXPECT_LE(std::abs(c.shift[k] - e[k]), 3 * c.shift_sigma[k]) << "axis " << k;
  }
  EXPECT_NEAR(c.vertical, e.z(), 0.05);
  // No false change on the stable ground: median dz within 1 cm, at most
  // 5 % of it beyond its LoD.
  EXPECT_GT(s.stable_common, 300);
  EXPECT_LT(std::abs(s.stable_median), 0.01);
  EXPECT_LE(s.stable_flagged, 0.05);
  // The body's loss as from the unbiased epoch 1 (34.5 m3), within 2 sigma.
  EXPECT_NEAR(s.dem.volume_cut, change_->summary.volume_cut, 2 * s.dem.sigma_cut);

  // The files of the epoch, as process_flight's per flight.
  for (const std::string& name :
       {EpochSurfaceFileName(1), EpochOrthoFileName(1), EpochCloudFileName(1),
        EpochChangeFileName(1), std::string("surface_report_e01.json"),
        std::string("surface_report_e01.md")})
    EXPECT_TRUE(std::filesystem::exists(dir + "/" + name)) << name;
  const io::GeoRaster ortho = io::ReadGeoTiff(dir + "/" + EpochOrthoFileName(1));
  EXPECT_EQ(ortho.band_names, (std::vector<std::string>{"red", "green", "blue"}));
  EXPECT_EQ(ortho.width, 4 * e1.surface->dem.width);  // 4 x 4 cells per DEM cell
  std::ifstream ply(dir + "/" + EpochCloudFileName(1), std::ios::binary);
  std::string line;
  std::getline(ply, line);
  EXPECT_EQ(line, "ply");
  std::stringstream report;
  report << std::ifstream(dir + "/surface_report_e01.json").rdbuf();
  EXPECT_NE(report.str().find("\"shift_sigma_m\""), std::string::npos) << report.str();
  EXPECT_NE(report.str().find("\"gain_m3\""), std::string::npos) << report.str();
  EXPECT_NE(report.str().find("\"reference\": \"surface_e00.tif\""), std::string::npos);
  // The reference epoch: its files, no change.
  EXPECT_TRUE(std::filesystem::exists(dir + "/" + EpochOrthoFileName(0)));
  EXPECT_FALSE(std::filesystem::exists(dir + "/" + EpochChangeFileName(0)));
}

TEST_F(EpochChangeTest, BadInputIsNamed) {
  // A DEM cell that would need more memory than the limit.
  EpochSurfaceInput in;
  in.epoch = 4;
  in.adjusted_points = {Eigen::Vector3d(20, 15, 0)};
  EpochSurfaceOptions o = EpochChangeOptions();
  o.surface.cell_size = 0.001;
  try {
    MeasureEpochSurface(in, o);
    ADD_FAILURE() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("max_dem_megabytes"), std::string::npos) << e.what();
  }
  // A stable mask of the wrong size.
  try {
    StableMask(surfaces_[0]->dem, {}, std::vector<uint8_t>(10, 1), "site.yaml: stable_mask");
    ADD_FAILURE() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("site.yaml: stable_mask"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("40 x 36"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
