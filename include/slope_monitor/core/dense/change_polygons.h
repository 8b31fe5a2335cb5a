// Polygons of significant change of a DoD (dem_change.h): the cells whose
// significance class is at least `min_class` in magnitude are split by sign
// into 4-connected regions (OpenCV connected components) and each region is
// traced into a polygon by GDAL (GDALPolygonize, through an OGR memory
// layer), in the DoD's site coordinates. A region smaller than `min_area` is
// dropped (isolated cells are noise at the LoD's 5 %).
//
//   std::vector<ChangePolygon> p = ChangePolygons(dod.change, ChangePolygonOptions());
//   // p[k].sign: +1 gain (fill) / -1 loss (cut); p[k].area [m^2]; p[k].volume [m^3]
#pragma once

#include <vector>

#include "slope_monitor/core/dense/dem_change.h"
#include "slope_monitor/core/io/geotiff.h"

namespace slope_monitor {
namespace dense {

struct ChangePolygonOptions {
  int min_class = 1;      // [-] |class| at least this (1: beyond LoD, 2: beyond 2 LoD); 1 or 2
  double min_area = 4.0;  // [m^2] smaller regions are dropped; >= 0
  void Check() const;     // InvalidArgument naming the field
};

struct ChangePolygon {
  int sign = 0;                // +1 gain, -1 loss
  int cells = 0;               // cells of the region
  double area = 0.0;           // [m^2] cells * cell_size^2 (= the polygon's area)
  double volume = 0.0;         // [m^3] sum of dz * cell area (signed)
  double mean_change = 0.0;    // [m] volume / area
  double max_change = 0.0;     // [m] largest |dz| (signed)
  Polygon outline;             // exterior ring, site x, y, closed implicitly
  std::vector<Polygon> holes;  // interior rings
};

// Polygons of the DoD `change` (bands "change" and "class"), largest area
// first. Throws InvalidArgument when a band is missing, IoError when GDAL fails.
std::vector<ChangePolygon> ChangePolygons(const io::GeoRaster& change,
                                          const ChangePolygonOptions& options);

}  // namespace dense
}  // namespace slope_monitor
