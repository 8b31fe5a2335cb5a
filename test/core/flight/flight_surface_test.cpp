// Change between two flights' DEMs (core/flight/flight_surface.h) on a
// synthetic pair with known truth: a textured slope, the later flight's DEM
// shifted horizontally by a consumer GNSS's metres and raised by a vertical
// bias, 2 cm noise in each DEM, and one known mound on moving ground. The
// co-registration must find the shift within its sigma, leave the stable
// ground unflagged and measure the mound; bad input is refused by name.
// With noise that grows with slope (1 cm on gentle, 10 cm on steep ground,
// the matcher's band 1 cm everywhere) one global LoD flags many steep stable
// cells; the heteroscedastic model (slope x roughness bins) flags about the
// nominal 5 %, on held-out cells too, and still finds the mound.
// Also the GeoTIFF placement in an EPSG CRS and back.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/flight/flight_surface.h"

namespace slope_monitor {
namespace flight {
namespace {

constexpr double kDemCell = 0.5;
constexpr int kDemCells = 160;                // 80 m x 80 m
const Eigen::Vector2d kGnssShift(2.5, -1.8);  // [m] the later flight's GNSS error
constexpr double kVerticalBias = 0.7;         // [m]
constexpr double kDemNoise = 0.02;            // [m] per DEM
constexpr double kDemSigma =
    0.025;  // [m] the DEMs' uncertainty band (conservative, as the matcher's)
const Eigen::Vector2d kMound(55.0, 30.0);  // [m] site
constexpr double kMoundRadius = 6.0, kMoundHeight = 1.0;

double SlopeTerrain(double x, double y) {
  return 0.15 * x + 0.05 * y + 1.5 * std::sin(2 * M_PI * x / 23.0) * std::cos(2 * M_PI * y / 31.0) +
         0.8 * std::sin(2 * M_PI * (x + 0.6 * y) / 13.0);
}

bool InMound(double x, double y) { return (Eigen::Vector2d(x, y) - kMound).norm() < kMoundRadius; }

io::GeoRaster SyntheticDem(bool after, unsigned seed) {
  io::GeoRaster d(kDemCells, kDemCells, 0.0, kDemCells * kDemCell, kDemCell);
  d.AddBand("height");
  d.AddBand("uncertainty");
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, kDemNoise);
  for (int r = 0; r < kDemCells; ++r)
    for (int c = 0; c < kDemCells; ++c) {
      Eigen::Vector2d p = d.CellCentre(r, c);
      double z = 0;
      if (after) {
        p -= kGnssShift;  // the later flight places the ground at x + shift
        z = kVerticalBias + (InMound(p.x(), p.y()) ? kMoundHeight : 0.0);
      }
      d.At(0, r, c) = static_cast<float>(z + SlopeTerrain(p.x(), p.y()) + noise(rng));
      d.At(1, r, c) = static_cast<float>(kDemSigma);
    }
  return d;
}

// Noise that grows with the true slope (gradient g): 1 cm up to g = 0.25
// (14 deg), 10 cm from g = 0.75 (37 deg), linear between; "steep" is g > 0.5.
constexpr double kGentleNoise = 0.01, kSteepNoise = 0.10;                   // [m]
constexpr double kRampStart = 0.25, kRampEnd = 0.75, kSteepGradient = 0.5;  // [m/m]
constexpr double kMatcherBand = 0.01;  // [m] the DEMs' uncertainty band (blind to the slope)

double TrueGradient(double x, double y) {
  const double h = 0.01;
  const Eigen::Vector2d g(SlopeTerrain(x + h, y) - SlopeTerrain(x - h, y),
                          SlopeTerrain(x, y + h) - SlopeTerrain(x, y - h));
  return g.norm() / (2 * h);
}

bool Steep(double x, double y) { return TrueGradient(x, y) > kSteepGradient; }

double NoiseAt(double x, double y) {
  const double t =
      std::clamp((TrueGradient(x, y) - kRampStart) / (kRampEnd - kRampStart), 0.0, 1.0);
  return kGentleNoise + t * (kSteepNoise - kGentleNoise);
}

io::GeoRaster SteepNoisyDem(bool after, unsigned seed) {
  io::GeoRaster d(kDemCells, kDemCells, 0.0, kDemCells * kDemCell, kDemCell);
  d.AddBand("height");
  d.AddBand("uncertainty");
  std::mt19937 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  for (int r = 0; r < kDemCells; ++r)
    for (int c = 0; c < kDemCells; ++c) {
      Eigen::Vector2d p = d.CellCentre(r, c);
      double z = 0;
      if (after) {
        p -= kGnssShift;
        z = kVerticalBias + (InMound(p.x(), p.y()) ? kMoundHeight : 0.0);
      }
      const double noise = NoiseAt(p.x(), p.y());
      d.At(0, r, c) = static_cast<float>(z + SlopeTerrain(p.x(), p.y()) + noise * unit(rng));
      d.At(1, r, c) = static_cast<float>(kMatcherBand);
    }
  return d;
}

dense::Polygon SquareArea(double x0, double y0, double x1, double y1) {
  return {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
}

TEST(CompareFlights, ShiftedFlightIsCoregisteredWithinItsSigmaAndStableGroundIsNotFlagged) {
  const io::GeoRaster ref = SyntheticDem(false, 1), aft = SyntheticDem(true, 2);
  FlightChangeInput in;
  in.reference = &ref;
  in.after = &aft;
  in.moving = {SquareArea(45, 20, 65, 40)};
  const FlightChange c = CompareFlights(in);
  const dense::Coregistration& k = c.summary.dem.coregistration;
  std::printf("%s\n", c.summary.BriefReport().c_str());
  for (int i = 0; i < 2; ++i) {
    EXPECT_GT(k.shift_sigma[i], 0.0);
    EXPECT_LT(k.shift_sigma[i], 0.1);
    EXPECT_LE(std::abs(k.shift[i] - kGnssShift[i]), 3 * k.shift_sigma[i]) << "axis " << i;
  }
  EXPECT_NEAR(k.vertical, kVerticalBias, 3 * k.level_sigma + 0.01);
  EXPECT_LT(std::abs(c.summary.stable_median), 0.01);
  EXPECT_NEAR(c.summary.stable_nmad, std::sqrt(2.0) * kDemNoise, 0.01);
  EXPECT_LE(c.summary.stable_flagged, 0.05);
  // The mound: cells whose centre lies in it, 1 m each (edges blurred by the
  // resampling: within 10 %).
  int mound_cells = 0;
  for (int r = 0; r < kDemCells; ++r)
    for (int col = 0; col < kDemCells; ++col) {
      const Eigen::Vector2d p = ref.CellCentre(r, col);
      mound_cells += InMound(p.x(), p.y());
    }
  const double truth = mound_cells * kDemCell * kDemCell * kMoundHeight;
  EXPECT_NEAR(c.summary.dem.volume_fill, truth, 0.1 * truth);
  EXPECT_LT(c.summary.dem.volume_cut, 0.05 * truth);
  EXPECT_EQ(c.result.change.band_names, (std::vector<std::string>{"change", "lod", "class"}));
}

int MoundCells(const io::GeoRaster& grid) {
  int n = 0;
  for (int r = 0; r < kDemCells; ++r)
    for (int col = 0; col < kDemCells; ++col) {
      const Eigen::Vector2d p = grid.CellCentre(r, col);
      n += InMound(p.x(), p.y());
    }
  return n;
}

TEST(CompareFlights, NoiseGrowingWithSlopeIsFlaggedAtTheNominalRateByTheErrorModel) {
  const io::GeoRaster ref = SteepNoisyDem(false, 11), aft = SteepNoisyDem(true, 12);
  FlightChangeInput in;
  in.reference = &ref;
  in.after = &aft;
  const dense::Polygon moving = SquareArea(45, 20, 65, 40);
  in.moving = {moving};
  // Share of the stable (outside `moving`) compared cells flagged, all and steep.
  auto flagged = [&](const FlightChange& c, double* steep_share) {
    int n = 0, f = 0, ns = 0, fs = 0;
    for (int r = 0; r < kDemCells; ++r)
      for (int col = 0; col < kDemCells; ++col) {
        const Eigen::Vector2d p = ref.CellCentre(r, col);
        if (p.x() >= 44 && p.x() <= 66 && p.y() >= 19 && p.y() <= 41) continue;
        const float v = c.result.change.At(dense::kChange, r, col);
        if (c.result.change.IsNoData(v)) continue;
        const bool flag = c.result.change.At(dense::kClass, r, col) != 0.0f;
        ++n, f += flag;
        if (Steep(p.x(), p.y())) ++ns, fs += flag;
      }
    EXPECT_GT(ns, n / 10) << "too few steep cells for the test";
    *steep_share = static_cast<double>(fs) / std::max(ns, 1);
    return static_cast<double>(f) / std::max(n, 1);
  };
  FlightChangeOptions global;
  global.change.error_model.enabled = false;
  const FlightChange g = CompareFlights(in, global);
  double g_steep = 0;
  const double g_all = flagged(g, &g_steep);
  std::printf("global LoD: stable flagged %.3f, steep stable flagged %.3f\n", g_all, g_steep);
  EXPECT_GT(g_steep, 0.15);  // one LoD for all: the steep ground's noise passes it

  // The literature's NMAD per bin: most of the excess gone (the bins still
  // mix noise levels: heavier tails than one Gaussian).
  FlightChangeOptions nmad;
  nmad.change.error_model.spread = dense::ErrorModelOptions::Spread::kNmad;
  const FlightChange n = CompareFlights(in, nmad);
  double n_steep = 0;
  const double n_all = flagged(n, &n_steep);
  std::printf("NMAD bins: stable flagged %.3f, steep stable flagged %.3f, held-out %.3f\n", n_all,
              n_steep, n.summary.dem.holdout_flagged);
  EXPECT_LT(n_steep, g_steep / 3);

  const FlightChange h = CompareFlights(in);  // quantile bins
  double h_steep = 0;
  const double h_all = flagged(h, &h_steep);
  const dense::DemChangeSummary& d = h.summary.dem;
  std::printf(
      "error model: stable flagged %.3f, steep stable flagged %.3f, held-out %.3f of %d "
      "(block %.1f m); %s\n",
      h_all, h_steep, d.holdout_flagged, d.holdout_cells, d.holdout_block,
      h.summary.BriefReport().c_str());
  for (const dense::ErrorBin& b : d.error_model.bins)
    std::printf("  slope %.1f..%.1f deg, roughness %.3f..%.3f m: %d cells, sigma %.4f m\n",
                b.slope_min, b.slope_max, b.roughness_min, b.roughness_max, b.cells, b.sigma);
  ASSERT_FALSE(d.error_model.empty());
  // 95 % LoD: about 5 % of unchanged cells pass it, gentle or steep, held out or not.
  EXPECT_LE(h_steep, 0.07);
  EXPECT_LE(h_all, 0.07);
  EXPECT_LE(d.holdout_flagged, 0.07);
  EXPECT_GT(d.holdout_cells, kDemCells * kDemCells / 2);
  EXPECT_LT(std::abs(h.summary.stable_median), 0.01);
  // The model's sigma of the difference follows the noise: sqrt(2) x 1 cm on
  // the gentlest bins, several cm on the steepest (the resampling of the
  // after DEM averages part of its noise).
  EXPECT_LT(d.error_model.bins.front().sigma, 0.025);
  EXPECT_GT(d.error_model.bins.back().sigma, 0.07);
  const double truth = MoundCells(ref) * kDemCell * kDemCell * kMoundHeight;
  EXPECT_NEAR(d.volume_fill, truth, 0.1 * truth);
  EXPECT_LT(d.volume_cut, 0.05 * truth);
}

TEST(CompareFlights, StablePolygonIsTheOnlyStableGround) {
  const io::GeoRaster ref = SyntheticDem(false, 3), aft = SyntheticDem(true, 4);
  FlightChangeInput in;
  in.reference = &ref;
  in.after = &aft;
  in.stable = {SquareArea(2, 2, 40, 78)};
  const FlightChange c = CompareFlights(in);
  SCOPED_TRACE(c.summary.BriefReport());
  // Cells in the polygon, the shifted edge trimmed: about 76 x 152.
  EXPECT_NEAR(c.summary.stable_common, 76 * 152, 76 * 4);
  EXPECT_LT((c.summary.dem.coregistration.shift - kGnssShift).norm(), 0.1);
  EXPECT_LE(c.summary.stable_flagged, 0.05);
}

void ExpectRefused(const FlightChangeInput& in, const std::string& words) {
  try {
    CompareFlights(in);
    ADD_FAILURE() << "not refused: " << words;
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("nothing compared"), std::string::npos) << e.what();
  }
}

TEST(CompareFlights, BadInputIsNamedAndNothingIsComputed) {
  const io::GeoRaster ref = SyntheticDem(false, 5);
  io::GeoRaster aft = SyntheticDem(true, 6);
  FlightChangeInput in;
  in.reference = &ref;
  in.after = &aft;
  in.stable_name = "site.yaml: areas.stable";
  // No overlap: the later flight covers only the western half, the reference the eastern.
  io::GeoRaster west = aft, east = ref;
  for (int r = 0; r < kDemCells; ++r)
    for (int c = 0; c < kDemCells; ++c) (c < kDemCells / 2 ? east : west).At(0, r, c) = NAN;
  FlightChangeInput disjoint = in;
  disjoint.reference = &east;
  disjoint.after = &west;
  ExpectRefused(disjoint, "no overlap with the reference: 0 cells");
  // A stable area outside the surface.
  in.stable = {SquareArea(200, 200, 240, 240)};
  ExpectRefused(in, "site.yaml: areas.stable lies outside the surface");
  // Holes over the stable area: the later flight has no height there.
  in.stable = {SquareArea(2, 2, 20, 20)};
  for (int r = 0; r < kDemCells; ++r)
    for (int c = 0; c < kDemCells; ++c) {
      const Eigen::Vector2d p = aft.CellCentre(r, c);
      if (p.x() < 21 && p.y() < 21) aft.At(0, r, c) = NAN;
    }
  ExpectRefused(in, "holes over the stable area: 0 of");
  // Different grids.
  io::GeoRaster other = SyntheticDem(true, 7);
  other.origin_x += 0.25;
  in.after = &other;
  in.stable.clear();
  EXPECT_THROW(CompareFlights(in), InvalidArgument);
}

TEST(FlightSurfaceFiles, DemIsPlacedInItsEpsgCrsAndReadBack) {
  FlightFrame frame;
  frame.crs = "EPSG:32611";
  frame.origin = Eigen::Vector3d(235200.0, 3811200.0, 10.0);
  const io::GeoRaster dem = SyntheticDem(false, 8);
  const std::string path =
      (std::filesystem::temp_directory_path() / "flight_surface_test_dem.tif").string();
  io::WriteGeoTiff(path, InCrs(dem, frame));
  const io::GeoRaster back = io::ReadGeoTiff(path);
  std::filesystem::remove(path);
  EXPECT_EQ(back.epsg, 32611);
  EXPECT_DOUBLE_EQ(back.origin_x, 235200.0);
  EXPECT_DOUBLE_EQ(back.origin_y, 3811200.0 + kDemCells * kDemCell);
  EXPECT_NEAR(back.At(0, 10, 10), dem.At(0, 10, 10) + 10.0, 1e-3);  // heights in the CRS
  const io::GeoRaster site = InSite(back, frame, "ref/surface_e01.tif");
  EXPECT_DOUBLE_EQ(site.origin_x, 0.0);
  EXPECT_NEAR(site.At(0, 10, 10), dem.At(0, 10, 10), 1e-5);
  FlightFrame other = frame;
  other.crs = "EPSG:32612";
  try {
    InSite(back, other, "ref/surface_e01.tif");
    ADD_FAILURE() << "another zone accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("ref/surface_e01.tif: its CRS (EPSG:32611)"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace flight
}  // namespace slope_monitor
