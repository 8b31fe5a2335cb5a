// The surface of an oriented real flight and its change against an earlier
// flight, with no ROS in it (process_flight wires it; doc/real_surfaces.md).
//
//   flight::FlightSurface s = flight::MeasureFlightSurface(photos, result, options);
//   io::WriteGeoTiff(dir + "/surface_e01.tif", flight::InCrs(s.dem, frame));
//   flight::FlightChange c = flight::CompareFlights({&reference_dem, &s.dem, stable, moving});
//
// Surface: every oriented photo is decoded once at a reduced working
// resolution (JPEG DCT scaling by 1/2, 1/4 or 1/8: the longer side at most
// working_size px), its camera model scaled to match (same interior in mm,
// pixel pitch times the factor). The photos then go through the simulator's
// dense chain unchanged (dense/epoch_surface.h: pairs by footprint overlap,
// epipolar rectification, coarse-to-fine LoG correlation both ways,
// intersection with a height sigma per point, one DEM on a fixed grid).
// Memory is bounded by the working resolution: the photos held are
// photos x working_size^2 x 3 bytes x 2/3, the points ~90 bytes each.
//
// DEM cell: cell_size, or (0) the working photos' median ground sample
// distance times the correlation's final node spacing, rounded up to the
// next centimetre: about one correlation node per cell and pair. Region:
// the oriented tie points' extent (0.5 .. 99.5 percentile, so a stray tie
// point does not blow up the grid), or the given one (a later flight takes
// the reference's grid).
//
// Orthophoto, cloud file and change (CompareFlights) are
// core/dense/surface_products.h's, which the graph's dense step calls too:
// ColourOrthophoto of the decoded photos on the DEM,
// WriteCloudPly, and dense::CompareSurfaces with a real flight's options
// (FlightChangeOptions: more co-registration passes, an 8 m shift search,
// the heteroscedastic LoD). The flight names below are those functions.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/dense/surface_products.h"
#include "slope_monitor/core/flight/flight_export.h"
#include "slope_monitor/core/flight/flight_orientation.h"
#include "slope_monitor/core/flight/flight_photos.h"

namespace slope_monitor {
namespace flight {

struct FlightSurfaceOptions {
  int working_size = 1100;  // [px] longer side of the decoded photos at most this; [100, 100000]
  double cell_size =
      0.0;  // [m] DEM cell; 0: final node spacing x median ground sample distance; >= 0
  int ortho_subdivision = 4;         // [-] orthophoto cells per DEM cell side; [1, 16]
  double max_dem_megabytes = 512.0;  // [MB] DEM grid limit (refused before matching); > 0
  // The dense chain (dense/epoch_surface.h). Its surface.cell_size and region
  // are set here (cell_size above, the region of the call).
  dense::EpochSurfaceOptions dense = [] {
    dense::EpochSurfaceOptions o;
    o.min_pair_overlap = 0.5;
    o.max_pairs_per_image = 2;
    o.surface.correlation.final_grid_spacing = 4;
    o.surface.min_points_per_cell = 2;
    return o;
  }();
  void Check() const;  // ConfigError naming the field
};

struct FlightSurfaceSummary {
  int photos = 0;                             // oriented photos used
  int decode_factor = 1;                      // photos decoded at 1 / this
  int working_width = 0, working_height = 0;  // [px]
  double ground_sample = 0.0;                 // [m] median, working resolution
  double cell_size = 0.0;                     // [m] DEM
  dense::EpochSurfaceSummary dense;
  std::map<std::string, double> seconds;  // "decode", "matching", "ortho"
  std::string BriefReport() const;
};

struct FlightSurface {
  io::GeoRaster dem;                     // site frame; bands height, uncertainty, count, spread
  io::GeoRaster ortho;                   // site frame; bands red, green, blue [0, 255]
  std::vector<dense::EpochPoint> cloud;  // site frame, sigma_z and colour per point
  FlightSurfaceSummary summary;
};

// The region (xmin, xmax, ymin, ymax) [m] of the DEM a flight gets without
// one given: its tie points' 0.5 .. 99.5 percentile extent snapped out to
// `cell`. Throws InvalidArgument when the block has fewer than 3 points.
Eigen::Vector4d TiePointRegion(const FlightResult& result, double cell);

// Measures the surface of an oriented flight. `region` all zero: the tie
// point region. Throws ConfigError for bad options and InvalidArgument when
// the block has no oriented photos, no pair can be measured (the message
// lists each pair's reason) or the grid exceeds max_dem_megabytes.
FlightSurface MeasureFlightSurface(const FlightPhotos& photos, const FlightResult& result,
                                   const FlightSurfaceOptions& options,
                                   const Eigen::Vector4d& region = Eigen::Vector4d::Zero(),
                                   const std::function<void(const std::string&)>& progress = {});

using dense::ColourOrthophoto;
using dense::WriteCloudPly;

// A site-frame raster placed in the frame's CRS (origin added, CRS as WKT)
// for a GeoTIFF a GIS reads; unchanged when the frame has no CRS.
io::GeoRaster InCrs(const io::GeoRaster& raster, const FlightFrame& frame);
// The inverse: a raster read from a GeoTIFF written with InCrs, in this
// frame's site coordinates. Throws InvalidArgument naming `what` when the
// file's CRS is not the frame's (EPSG codes differ, or one has none).
io::GeoRaster InSite(const io::GeoRaster& raster, const FlightFrame& frame,
                     const std::string& what);

// A real flight's change options (the graph's are dense::SurfaceChangeOptions'
// own): the defaults are set in the constructor (doc/real_surfaces.md).
struct FlightChangeOptions : dense::SurfaceChangeOptions {
  // change: 10 co-registration passes (a consumer GNSS shift of metres needs a
  // few), max_shift 10 m, min_stable_cells 100, the heteroscedastic LoD with
  // each bin's 95 % quantile spread (real DoDs have heavy tails: copr split
  // 10.8 % flagged with NMAD bins, 4.1 % with quantile bins); search_radius 8 m.
  FlightChangeOptions();
};
using FlightChangeInput = dense::SurfaceChangeInput;
using FlightChangeSummary = dense::SurfaceChangeSummary;
using FlightChange = dense::CoregisteredChange;

// dense::CompareSurfaces with a flight's options.
FlightChange CompareFlights(const FlightChangeInput& input,
                            const FlightChangeOptions& options = {});

// surface_report.json / .md beside the flight's report: the surface's
// figures and, when `change` is non-null, the change's.
void WriteSurfaceReport(const FlightSurfaceSummary& surface, const FlightChangeSummary* change,
                        const std::string& reference, const std::string& json_path,
                        const std::string& md_path);

}  // namespace flight
}  // namespace slope_monitor
