// Surface change between two epochs' surface models (cut and fill).
//
// Both models must share the grid (origin, cell size, size; as made with the
// same SurfaceConfig::region and cell size). Per cell with a height in both:
//   dz  = z_after - z_before                                   [m]
//   LoD = k * sqrt(u_before^2 + u_after^2)                     [m]
// (u: the per-cell uncertainty band, k = lod_factor, 1.96 for 95 %). A cell is
// significant when |dz| > LoD. Over significant cells
//   gain = sum(dz > 0) dz * cell^2,   loss = sum(dz < 0) -dz * cell^2     [m^3]
// (the LoD drops the part of a change that is below it, e.g. the thin
// edges of a debris fan, so gain and loss are lower bounds; volume_net_all
// sums every compared cell without the LoD) with 1-sigma uncertainties sqrt(sum u_dz^2) * cell^2
// (cells independent, u_dz = sqrt(u_before^2 + u_after^2)), and net = gain - loss. Cells missing in
// either model are holes of the change raster and are counted, never filled.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/io/geotiff.h"

namespace slope_monitor {
namespace dense {

struct ChangeOptions {
  double lod_factor = 1.96;  // [-] k of the level of detection; [0, 10]
  double min_lod = 0.0;      // [m] floor of the LoD (e.g. known systematic error); >= 0
  void Check() const;        // ConfigError naming the field
};

struct ChangeSummary {
  int cells_compared = 0;    // cells with a height in both models
  int cells_missing = 0;     // cells without a height in one or both
  int cells_gain = 0;        // significant positive
  int cells_loss = 0;        // significant negative
  double volume_gain = 0.0;  // [m^3]
  double volume_loss = 0.0;  // [m^3] (positive number)
  double volume_net = 0.0;   // [m^3] gain - loss (significant cells)
  double volume_net_all =
      0.0;  // [m^3] sum of dz * cell^2 over ALL compared cells (no LoD: unbiased net)
  double sigma_gain = 0.0;  // [m^3] 1 sigma
  double sigma_loss = 0.0;  // [m^3] 1 sigma
  bool IsSolutionUsable() const { return cells_compared > 0; }
  std::string BriefReport() const;
};

struct ChangePoint {
  Eigen::Vector3d x_in_site;  // cell centre at the after-epoch height [m]
  float dz = 0.0f;            // [m]
  float lod = 0.0f;           // [m]
};

struct ChangeResult {
  io::GeoRaster change;  // bands "dz", "lod", "significant" (1 gain, -1 loss, 0 not significant)
  std::vector<ChangePoint> significant;  // the change cloud (significant cells only)
  ChangeSummary summary;
};

enum ChangeBand : int { kDz = 0, kLod = 1, kSignificant = 2 };

// Throws InvalidArgument when the grids differ or a model lacks the height
// or uncertainty band (named by band description "height" / "uncertainty",
// else bands 0 / 1).
ChangeResult SurfaceChange(const io::GeoRaster& before, const io::GeoRaster& after,
                           const ChangeOptions& options);

}  // namespace dense
}  // namespace slope_monitor
