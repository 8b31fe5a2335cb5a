// One dense surface per survey epoch: every usable image pair of the epoch,
// with the orientations the bundle adjuster solved, is measured
// (dense/surface.h: rectify, coarse-to-fine LoG correlation, intersection)
// and all pairs' points are merged into one DEM on a fixed grid.
//
//   dense::EpochSurfaceInput in;           // epoch, images (adjusted poses), stereo pairs,
//   adjusted points dense::EpochSurfaceOptions options;    // surface options, overlap, region,
//   memory limit dense::EpochSurfaceResult r = dense::MeasureEpochSurface(in, options);
//   io::WriteGeoTiff(dir + "/surface_e03.tif", r.dem);   // EpochSurfaceFileName(3)
//
// Pairs: UAV images (kind kUav) pair with each other when the share of the
// left image's ground footprint that the right image also sees is at least
// min_pair_overlap (60 %); fixed cameras pair only as configured in
// `stereo_pairs`. A pair that fails (not overlapping, no texture, ...) is
// named in Summary::pair_errors and skipped; the epoch's other pairs are kept.
//
// Where the ground is comes from the adjustment, not from a guess: the
// adjusted points (targets, tie points) fit a plane z = a + b x + c y (least
// squares); footprints are intersected with it, and each pair's depth range is
// the range of the adjusted points' depths in the left camera, widened by
// depth_margin (a share) on both sides. With fewer than 3 adjusted points the
// plane is horizontal at their mean (one or two points) and, with none, the
// pair is rejected ("no adjusted points").
//
// Memory: the DEM needs (bands * 4 + 28) bytes per cell while it is gridded;
// a grid that would need more than max_dem_megabytes is refused with an
// InvalidArgument naming cell_size, the grid size and the limit, before
// anything is measured.
#pragma once

#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/dense/surface.h"

namespace slope_monitor {
namespace dense {

enum class ImageKind { kUav, kFixed };

struct EpochImage {
  OrientedImage image;  // adjusted orientation; image may be BGR (colour of the cloud) or grey
  ImageKind kind = ImageKind::kUav;
  std::string camera;  // camera name (stereo pairs refer to it)
};

struct EpochSurfaceInput {
  int epoch = 0;
  std::vector<EpochImage> images;
  std::vector<std::pair<std::string, std::string>>
      stereo_pairs;                              // fixed-camera pairs (left, right camera)
  std::vector<Eigen::Vector3d> adjusted_points;  // [m] site, from the adjustment
};

struct EpochSurfaceOptions {
  SurfaceOptions surface;            // per-pair measurement (cell_size is the DEM cell)
  double min_pair_overlap = 0.6;     // [-] UAV pairs: shared footprint share; (0, 1]
  double depth_margin = 0.3;         // [-] depth range widened by this share on both sides; [0, 10]
  int max_pairs_per_image = 2;       // [-] UAV: best-overlapping partners kept per image; [1, 100]
  double max_dem_megabytes = 256.0;  // [MB] memory limit of one epoch's DEM; (0, 1e5]
  // DEM extent in site [m]: xmin, xmax, ymin, ymax (all zero: bounding box of the points).
  Eigen::Vector4d region = Eigen::Vector4d::Zero();
  void Check() const;  // ConfigError naming the field
};

struct EpochPoint {
  Eigen::Vector3d x_in_site;  // [m]
  float sigma_z = 0.0f;       // [m]
  cv::Vec3b bgr{0, 0, 0};     // colour from the pair's left photo
};

struct EpochSurfaceSummary {
  int epoch = 0;
  int candidate_pairs = 0;  // pairs considered (overlap checked)
  int pairs_measured = 0;
  std::vector<std::string> pair_errors;  // one line per rejected or failed pair, naming both images
  int points = 0;
  int cells = 0, filled_cells = 0;
  double seconds = 0.0;
  bool IsSolutionUsable() const { return filled_cells > 0; }
  std::string BriefReport() const;
};

struct EpochSurfaceResult {
  io::GeoRaster dem;  // bands as SurfaceResult::model (height, uncertainty, count, spread)
  std::vector<EpochPoint> points;
  EpochSurfaceSummary summary;
};

// Share of `left`'s footprint on the plane z = plane[0] + plane[1] x +
// plane[2] y that `right` also sees (a 16 x 12 grid of left pixels).
double FootprintOverlap(const OrientedImage& left, const OrientedImage& right,
                        const Eigen::Vector3d& plane);

// Least-squares plane (a, b, c) of z = a + b x + c y through the points (see
// the file comment for fewer than 3 points). Throws InvalidArgument when empty.
Eigen::Vector3d GroundPlane(const std::vector<Eigen::Vector3d>& points);

// The pairs to measure (indices into input.images, left first), and why
// others were not taken (appended to `rejected`).
std::vector<std::pair<int, int>> ChoosePairs(const EpochSurfaceInput& input,
                                             const EpochSurfaceOptions& options,
                                             const Eigen::Vector3d& plane,
                                             std::vector<std::string>* rejected);

// Throws ConfigError for bad options, InvalidArgument when the DEM would
// exceed the memory limit or no pair could be measured (the message lists
// each pair's reason).
EpochSurfaceResult MeasureEpochSurface(
    const EpochSurfaceInput& input, const EpochSurfaceOptions& options,
    const std::function<void(const std::string&)>& progress = {});

// The region (xmin, xmax, ymin, ymax) a DEM covers: later epochs use the
// reference epoch's grid so their DEMs can be differenced.
Eigen::Vector4d RegionOf(const io::GeoRaster& dem);

// The per-epoch files: `<stem>_e<epoch, two digits>.<extension>`, e.g.
// ("surface_report", 3, "json") -> "surface_report_e03.json"; then
// "surface_e03.tif", "change_e03.tif", "ortho_e03.tif", "cloud_e03.ply".
std::string EpochFileName(const char* stem, int epoch, const char* extension);
std::string EpochSurfaceFileName(int epoch);
std::string EpochChangeFileName(int epoch);
std::string EpochOrthoFileName(int epoch);
std::string EpochCloudFileName(int epoch);

}  // namespace dense
}  // namespace slope_monitor
