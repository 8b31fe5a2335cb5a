// Dense surface measurement of an oriented image pair: rectification,
// coarse-to-fine LoG correlation, forward intersection of every valid
// parallax to a site point, and gridding to a regular surface model.
//
//   dense::SurfaceOptions options;                 // cell size, correlation, ...
//   dense::SurfaceConfig config{min_depth, max_depth, region};
//   dense::SurfaceSummary summary;
//   dense::SurfaceResult s = dense::MeasureSurface(left, right, options, config, &summary);
//   io::WriteGeoTiff("dem.tif", s.model);          // bands: height, uncertainty, count, spread
//   io::WriteGeoTiff("ortho.tif", dense::MakeOrthophoto(s.model, left, options.ortho_cell_size));
//
// Gridding (weighted mean): each intersected point p with height z_p and a
// height standard deviation sigma_p (propagated from the parallax standard
// deviation, see below) falls in one cell; the cell height is
//     z = sum(w_p z_p) / sum(w_p),  w_p = 1 / sigma_p^2
// the spread is the weighted standard deviation of the z_p about z, and the
// per-cell uncertainty (1 sigma, metres) is
//     u = sqrt(n / n_eff / sum(w_p) + spread^2 / n_eff),  n_eff = max(1, n / m)
// (measurement noise of the mean plus the height variation inside the cell
// as a standard error), where m = (window / final_grid_spacing)^2 is the
// number of grid points that share one correlation window: neighbouring
// parallaxes are not independent, so only about n / m of the n points of a
// cell count (with plain 1 / sqrt(n) the level of detection of a change came
// out far too small on the simulator). Cells with fewer than min_points_per_cell points are
// holes: nodata in every band except count. Holes are never filled.
//
// sigma_p: a parallax error sigma_d [px] moves the point along the left ray
// by sigma_r = sigma_d * Z^2 / (f B) (depth Z, focal f px, baseline B); its
// height component is taken as sigma_r * |ray_z| plus the plan error times
// the local slope, approximated as sigma_r (the conservative choice).
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/dense/correlation.h"
#include "slope_monitor/core/dense/rectify.h"
#include "slope_monitor/core/io/geotiff.h"

namespace slope_monitor {

class SiteCrs;  // core/common/site_crs.h

namespace dense {

struct SurfaceOptions {
  CorrelationOptions correlation;
  RectifyOptions rectify;
  double cell_size = 0.5;        // [m] surface model cell; (0, 100]
  int min_points_per_cell = 1;   // [-] fewer points: hole; [1, 1000]
  double parallax_sigma = 0.15;  // [px] a-priori parallax standard deviation; (0, 10]
  double max_ray_gap = 0.0;  // [m] reject intersections whose rays miss by more; 0: 10 x cell_size
  double ortho_cell_size = 0.0;  // [m] orthophoto cell; 0: cell_size
  void Check() const;            // throws ConfigError naming the field
};

// What is fixed for one measurement: where the surface can be.
struct SurfaceConfig {
  double min_depth = 0.0;  // [m] nearest surface distance from the cameras, > 0
  double max_depth = 0.0;  // [m] farthest, > min_depth
  // Site region of the surface model [m]: xmin, xmax, ymin, ymax. All zero:
  // the bounding box of the intersected points, snapped to cell_size.
  Eigen::Vector4d region = Eigen::Vector4d::Zero();
};

struct SurfacePoint {
  Eigen::Vector3d x_in_site;  // [m]
  float sigma_z = 0.0f;       // [m]
  float correlation = 0.0f;   // [-] ZNCC
  float intensity = 0.0f;     // [0, 255] left image grey value
};

struct SurfaceSummary {
  CorrelationSummary correlation;
  int patches = 0;
  int points = 0;                  // intersected points
  int rejected_points = 0;         // rays that do not meet / behind / outside the region
  int cells = 0;                   // surface model cells
  int filled_cells = 0;            // cells with a height
  double rectified_overlap = 0.0;  // [-]
  double seconds = 0.0;
  bool IsSolutionUsable() const { return filled_cells > 0; }
  std::string BriefReport() const;
};

struct SurfaceResult {
  io::GeoRaster model;               // bands "height", "uncertainty", "count", "spread"
  std::vector<SurfacePoint> points;  // every intersected point (for the point cloud)
  RectifiedGeometry geometry;
};

// Band indices of a surface model made here.
enum SurfaceBand : int { kHeight = 0, kUncertainty = 1, kCount = 2, kSpread = 3 };

// The whole chain. Throws InvalidArgument for a bad pair (see Rectify), for
// images without texture (see MatchRectified), and when no point could be
// measured; ConfigError for bad options.
SurfaceResult MeasureSurface(const OrientedImage& left, const OrientedImage& right,
                             const SurfaceOptions& options, const SurfaceConfig& config,
                             SurfaceSummary* summary = nullptr);

// Measures the pair (MeasureSurface) and writes <stem>_surface.tif (bands
// above) and <stem>_ortho.tif (MakeOrthophoto of the left image,
// options.ortho_cell_size). Nothing is written unless the measurement and the
// orthophoto succeeded; each file goes to a temporary name and is renamed
// (io::WriteGeoTiff), and when the second file cannot be written the first is
// removed again, so a failure never leaves a file that looks valid. Throws
// what MeasureSurface throws, and IoError naming the file. With a site CRS
// both files are written in its map CRS (io::MapRasterFromSite: an EPSG
// code; a local_enu site's resampled onto a north-up UTM grid), else in the
// local CRS `site`; the returned model is in `site` either way.
SurfaceResult MeasureSurfaceToFiles(const OrientedImage& left, const OrientedImage& right,
                                    const SurfaceOptions& options, const SurfaceConfig& config,
                                    const std::string& stem, SurfaceSummary* summary = nullptr,
                                    const SiteCrs* site = nullptr);

// Grids points into a surface model (weighted mean, see the file comment).
// points_per_window: m above (1: every point independent).
io::GeoRaster GridSurface(const std::vector<SurfacePoint>& points, double cell_size,
                          int min_points_per_cell, const Eigen::Vector4d& region,
                          double points_per_window = 1.0);

// Orthophoto of `image` on the surface model: each cell of the ortho grid
// (cell_size, same extent) takes its height from the model (bilinear between
// cell centres), is projected into the image with its camera model and takes
// the bilinear grey value. Band "gray"; nodata where the model has no height
// or the point is outside the image.
io::GeoRaster MakeOrthophoto(const io::GeoRaster& model, const OrientedImage& image,
                             double cell_size);

}  // namespace dense
}  // namespace slope_monitor
