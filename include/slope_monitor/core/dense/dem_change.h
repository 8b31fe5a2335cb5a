// DEM of difference (DoD) of an epoch against the reference epoch, with
// co-registration on stable terrain and a per-cell level of detection. The
// error model is written out in doc/dense_change.md; in short:
//
// 1. Stable cells: outside every monitored outline (site polygons) and, when
//    an operator mask is given (one byte per cell, same grid), where it is
//    non-zero.
// 2. Co-registration (Nuth-Kaab-style, linearised): on stable cells
//      z_after(x) - z_ref(x) = -grad z_ref(x) . s + a + b (x - xc) + c (y - yc)
//    for the horizontal shift s (ridge-damped, so a shift the terrain cannot
//    reveal stays 0), the vertical shift a and the tilt (b, c), solved by
//    least squares with 3-sigma (MAD) clipping, repeated with the after DEM
//    resampled at x + s and the plane removed. The residual (robust RMS of
//    the stable cells after co-registration) is reported.
// 3. Per cell: dz = z_after' - z_ref and
//      sigma_dz^2 = u_ref^2 + u_after^2 + sigma_extra^2
//    (u: the DEMs' matching uncertainty band, sigma_extra^2 = the stable
//    residual variance that the matching uncertainty does not explain), the
//    level of detection LoD = lod_factor * sigma_dz, and the class
//    +-1 (|dz| > LoD) or +-2 (|dz| > 2 LoD), 0 otherwise.
//    With error_model.enabled (heteroscedastic, after Hugonnet et al. 2022)
//    sigma_extra is replaced by a per-cell sigma: the stable cells' dz binned
//    by the reference's slope and, within each slope bin, by its roughness
//    (RMS of the heights about their local plane), the spread of each bin
//    (NMAD, or the LoD's quantile of |dz - median| / lod_factor), linearly
//    interpolated between the bins' median predictors (clamped outside):
//      sigma_dz = max(model(slope, roughness), sqrt(u_ref^2 + u_after^2)).
//    Held-out check: the stable cells split in a checkerboard of blocks
//    larger than the error correlation range; a model fitted on one colour
//    flags the other colour's cells, both ways; the share is reported.
// 4. Volumes inside the outlines (no outline: the whole DEM): net over every compared cell; fill
// and cut
//    over the significant cells. Their 1-sigma uncertainty adds a random part,
//    correlated with an exponential covariance of range L (estimated from the
//    stable residuals' autocorrelation): var = sum(sigma_dz^2 a^2) * min(n,
//    2 pi L^2 / a), and a systematic part, the co-registration's mean level
//    uncertainty fully correlated over the area: (sigma_level * A)^2.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/io/geotiff.h"

namespace slope_monitor {
namespace dense {

using Polygon = std::vector<Eigen::Vector2d>;  // site x, y [m], closed implicitly

// The heteroscedastic error model of the DoD (see the file comment).
struct ErrorModelOptions {
  bool enabled = false;      // false: one stable residual (sigma_extra) for every cell
  int slope_bins = 8;        // [-] equal-count bins of the reference's slope; [1, 50]
  int roughness_bins = 3;    // [-] equal-count bins of roughness within each slope bin; [1, 50]
  int roughness_radius = 2;  // [cells] roughness window (2 r + 1)^2; [1, 20]
  int min_bin_cells = 50;    // [-] fewer stable cells per bin: fewer bins; [5, 1e9]
  // Spread of a bin: kNmad (the literature's) or kQuantile (the LoD's
  // two-sided coverage quantile of |dz - median| over lod_factor: holds the
  // flagged share at the nominal rate when the errors have heavy tails).
  enum class Spread { kNmad, kQuantile };
  Spread spread = Spread::kNmad;
  double holdout_block = 0.0;  // [m] held-out checkerboard block; 0: 4 x the correlation
                               // range, at least 8 cells; >= 0
  void Check() const;          // ConfigError naming the field
};

struct DemChangeOptions {
  double lod_factor = 1.96;  // [-] LoD = lod_factor * sigma_dz; (0, 10]
  int coregistration_iterations =
      4;                      // [-] resample-and-refit passes; [0, 20] (0: no co-registration)
  double clip_sigmas = 3.0;   // [-] stable outliers beyond this many robust sigmas; [1, 10]
  double max_shift = 5.0;     // [m] larger horizontal shift: co-registration failed; > 0
  int min_stable_cells = 30;  // [-] fewer: co-registration refused; [4, 1e9]
  double max_correlation_length = 20.0;  // [m] cap of the estimated error correlation range; > 0
  ErrorModelOptions error_model;
  void Check() const;  // ConfigError naming the field
};

// One bin of the error model: its predictors' range and median, its stable
// cells and their dz's median and spread.
struct ErrorBin {
  double slope_min = 0, slope_max = 0, slope = 0;              // [deg] the bin's median
  double roughness_min = 0, roughness_max = 0, roughness = 0;  // [m]
  int cells = 0;
  double median = 0;  // [m] dz
  double sigma = 0;   // [m] the spread (ErrorModelOptions::spread)
};

struct ErrorModel {
  std::vector<ErrorBin> bins;  // slope-major: slope_bins x roughness_bins
  int slope_bins = 0, roughness_bins = 0;
  bool empty() const { return bins.empty(); }
  double Sigma(double slope_deg, double roughness) const;  // [m] interpolated
};

struct Coregistration {
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();  // [m] s: the after DEM is read at x + s
  // [m] 1 sigma of s: the final residual's variance times the normal matrix's
  // inverse (no ridge), inflated by the cells one correlation range holds;
  // infinite where the stable terrain's slopes cannot reveal the shift.
  Eigen::Vector2d shift_sigma = Eigen::Vector2d::Zero();
  double vertical = 0.0;                             // [m] a (at the centre)
  Eigen::Vector2d tilt = Eigen::Vector2d::Zero();    // [m/m] b, c
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();  // [m] xc, yc
  int stable_cells = 0;                              // stable cells with a height in both DEMs
  int inliers = 0;                                   // after clipping
  double residual_before = 0.0;     // [m] robust RMS of stable dz before co-registration
  double residual = 0.0;            // [m] robust RMS after
  double level_sigma = 0.0;         // [m] 1-sigma uncertainty of the mean level (systematic)
  double correlation_length = 0.0;  // [m] L of the residuals
};

struct DemChangeSummary {
  Coregistration coregistration;
  int cells_compared = 0;  // inside or outside the outlines
  int cells_missing = 0;
  int cells_inside = 0;          // compared cells inside the outlines
  int cells_significant = 0;     // |class| >= 1 inside the outlines
  double sigma_extra = 0.0;      // [m] unexplained stable residual
  ErrorModel error_model;        // empty unless options.error_model.enabled
  int holdout_cells = 0;         // stable cells of the two-fold held-out check
  double holdout_flagged = 0.0;  // [-] their share flagged by the other fold's model
  double holdout_block = 0.0;    // [m] checkerboard block
  double volume_net = 0.0;       // [m^3] inside, all compared cells
  double volume_fill = 0.0;      // [m^3] inside, significant gain
  double volume_cut = 0.0;       // [m^3] inside, significant loss (positive)
  double sigma_net = 0.0, sigma_fill = 0.0, sigma_cut = 0.0;  // [m^3] 1 sigma
  std::string BriefReport() const;
};

struct DemChangeResult {
  io::GeoRaster change;              // bands "change", "lod", "class" (-2..2)
  io::GeoRaster after_coregistered;  // the after DEM on the reference grid, co-registered (height,
                                     // uncertainty)
  DemChangeSummary summary;
};

enum DemChangeBand : int { kChange = 0, kLodBand = 1, kClass = 2 };

// Stable-cell mask of a grid: 1 outside every outline and where `mask` (empty:
// everywhere) is non-zero. Throws InvalidArgument naming `mask_name` when the
// mask's size differs from the grid.
std::vector<uint8_t> StableMask(const io::GeoRaster& grid, const std::vector<Polygon>& outlines,
                                const std::vector<uint8_t>& mask, const std::string& mask_name);

// Co-registers `after` to `reference` (same grid) on the stable cells.
// Throws InvalidArgument when the grids differ or too few stable cells remain.
Coregistration Coregister(const io::GeoRaster& reference, const io::GeoRaster& after,
                          const std::vector<uint8_t>& stable, const DemChangeOptions& options);

// The DoD (see the file comment). Throws what Coregister throws.
DemChangeResult DemChange(const io::GeoRaster& reference, const io::GeoRaster& after,
                          const std::vector<Polygon>& outlines, const std::vector<uint8_t>& stable,
                          const DemChangeOptions& options);

}  // namespace dense
}  // namespace slope_monitor
