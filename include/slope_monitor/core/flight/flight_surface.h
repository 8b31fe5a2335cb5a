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
// Orthophoto: RGB, the DEM's extent and origin with ortho_subdivision x
// ortho_subdivision cells per DEM cell (so it lines up with the DEM); each
// cell takes the DEM height (bilinear), is projected into every photo whose
// footprint can hold it (found by projecting every 4th DEM cell: nadir and
// oblique photos alike), and takes the bilinear colour of the photo where it
// lies closest to the principal point (the most nadir view; no blending).
// Nodata where the DEM has a hole.
//
// Change (CompareFlights): both DEMs on one grid; stable ground is inside the
// stable polygons when any is given, else everywhere outside the moving
// outlines; co-registration and DoD are dense/dem_change.h (Nuth-Kaab on the
// reference's slope, iterated, with vertical shift and tilt; LoD from both
// DEMs' sigma and a heteroscedastic model of the stable residual by slope
// and roughness, with its held-out check), started
// from a whole-cell shift search (FlightChangeOptions::search_radius). Bad input
// is refused before anything is computed, each with its own message: no
// common cell ("no overlap"), a stable area with no cell on the grid
// ("outside the surface"), a stable area with fewer than min_stable_cells
// cells holding a height in both DEMs ("holes over the stable area").
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
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

// The RGB orthophoto of BGR photos on a DEM (see the file comment).
io::GeoRaster ColourOrthophoto(const io::GeoRaster& dem,
                               const std::vector<dense::OrientedImage>& photos, int subdivision);

// A site-frame raster placed in the frame's CRS (origin added, CRS as WKT)
// for a GeoTIFF a GIS reads; unchanged when the frame has no CRS.
io::GeoRaster InCrs(const io::GeoRaster& raster, const FlightFrame& frame);
// The inverse: a raster read from a GeoTIFF written with InCrs, in this
// frame's site coordinates. Throws InvalidArgument naming `what` when the
// file's CRS is not the frame's (EPSG codes differ, or one has none).
io::GeoRaster InSite(const io::GeoRaster& raster, const FlightFrame& frame,
                     const std::string& what);

// The dense cloud as binary PLY (x, y, z site [m] as float; sigma_z [m];
// red, green, blue). Throws IoError naming the path.
void WriteCloudPly(const std::vector<dense::EpochPoint>& cloud, const std::string& path);

struct FlightChangeOptions {
  dense::DemChangeOptions change = [] {
    dense::DemChangeOptions o;
    o.coregistration_iterations = 10;  // a consumer GNSS shift of metres needs a few passes
    o.max_shift = 10.0;
    o.min_stable_cells = 100;
    // Heteroscedastic LoD: real surfaces' errors grow on steep and rough
    // ground (bushes, edges), one global residual flags them (issue 35).
    // Each bin's spread from its 95 % quantile: real DoDs have heavy tails
    // (blunders of metres on 1 % of copr's cells) that the NMAD does not see
    // (copr split: 10.8 % flagged with NMAD bins, 4.1 % with quantile bins;
    // doc/real_surfaces.md).
    o.error_model.enabled = true;
    o.error_model.spread = dense::ErrorModelOptions::Spread::kQuantile;
    return o;
  }();
  // Start of the co-registration: the whole-cell shift within search_radius
  // [m] that minimises the NMAD of dz about its least-squares plane on the
  // stable cells (GNSS-oriented flights also differ by a tilt; among the shifts
  // keeping at least half the largest overlap), searched on DEMs
  // averaged to ~search_cell [m] and then on the full grid around the best
  // (a consumer GNSS's metres are more than the linearised Nuth-Kaab step
  // converges from on terrain whose features are smaller; at least 2 x 2
  // cells per block); 0: no search.
  double search_radius = 8.0;  // [m] >= 0, <= change.max_shift
  double search_cell = 0.3;    // [m] > 0
  void Check() const;
};

struct FlightChangeInput {
  const io::GeoRaster* reference = nullptr;  // the earlier flight's DEM (site frame)
  const io::GeoRaster* after = nullptr;      // this flight's DEM on the same grid
  std::vector<dense::Polygon> stable;        // [m] site; empty: outside `moving`
  std::vector<dense::Polygon> moving;        // [m] site: never stable, volumes inside
  std::string stable_name = "areas.stable";  // names the stable polygons in messages
};

struct FlightChangeSummary {
  dense::DemChangeSummary dem;  // its co-registration's shift includes the search's
  Eigen::Vector2d searched_shift = Eigen::Vector2d::Zero();  // [m] the search's whole-cell start
  int common_cells = 0;                                      // a height in both DEMs
  int stable_common = 0;                                     // ... and stable
  double stable_median = 0.0;   // [m] median dz on stable ground after co-registration
  double stable_nmad = 0.0;     // [m] 1.4826 x median |dz - median| there
  double stable_flagged = 0.0;  // [-] share of the stable common cells with |class| >= 1
  double flagged = 0.0;         // [-] share of all common cells with |class| >= 1
  std::string BriefReport() const;
};

struct FlightChange {
  dense::DemChangeResult result;  // change raster: bands change, lod, class
  FlightChangeSummary summary;
};

// Throws InvalidArgument (see the file comment) and what dense::DemChange throws.
FlightChange CompareFlights(const FlightChangeInput& input,
                            const FlightChangeOptions& options = {});

// surface_report.json / .md beside the flight's report: the surface's
// figures and, when `change` is non-null, the change's.
void WriteSurfaceReport(const FlightSurfaceSummary& surface, const FlightChangeSummary* change,
                        const std::string& reference, const std::string& json_path,
                        const std::string& md_path);

}  // namespace flight
}  // namespace slope_monitor
