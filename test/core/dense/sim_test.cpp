// The dense chain on the package's simulator (src/core/sim): a small textured
// slope with a moving landslide body, a head scarp and a tree, rendered by
// sim::Renderer through the camera model (with lens distortion) for two
// nadir cameras at two epochs. The pair is oriented with the TRUE poses. The
// surface model is compared with the simulator's true height field of the
// same epoch (the mesh the renderer intersects, sim::Scene::AtTime), and the
// surface change with the true change of the moved body.
//
// Bare ground = cells farther than 1.5 m from where sim::SurveyTruth::
// Unmatchable flags the tree (crown radius) or the scarp band; the cells near
// them are reported separately.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/dense/change.h"
#include "slope_monitor/core/dense/options_yaml.h"
#include "slope_monitor/core/dense/surface.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/survey.h"
#include "slope_monitor/core/sim/truth.h"

#include "../sim/test_scene.h"  // the small simulated slope (header only)

namespace slope_monitor {
namespace dense {
namespace {

constexpr double kSimEpochTime = 3600.0;  // [s] epoch 1; the body travels 2 m by then
const Eigen::Vector4d kSimRegion(10.0, 30.0, 6.0, 24.0);

sim::SceneSpec SimSiteSpec() {
  sim::SceneSpec s = sim::testing::SmallSlope(11);
  // Steeper than the slope here: the body's surface drops; 2 m per hour.
  sim::testing::SetSouthwardBody(&s, Eigen::Vector2d(20, 15), 7.0, 5.0, 0.3, 2.0);
  s.scarp.depth = 1.0;
  s.obstacles.push_back(sim::testing::Tree(13.0, 20.0));
  return s;
}

// f = 800 px; at 35 m: 4.4 cm per pixel.
camera::CameraModel SimCamera() {
  return sim::testing::SmallCamera(640, 480, 8.0, 0.01, -0.006, -1.0e-3);
}

camera::ExteriorOrientation NadirAt(const sim::Scene& scene, double x, double y) {
  return sim::testing::NadirFrom(Eigen::Vector3d(x, y, scene.AnalyticHeight(20.0, 15.0) + 35.0));
}

OrientedImage Render(const sim::Scene& scene, const sim::Scene::State& state,
                     const camera::CameraModel& model, const camera::ExteriorOrientation& pose,
                     const std::string& name, unsigned seed) {
  const sim::Renderer renderer(scene, model);
  sim::RenderOptions ro;
  ro.threads = 2;
  OrientedImage im;
  im.name = name;
  im.image = sim::testing::Photo(renderer, state, pose, ro, seed);
  im.camera = model;
  im.pose = pose;
  im.oriented = true;
  return im;
}

// Within kNear of a cell sim::SurveyTruth::Unmatchable flags (the tree's
// crown radius, the scarp band): a tree seen from 35 m is displaced outwards
// by its height times the viewing angle and widened by the correlation
// window, so its effect reaches beyond its radius.
constexpr double kNear = 1.5;  // [m]
bool SimNear(const sim::SurveyTruth& truth, const Eigen::Vector3d& x_ref) {
  if (truth.Unmatchable(x_ref)) return true;
  for (double r : {0.5 * kNear, kNear})
    for (int k = 0; k < 12; ++k) {
      const double a = 2 * M_PI * k / 12;
      if (truth.Unmatchable(x_ref + r * Eigen::Vector3d(std::cos(a), std::sin(a), 0))) return true;
    }
  return false;
}

struct Stats {
  size_t n = 0;
  double rms = 0, p95 = 0, mean = 0;
};

Stats Summarise(std::vector<double> e) {
  Stats s;
  s.n = e.size();
  if (e.empty()) return s;
  double s2 = 0, s1 = 0;
  for (double v : e) s2 += v * v, s1 += v;
  s.rms = std::sqrt(s2 / e.size());
  s.mean = s1 / e.size();
  for (double& v : e) v = std::abs(v);
  std::sort(e.begin(), e.end());
  s.p95 = e[static_cast<size_t>(0.95 * (e.size() - 1))];
  return s;
}

// Half-metre cells from a 2 px grid of points; cameras 25-45 m above the
// ground of kSimRegion.
SurfaceOptions SimSurfaceOptions() {
  SurfaceOptions o;
  o.cell_size = 0.5;
  o.min_points_per_cell = 2;
  o.correlation.final_grid_spacing = 2;
  return o;
}

SurfaceConfig SimSurfaceConfig() {
  SurfaceConfig c;
  c.min_depth = 25.0;
  c.max_depth = 45.0;
  c.region = kSimRegion;
  return c;
}

class DenseSimTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    scene_ = new sim::Scene(SimSiteSpec());
    before_ = new sim::Scene::State(scene_->AtTime(0.0));
    after_ = new sim::Scene::State(scene_->AtTime(kSimEpochTime));
    truth_ = new sim::SurveyTruth();
    truth_->landslide = scene_->spec().landslide;
    truth_->scarp = scene_->spec().scarp;
    truth_->obstacles = scene_->obstacles();
    const camera::CameraModel model = SimCamera();
    const camera::ExteriorOrientation pl = NadirAt(*scene_, 17.0, 15.0),
                                      pr = NadirAt(*scene_, 23.0, 15.0);
    images_ =
        new std::vector<OrientedImage>{Render(*scene_, *before_, model, pl, "sim/left_e0", 1),
                                       Render(*scene_, *before_, model, pr, "sim/right_e0", 2),
                                       Render(*scene_, *after_, model, pl, "sim/left_e1", 3),
                                       Render(*scene_, *after_, model, pr, "sim/right_e1", 4)};
    const SurfaceOptions o = SimSurfaceOptions();
    const SurfaceConfig c = SimSurfaceConfig();
    model0_ = new SurfaceResult(MeasureSurface((*images_)[0], (*images_)[1], o, c, &summary0_));
    model1_ = new SurfaceResult(MeasureSurface((*images_)[2], (*images_)[3], o, c, &summary1_));
  }
  static void TearDownTestSuite() {
    delete scene_;
    delete before_;
    delete after_;
    delete truth_;
    delete images_;
    delete model0_;
    delete model1_;
  }
  static sim::Scene* scene_;
  static sim::Scene::State* before_;
  static sim::Scene::State* after_;
  static sim::SurveyTruth* truth_;
  static std::vector<OrientedImage>* images_;
  static SurfaceResult* model0_;
  static SurfaceResult* model1_;
  static SurfaceSummary summary0_, summary1_;
};
sim::Scene* DenseSimTest::scene_ = nullptr;
sim::Scene::State* DenseSimTest::before_ = nullptr;
sim::Scene::State* DenseSimTest::after_ = nullptr;
sim::SurveyTruth* DenseSimTest::truth_ = nullptr;
std::vector<OrientedImage>* DenseSimTest::images_ = nullptr;
SurfaceResult* DenseSimTest::model0_ = nullptr;
SurfaceResult* DenseSimTest::model1_ = nullptr;
SurfaceSummary DenseSimTest::summary0_, DenseSimTest::summary1_;

TEST_F(DenseSimTest, SurfaceModelAgreesWithTheTrueSurfaceOnBareGround) {
  for (int epoch = 0; epoch < 2; ++epoch) {
    const io::GeoRaster& m = (epoch == 0 ? model0_ : model1_)->model;
    const sim::Scene::State& st = epoch == 0 ? *before_ : *after_;
    ASSERT_EQ(m.width, 40);
    ASSERT_EQ(m.height, 36);
    std::vector<double> bare, hard;
    int bare_cells = 0;
    for (int r = 0; r < m.height; ++r)
      for (int c = 0; c < m.width; ++c) {
        const Eigen::Vector2d xy = m.CellCentre(r, c);
        const double zt = st.grid.HeightAt(xy.x(), xy.y());
        ASSERT_FALSE(std::isnan(zt));
        const Eigen::Vector3d x_ref =
            truth_->landslide.ReferencePositionOf(Eigen::Vector3d(xy.x(), xy.y(), zt), st.t);
        const bool unmatchable = SimNear(*truth_, x_ref);
        bare_cells += !unmatchable;
        const float z = m.At(kHeight, r, c);
        if (m.IsNoData(z)) continue;
        (unmatchable ? hard : bare).push_back(z - zt);
      }
    const Stats b = Summarise(bare), h = Summarise(hard);
    std::printf(
        "epoch %d: %s\n  bare ground: %zu/%d cells filled, height error RMS %.4f m, mean %.4f m, "
        "p95 %.4f m\n"
        "  near scarp / tree (<= 1.5 m of Unmatchable): %zu cells, RMS %.4f m, mean %.4f m, p95 "
        "%.4f m\n",
        epoch, (epoch == 0 ? summary0_ : summary1_).BriefReport().c_str(), b.n, bare_cells, b.rms,
        b.mean, b.p95, h.n, h.rms, h.mean, h.p95);
    // Expected precision: sigma_z = Z^2 / (f B) sigma_d = 35^2 / (800 * 6) * 0.1 px = 0.026 m.
    EXPECT_GT(b.n, 0.95 * bare_cells);
    EXPECT_LT(b.rms, 0.08);
    EXPECT_LT(b.p95, 0.12);
    EXPECT_LT(std::abs(b.mean), 0.03);
    // The tree and the scarp are where matching must fail: worse than bare ground.
    ASSERT_GT(h.n, 10u);
    EXPECT_GT(h.rms, 2 * b.rms);
  }
}

TEST_F(DenseSimTest, ConesConfigurationOnTheSimulator) {
  // config/dense_cones.yaml (no worse than SGBM on Cones, cones_test.cpp) on
  // these (unseen) images: it does NOT transfer. The 5x5 final window and the
  // higher LoG peak give about three times the height error of the defaults
  // on this smooth, finely textured ground (measured: RMS 0.120 m, p95
  // 0.175 m against 0.044 m / 0.076 m), which is why it is a named
  // configuration, not the default.
  SurfaceOptions o = SimSurfaceOptions();
  ReadCorrelationOptions(std::string(SM_SOURCE_DIR) + "/config/dense_cones.yaml", &o.correlation);
  const SurfaceConfig c = SimSurfaceConfig();
  SurfaceSummary summary;
  const io::GeoRaster m = MeasureSurface((*images_)[0], (*images_)[1], o, c, &summary).model;
  std::vector<double> bare;
  int bare_cells = 0;
  for (int r = 0; r < m.height; ++r)
    for (int k = 0; k < m.width; ++k) {
      const Eigen::Vector2d xy = m.CellCentre(r, k);
      const double zt = before_->grid.HeightAt(xy.x(), xy.y());
      if (SimNear(*truth_, Eigen::Vector3d(xy.x(), xy.y(), zt))) continue;
      ++bare_cells;
      const float z = m.At(kHeight, r, k);
      if (!m.IsNoData(z)) bare.push_back(z - zt);
    }
  const Stats b = Summarise(bare);
  std::printf(
      "config/dense_cones.yaml, epoch 0: %s\n  bare ground: %zu/%d cells, RMS %.4f m, mean %.4f m, "
      "p95 %.4f m\n",
      summary.BriefReport().c_str(), b.n, bare_cells, b.rms, b.mean, b.p95);
  EXPECT_GT(b.n, 0.95 * bare_cells);
  EXPECT_LT(b.rms, 0.16);
  EXPECT_LT(b.p95, 0.21);
}

TEST_F(DenseSimTest, ChangeVolumesMatchTheTrueMovedVolume) {
  ChangeOptions co;
  const ChangeResult ch = SurfaceChange(model0_->model, model1_->model, co);
  // True change over the whole model grid (cell centres of the true meshes).
  const io::GeoRaster& g = ch.change;
  const double area = g.cell_size * g.cell_size;
  double gain = 0, loss = 0, gain_sig = 0, loss_sig = 0;
  for (int r = 0; r < g.height; ++r)
    for (int c = 0; c < g.width; ++c) {
      const Eigen::Vector2d xy = g.CellCentre(r, c);
      const double dz =
          after_->grid.HeightAt(xy.x(), xy.y()) - before_->grid.HeightAt(xy.x(), xy.y());
      (dz > 0 ? gain : loss) += std::abs(dz) * area;
      const float sig = g.At(kSignificant, r, c);
      if (!g.IsNoData(sig) && sig != 0.0f) (dz > 0 ? gain_sig : loss_sig) += std::abs(dz) * area;
    }
  std::printf(
      "change: %s\n  true over the grid: gain %.2f m3, loss %.2f m3, net %.2f m3; over the "
      "significant "
      "cells: gain %.2f m3, loss %.2f m3\n  ratio gain measured/true %.3f, loss %.3f, net(all "
      "cells) %.3f\n",
      ch.summary.BriefReport().c_str(), gain, loss, gain - loss, gain_sig, loss_sig,
      ch.summary.volume_gain / gain, ch.summary.volume_loss / loss,
      ch.summary.volume_net_all / (gain - loss));
  // The body slides down with a plunge steeper than the slope: its surface
  // drops (loss), there is next to no gain.
  ASSERT_GT(loss, 20.0);
  ASSERT_LT(gain, 1.0);
  // The net over all compared cells (no LoD) against the true moved volume:
  // measured -3.4 %.
  EXPECT_NEAR(ch.summary.volume_net_all, gain - loss, 0.05 * (loss - gain));
  // Over the significant cells the measured loss is the true loss of those
  // cells (measured +1.0 %); the thin edges of the body lie under the LoD,
  // so the significant loss is a lower bound of the whole (measured -7.2 %).
  EXPECT_NEAR(ch.summary.volume_loss, loss_sig, 0.03 * loss_sig);
  EXPECT_GT(ch.summary.volume_loss, 0.88 * loss);
  EXPECT_LT(ch.summary.volume_loss, loss);
  EXPECT_LT(ch.summary.volume_gain, 1.5);
  // No significant change far from the body (the tree does not move).
  int false_cells = 0;
  for (const ChangePoint& p : ch.significant) {
    const Eigen::Vector2d d = p.x_in_site.head<2>() - truth_->landslide.centre;
    const double rho = std::hypot(d.x() / (truth_->landslide.width + 2.0),
                                  d.y() / (truth_->landslide.length + 3.0));
    false_cells += rho > 1.0;
  }
  EXPECT_LT(false_cells, 0.01 * ch.summary.cells_compared);
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
