// GeoTIFF rasters in the site frame (GDAL).
//
// A GeoRaster is a north-up grid of float32 cells with one or more bands
// (height, uncertainty, count, ...). Cells are addressed (row, col) with row 0
// the northern-most row and col 0 the western-most column, exactly like the
// GeoTIFF pixel order. The grid is placed in the `site` frame (x east, y
// north, metres) by the upper-left corner of cell (0, 0) and a square cell
// size; this is GDAL's geotransform
//
//   x = origin_x + (col + 0.5) * cell_size        (cell centre)
//   y = origin_y - (row + 0.5) * cell_size
//   geotransform = {origin_x, cell_size, 0, origin_y, 0, -cell_size}
//
// so origin_y is the NORTHERN edge of the raster (the largest y).
//
// Missing cells hold the nodata value (default NaN; a finite value such as
// -9999 is allowed). Readers must test with IsNoData(), which treats NaN
// correctly. Holes are never filled by this module.
//
// Spatial reference: with epsg == 0 the file carries a local engineering CRS
// (LOCAL_CS named "site", metres), because `site` is a local slope frame; with
// epsg > 0 it carries that EPSG code (e.g. a UTM zone when the site is
// georeferenced). On reading, epsg is the EPSG code of the file's CRS when it
// has one, else 0; srs_wkt is the file's CRS as WKT (empty when none). On
// writing, a non-empty srs_wkt is the CRS written (it wins over epsg).
//
// Writing goes to a temporary file in the same directory, which is renamed
// over `path` only after GDAL has closed it without error, so a half-written
// file never carries the final name. Every failure throws IoError naming the
// file; an inconsistent raster (band sizes, cell size <= 0, ...) throws
// InvalidArgument before anything is written.
//
//   io::GeoRaster dem(200, 150, /*origin_x=*/0.0, /*origin_y=*/150.0, /*cell_size=*/1.0);
//   dem.AddBand("height");                 // filled with nodata
//   dem.At(0, row, col) = 12.5f;
//   io::WriteGeoTiff("dem.tif", dem);
//   io::GeoRaster back = io::ReadGeoTiff("dem.tif");
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace io {

struct GeoRaster {
  int width = 0;                                             // [cells] columns
  int height = 0;                                            // [cells] rows
  double origin_x = 0.0;                                     // [m] site x of the western edge
  double origin_y = 0.0;                                     // [m] site y of the northern edge
  double cell_size = 1.0;                                    // [m] square cells, > 0
  double nodata = std::numeric_limits<double>::quiet_NaN();  // marks missing cells (NaN or finite)
  int epsg = 0;                         // 0: local engineering CRS "site"; > 0: EPSG code
  std::string srs_wkt;                  // filled on read; on write, when not empty, the CRS written
  std::vector<std::string> band_names;  // one description per band
  std::vector<std::vector<float>> bands;  // [band][row * width + col]
  // A picture (an orthophoto): 3 bands of 0..255 written as an 8-bit RGB
  // GeoTIFF with an alpha band, 0 where a band is nodata (what GIS tools
  // show as colour with transparent holes; Float32 bands they show as grey).
  // ReadGeoTiff gives such a file back as 3 bands with NaN where alpha is 0.
  bool rgb = false;

  GeoRaster() = default;
  GeoRaster(int width_cells, int height_cells, double x_west, double y_north, double cell)
      : width(width_cells),
        height(height_cells),
        origin_x(x_west),
        origin_y(y_north),
        cell_size(cell) {}

  // Appends a band filled with `fill` (default: nodata) and returns its index.
  int AddBand(const std::string& name);
  int AddBand(const std::string& name, float fill);
  int num_bands() const { return static_cast<int>(bands.size()); }
  // Index of the band with this description, or -1.
  int BandIndex(const std::string& name) const;

  float& At(int band, int row, int col) {
    return bands[band][static_cast<size_t>(row) * width + col];
  }
  float At(int band, int row, int col) const {
    return bands[band][static_cast<size_t>(row) * width + col];
  }
  bool IsNoData(float v) const {
    return std::isnan(v) || (!std::isnan(nodata) && static_cast<double>(v) == nodata);
  }

  // Site (x, y) of the centre of a cell.
  Eigen::Vector2d CellCentre(int row, int col) const {
    return {origin_x + (col + 0.5) * cell_size, origin_y - (row + 0.5) * cell_size};
  }
  // Cell containing site (x, y); false when outside the raster.
  bool CellOf(double x, double y, int* row, int* col) const;
  // Bilinear interpolation of a band at site (x, y) between cell centres;
  // NaN when outside or when any of the four cells is nodata.
  double Interpolate(int band, double x, double y) const;

  // The six GDAL geotransform coefficients (see the file comment).
  std::vector<double> GeoTransform() const {
    return {origin_x, cell_size, 0.0, origin_y, 0.0, -cell_size};
  }

  // Throws InvalidArgument when sizes, cell size or band lengths disagree.
  void Check(const std::string& context) const;
};

// Writes a float32 GeoTIFF (DEFLATE compressed) atomically (temp file + rename).
// Throws InvalidArgument for an inconsistent raster and IoError naming `path`
// when the file cannot be written.
void WriteGeoTiff(const std::string& path, const GeoRaster& raster);

// Reads any GDAL-readable north-up raster (bands converted to float32).
// Throws IoError naming `path` when the file is missing or unreadable, or
// when the raster is rotated (non-zero geotransform terms 2 and 4) or its
// cells are not square.
GeoRaster ReadGeoTiff(const std::string& path);

}  // namespace io
}  // namespace slope_monitor
