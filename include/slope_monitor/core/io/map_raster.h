// Site-frame rasters <-> the site's map CRS (common/site_crs.h), for the
// GeoTIFFs a GIS reads (the dense step's surface_eNN.tif and change_eNN.tif,
// dense_surface's and dense_matcher's rasters).
//
// The libraries grid in `site` (x east, y north, metres). A GIS wants an EPSG
// CRS: SiteCrs::MapCrs, the site's own CRS for a shifted_crs site, the UTM
// zone of the origin for a local_enu site (doc/coordinates.md).
//
//  * shifted_crs: the map grid is the site grid moved by the origin (the
//    geotransform's corner plus origin x, y): the same cells, nothing
//    resampled.
//  * local_enu: an ENU grid is rotated against UTM grid north by the meridian
//    convergence and scaled by the point scale, so the raster is resampled
//    onto a north-up grid in the map CRS of the same cell size (UTM metres)
//    covering the site raster: each map cell centre is taken to the site
//    frame by PROJ (at the origin's height, as deformation.tif) and the site
//    raster sampled there: bilinear between the four cell centres, the
//    containing cell where one of them is nodata (so the edges survive), the
//    containing cell always for the categorical bands (kCategoricalBands).
//
// Heights: the band named "height" holds heights; it is converted to the
// map CRS's heights (shifted_crs: plus origin z; local_enu: WGS 84 ellipsoidal
// height of the point, by PROJ). Every other band (a change, an uncertainty,
// a count) is kept as it is.
//
// Without a georeference (site == nullptr) the raster is returned as it is,
// in the local engineering CRS `site` (io::GeoRaster epsg 0).
//
//   const SiteCrs site(site_file.crs);
//   io::WriteGeoTiff("surface_e01.tif", io::MapRasterFromSite(dem, &site));
//   io::GeoRaster back = io::SiteRasterFromMap(io::ReadGeoTiff("surface_e01.tif"), &site, dem);
#pragma once

#include "slope_monitor/core/io/geotiff.h"

namespace slope_monitor {

class SiteCrs;

namespace io {

// Bands resampled from the containing cell only (never interpolated).
extern const char* const kCategoricalBands[3];  // "count", "class", "significant"

// Labels `raster` (already gridded in the site's map CRS) with that CRS: the
// EPSG code SiteCrs::MapEpsg, or, where the map CRS has none (0), the site's
// CRS as WKT (SiteCrs::CrsWkt); srs_wkt is emptied when there is an EPSG code.
void SetMapCrs(GeoRaster* raster, const SiteCrs& site);

// The raster in the site's map CRS (see above). Throws InvalidArgument for an
// inconsistent raster or a cell PROJ cannot convert (naming it).
GeoRaster MapRasterFromSite(const GeoRaster& in_site, const SiteCrs* site);

// The inverse: a raster in the map CRS (written by MapRasterFromSite) sampled
// on the grid of `site_grid` (its size, corner and cell size; its bands are
// not used), the heights back in site z. With site == nullptr the raster's
// own cells are sampled alike. Throws InvalidArgument when the raster's EPSG
// code is not the site's map CRS (naming both).
GeoRaster SiteRasterFromMap(const GeoRaster& in_map, const SiteCrs* site,
                            const GeoRaster& site_grid);
// The same on a north-up site grid of the raster's cell size covering it
// (its corners taken to the site frame at the origin's height).
GeoRaster SiteRasterFromMap(const GeoRaster& in_map, const SiteCrs* site);

}  // namespace io
}  // namespace slope_monitor
