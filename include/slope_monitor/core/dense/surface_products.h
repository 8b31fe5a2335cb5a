// What a measured surface leaves besides its DEM, with no ROS in it: the RGB
// orthophoto, the dense cloud as a file, and the change against a reference
// surface co-registered on stable ground with its report. process_flight
// (a real flight, core/flight/flight_surface.h) and the graph's dense step
// (dense::SurfaceSeries: the dense_epoch nodelet, process_bag, dense_surface
// --bag) call these same functions (doc/real_surfaces.md).
//
//   io::GeoRaster ortho = dense::ColourOrthophoto(dem, photos, 4);
//   dense::WriteCloudPly(points, dir + "/cloud_e02.ply");
//   dense::CoregisteredChange c = dense::CompareSurfaces({&reference_dem, &dem, stable, moving});
//
// Orthophoto: RGB, the DEM's extent and origin with `subdivision` x
// `subdivision` cells per DEM cell (so it lines up with the DEM); each cell
// takes the DEM height (bilinear), is projected into every photo whose
// footprint can hold it (found by projecting every 4th DEM cell: nadir and
// oblique photos alike), and takes the bilinear colour of the photo where it
// lies closest to the principal point (the most nadir view; no blending). A
// grey photo gives the same value in red, green and blue. Nodata where the
// DEM has a hole.
//
// Change (CompareSurfaces): both DEMs on one grid; stable ground is inside
// the stable polygons when any is given, else everywhere outside the moving
// outlines, and (both ways) where an operator's stable mask is non-zero;
// co-registration and DoD are dense/dem_change.h (Nuth-Kaab on the
// reference's slope, iterated, with vertical shift and tilt; LoD from both
// DEMs' sigma and the stable residual, or its heteroscedastic model by slope
// and roughness with its held-out check), started from a whole-cell shift
// search (SurfaceChangeOptions::search_radius): a consumer GNSS shifts a
// flight by metres, more than the linearised Nuth-Kaab step converges from on
// terrain whose features are smaller. Bad input is refused before anything
// is computed, each with its own message: no common cell ("no overlap"), a
// stable area with no cell on the grid ("outside the surface"), a stable
// area with fewer than min_stable_cells cells holding a height in both DEMs
// ("holes over the stable area").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json_fwd.hpp>

#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/dense/surface.h"

namespace slope_monitor {
namespace dense {

// The RGB orthophoto of BGR (or grey) photos on a DEM (see the file comment).
io::GeoRaster ColourOrthophoto(const io::GeoRaster& dem, const std::vector<OrientedImage>& photos,
                               int subdivision);

// The dense cloud as binary PLY (x, y, z site [m] as float; sigma_z [m];
// red, green, blue). Throws IoError naming the path.
void WriteCloudPly(const std::vector<EpochPoint>& cloud, const std::string& path);

struct SurfaceChangeOptions {
  // The co-registration and DoD. These defaults are the graph's (one global
  // stable residual in the LoD: the simulator's truth tests);
  // flight::FlightChangeOptions sets a real flight's.
  DemChangeOptions change;
  // Start of the co-registration: the whole-cell shift within search_radius
  // [m] that minimises the NMAD of dz about its least-squares plane on the
  // stable cells (GNSS-oriented flights also differ by a tilt; among the shifts
  // keeping at least half the largest overlap), searched on DEMs
  // averaged to ~search_cell [m] and then on the full grid around the best
  // (at least 2 x 2 cells per block); 0: no search. The graph's 4 m: a
  // consumer GNSS's metres; a block tied by control points finds 0.
  double search_radius = 4.0;  // [m] >= 0, <= change.max_shift
  double search_cell = 0.3;    // [m] > 0
  void Check() const;          // ConfigError naming the field
};

struct SurfaceChangeInput {
  const io::GeoRaster* reference = nullptr;  // the earlier surface's DEM (site frame)
  const io::GeoRaster* after = nullptr;      // this surface's DEM on the same grid
  std::vector<Polygon> stable;               // [m] site; empty: outside `moving`
  std::vector<Polygon> moving;               // [m] site: never stable, volumes inside
  std::string stable_name = "areas.stable";  // names the stable ground in messages
  // An operator's stable mask on the grid (non-zero = stable; empty: none).
  // Throws InvalidArgument naming stable_name when its size is not the grid's.
  std::vector<uint8_t> stable_mask;
};

struct SurfaceChangeSummary {
  DemChangeSummary dem;  // its co-registration's shift includes the search's
  Eigen::Vector2d searched_shift = Eigen::Vector2d::Zero();  // [m] the search's whole-cell start
  int common_cells = 0;                                      // a height in both DEMs
  int stable_common = 0;                                     // ... and stable
  double stable_median = 0.0;   // [m] median dz on stable ground after co-registration
  double stable_nmad = 0.0;     // [m] 1.4826 x median |dz - median| there
  double stable_flagged = 0.0;  // [-] share of the stable common cells with |class| >= 1
  double flagged = 0.0;         // [-] share of all common cells with |class| >= 1
  std::string BriefReport() const;
};

struct CoregisteredChange {
  DemChangeResult result;  // change raster: bands change, lod, class
  SurfaceChangeSummary summary;
};

// Throws InvalidArgument (see the file comment) and what dense::DemChange throws.
CoregisteredChange CompareSurfaces(const SurfaceChangeInput& input,
                                   const SurfaceChangeOptions& options = {});

// The change's figures for surface_report.json (the value of its "change":
// shift, vertical, their sigma, stable figures, volumes, the error model's
// bins) and surface_report.md (a section with the error model's table).
nlohmann::ordered_json ChangeReportJson(const SurfaceChangeSummary& change,
                                        const std::string& reference);
std::string ChangeReportMarkdown(const SurfaceChangeSummary& change, const std::string& reference);

// surface_report_eNN.json / .md of a graph epoch (SurfaceSeries): the
// surface's figures and, when `change` is non-null, the change's. Throws
// IoError naming the file.
void WriteEpochSurfaceReport(const EpochSurfaceSummary& surface, const SurfaceChangeSummary* change,
                             const std::string& reference, const std::string& json_path,
                             const std::string& md_path);

}  // namespace dense
}  // namespace slope_monitor
