// Change between two flights' DEMs (core/flight/flight_surface.h) on a
// synthetic pair with known truth: a textured slope, the later flight's DEM
// shifted horizontally by a consumer GNSS's metres and raised by a vertical
// bias, 2 cm noise in each DEM, and one known mound on moving ground. The
// co-registration must find the shift within its sigma, leave the stable
// ground unflagged and measure the mound; bad input is refused by name.
// Also the GeoTIFF placement in an EPSG CRS and back.
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
