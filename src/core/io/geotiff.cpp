#include "slope_monitor/core/io/geotiff.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <random>
#include <sstream>

#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <gdal_priv.h>
#include <ogr_spatialref.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace io {

namespace {

void RegisterGdal() {
  static std::once_flag once;
  std::call_once(once, [] { GDALAllRegister(); });
}

// Silences GDAL's stderr printing for a scope and keeps the last message.
class QuietGdal {
 public:
  QuietGdal() {
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~QuietGdal() { CPLPopErrorHandler(); }
  static std::string Last() {
    const char* m = CPLGetLastErrorMsg();
    return (m && *m) ? std::string(" (GDAL: ") + m + ")" : std::string();
  }
};

// GDAL writes into memory; the bytes reach the disk through
// io::WriteFileAtomically (exclusive temporary + rename, safe_file.h).
std::string MemoryNameFor() {
  static std::atomic<unsigned> counter{0};
  std::ostringstream s;
  s << "/vsimem/slope_monitor_geotiff_" << counter++ << ".tif";
  return s.str();
}

}  // namespace

int GeoRaster::AddBand(const std::string& name) {
  return AddBand(name, static_cast<float>(nodata));
}

int GeoRaster::AddBand(const std::string& name, float fill) {
  if (width <= 0 || height <= 0)
    throw InvalidArgument(Message("GeoRaster::AddBand('", name, "'): size ", width, "x", height,
                                  " must be positive"));
  band_names.push_back(name);
  bands.emplace_back(static_cast<size_t>(width) * height, fill);
  return num_bands() - 1;
}

int GeoRaster::BandIndex(const std::string& name) const {
  for (int b = 0; b < num_bands(); ++b)
    if (b < static_cast<int>(band_names.size()) && band_names[b] == name) return b;
  return -1;
}

bool GeoRaster::CellOf(double x, double y, int* row, int* col) const {
  const double c = std::floor((x - origin_x) / cell_size);
  const double r = std::floor((origin_y - y) / cell_size);
  if (!(c >= 0 && c < width && r >= 0 && r < height)) return false;
  *row = static_cast<int>(r);
  *col = static_cast<int>(c);
  return true;
}

double GeoRaster::Interpolate(int band, double x, double y) const {
  const double fc = (x - origin_x) / cell_size - 0.5;
  const double fr = (origin_y - y) / cell_size - 0.5;
  if (!(fc >= 0 && fr >= 0 && fc <= width - 1 && fr <= height - 1))
    return std::numeric_limits<double>::quiet_NaN();
  const int c0 = std::min(static_cast<int>(fc), std::max(width - 2, 0));
  const int r0 = std::min(static_cast<int>(fr), std::max(height - 2, 0));
  const int c1 = std::min(c0 + 1, width - 1), r1 = std::min(r0 + 1, height - 1);
  const double ac = fc - c0, ar = fr - r0;
  const float v00 = At(band, r0, c0), v01 = At(band, r0, c1), v10 = At(band, r1, c0),
              v11 = At(band, r1, c1);
  if (IsNoData(v00) || IsNoData(v01) || IsNoData(v10) || IsNoData(v11))
    return std::numeric_limits<double>::quiet_NaN();
  return (1 - ar) * ((1 - ac) * v00 + ac * v01) + ar * ((1 - ac) * v10 + ac * v11);
}

void GeoRaster::Check(const std::string& context) const {
  if (width <= 0 || height <= 0)
    throw InvalidArgument(
        Message(context, ": raster size ", width, "x", height, " must be positive"));
  if (!(cell_size > 0.0) || !std::isfinite(cell_size))
    throw InvalidArgument(Message(context, ": cell_size ", cell_size, " must be > 0"));
  if (!std::isfinite(origin_x) || !std::isfinite(origin_y))
    throw InvalidArgument(
        Message(context, ": origin (", origin_x, ", ", origin_y, ") must be finite"));
  if (bands.empty()) throw InvalidArgument(Message(context, ": raster has no band"));
  if (band_names.size() != bands.size())
    throw InvalidArgument(
        Message(context, ": ", band_names.size(), " band names for ", bands.size(), " bands"));
  for (size_t b = 0; b < bands.size(); ++b)
    if (bands[b].size() != static_cast<size_t>(width) * height)
      throw InvalidArgument(Message(context, ": band ", b, " ('", band_names[b], "') has ",
                                    bands[b].size(), " values, expected ",
                                    static_cast<size_t>(width) * height));
  if (epsg < 0) throw InvalidArgument(Message(context, ": epsg ", epsg, " must be >= 0"));
  if (rgb && bands.size() != 3)
    throw InvalidArgument(Message(context, ": an RGB raster needs 3 bands, not ", bands.size()));
}

namespace {

// An RGB raster's bands as bytes (rounded, clamped to 0..255) and its alpha
// band: 255 where all three have a value, 0 (and 0 in each band) elsewhere.
bool WriteRgbBands(const GeoRaster& raster, GDALDataset* ds) {
  const size_t n = static_cast<size_t>(raster.width) * raster.height;
  std::vector<GByte> alpha(n, 255);
  for (int b = 0; b < 3; ++b)
    for (size_t i = 0; i < n; ++i)
      if (raster.IsNoData(raster.bands[b][i])) alpha[i] = 0;
  std::vector<GByte> bytes(n);
  for (int b = 0; b < 4; ++b) {
    for (size_t i = 0; b < 3 && i < n; ++i)
      bytes[i] = alpha[i] == 0
                     ? 0
                     : static_cast<GByte>(std::clamp(
                           std::lround(static_cast<double>(raster.bands[b][i])), 0L, 255L));
    GDALRasterBand* band = ds->GetRasterBand(b + 1);
    band->SetDescription(b < 3 ? raster.band_names[b].c_str() : "alpha");
    GByte* data = b < 3 ? bytes.data() : alpha.data();
    if (band->RasterIO(GF_Write, 0, 0, raster.width, raster.height, data, raster.width,
                       raster.height, GDT_Byte, 0, 0) != CE_None)
      return false;
  }
  return true;
}

}  // namespace

void WriteGeoTiff(const std::string& path, const GeoRaster& raster) {
  raster.Check(path);
  RegisterGdal();
  QuietGdal quiet;
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
  if (!driver) throw IoError(Message(path, ": GDAL has no GTiff driver"));

  OGRSpatialReference srs;
  if (!raster.srs_wkt.empty()) {
    if (srs.importFromWkt(raster.srs_wkt.c_str()) != OGRERR_NONE)
      throw InvalidArgument(Message(path, ": srs_wkt is not a CRS GDAL reads", QuietGdal::Last()));
  } else if (raster.epsg > 0) {
    if (srs.importFromEPSG(raster.epsg) != OGRERR_NONE)
      throw InvalidArgument(Message(path, ": unknown EPSG code ", raster.epsg, QuietGdal::Last()));
  } else {
    srs.SetLocalCS("site");
    srs.SetLinearUnits(SRS_UL_METER, 1.0);
  }

  const std::string tmp = MemoryNameFor();
  char** create_options = nullptr;
  create_options = CSLSetNameValue(create_options, "COMPRESS", "DEFLATE");
  create_options = CSLSetNameValue(create_options, "PREDICTOR", raster.rgb ? "2" : "3");
  if (raster.rgb) {
    create_options = CSLSetNameValue(create_options, "PHOTOMETRIC", "RGB");
    create_options = CSLSetNameValue(create_options, "ALPHA", "YES");
  }
  GDALDataset* ds =
      driver->Create(tmp.c_str(), raster.width, raster.height, raster.num_bands() + raster.rgb,
                     raster.rgb ? GDT_Byte : GDT_Float32, create_options);
  CSLDestroy(create_options);
  if (!ds) throw IoError(Message(path, ": cannot create GeoTIFF", QuietGdal::Last()));

  bool ok = true;
  std::vector<double> gt = raster.GeoTransform();
  ok = ok && ds->SetGeoTransform(gt.data()) == CE_None;
  ok = ok && ds->SetSpatialRef(&srs) == CE_None;
  if (raster.rgb) {
    ok = ok && WriteRgbBands(raster, ds);
  } else {
    for (int b = 0; ok && b < raster.num_bands(); ++b) {
      GDALRasterBand* band = ds->GetRasterBand(b + 1);
      band->SetDescription(raster.band_names[b].c_str());
      ok = band->SetNoDataValue(raster.nodata) == CE_None;
      ok = ok && band->RasterIO(GF_Write, 0, 0, raster.width, raster.height,
                                const_cast<float*>(raster.bands[b].data()), raster.width,
                                raster.height, GDT_Float32, 0, 0) == CE_None;
    }
  }
  std::string why = QuietGdal::Last();
  // GDALClose flushes; a failure there (disk full) is the last chance to notice.
  CPLErrorReset();
  GDALClose(ds);
  if (CPLGetLastErrorType() >= CE_Failure) {
    ok = false;
    why = QuietGdal::Last();
  }
  if (!ok) {
    VSIUnlink(tmp.c_str());
    throw IoError(Message(path, ": writing the GeoTIFF failed", why));
  }
  vsi_l_offset size = 0;
  GByte* bytes = VSIGetMemFileBuffer(tmp.c_str(), &size, TRUE);  // takes ownership, unlinks
  if (!bytes) throw IoError(Message(path, ": GDAL produced no GeoTIFF in memory"));
  const std::string content(reinterpret_cast<const char*>(bytes), static_cast<size_t>(size));
  CPLFree(bytes);
  WriteFileAtomically(path, content);
}

GeoRaster ReadGeoTiff(const std::string& path) {
  RegisterGdal();
  QuietGdal quiet;
  GDALDataset* ds = static_cast<GDALDataset*>(GDALOpen(path.c_str(), GA_ReadOnly));
  if (!ds) throw IoError(Message(path, ": cannot open raster", QuietGdal::Last()));
  struct Closer {
    GDALDataset* d;
    ~Closer() { GDALClose(d); }
  } closer{ds};

  GeoRaster r;
  r.width = ds->GetRasterXSize();
  r.height = ds->GetRasterYSize();
  if (ds->GetRasterCount() < 1) throw IoError(Message(path, ": raster has no band"));
  double gt[6];
  if (ds->GetGeoTransform(gt) != CE_None)
    throw IoError(Message(path, ": raster has no geotransform"));
  if (gt[2] != 0.0 || gt[4] != 0.0)
    throw IoError(
        Message(path, ": rotated geotransform (", gt[2], ", ", gt[4], ") is not supported"));
  if (!(gt[1] > 0.0) || std::abs(gt[1] + gt[5]) > 1e-9 * gt[1])
    throw IoError(Message(path, ": cells must be square and north-up (geotransform dx ", gt[1],
                          ", dy ", gt[5], ")"));
  r.origin_x = gt[0];
  r.origin_y = gt[3];
  r.cell_size = gt[1];

  if (const OGRSpatialReference* srs = ds->GetSpatialRef()) {
    char* wkt = nullptr;
    if (srs->exportToWkt(&wkt) == OGRERR_NONE && wkt) r.srs_wkt = wkt;
    CPLFree(wkt);
    const char* code = srs->GetAuthorityCode(nullptr);
    const char* name = srs->GetAuthorityName(nullptr);
    if (code && name && std::string(name) == "EPSG") r.epsg = std::atoi(code);
  }

  // An RGB picture with an alpha band (WriteGeoTiff of an rgb raster, and
  // the usual orthophoto of other tools): its colour bands, NaN where alpha is 0.
  const int count = ds->GetRasterCount();
  r.rgb = count == 4 && ds->GetRasterBand(1)->GetColorInterpretation() == GCI_RedBand &&
          ds->GetRasterBand(2)->GetColorInterpretation() == GCI_GreenBand &&
          ds->GetRasterBand(3)->GetColorInterpretation() == GCI_BlueBand &&
          ds->GetRasterBand(4)->GetColorInterpretation() == GCI_AlphaBand;
  std::vector<float> alpha;
  if (r.rgb) {
    alpha.resize(static_cast<size_t>(r.width) * r.height);
    if (ds->GetRasterBand(4)->RasterIO(GF_Read, 0, 0, r.width, r.height, alpha.data(), r.width,
                                       r.height, GDT_Float32, 0, 0) != CE_None)
      throw IoError(Message(path, ": cannot read its alpha band", QuietGdal::Last()));
  }
  for (int b = 0; b < (r.rgb ? 3 : count); ++b) {
    GDALRasterBand* band = ds->GetRasterBand(b + 1);
    int has_nodata = 0;
    const double nd = band->GetNoDataValue(&has_nodata);
    if (b == 0 && has_nodata) r.nodata = nd;
    const char* desc = band->GetDescription();
    r.band_names.push_back(desc ? desc : "");
    r.bands.emplace_back(static_cast<size_t>(r.width) * r.height);
    if (band->RasterIO(GF_Read, 0, 0, r.width, r.height, r.bands.back().data(), r.width, r.height,
                       GDT_Float32, 0, 0) != CE_None)
      throw IoError(Message(path, ": cannot read band ", b + 1, QuietGdal::Last()));
    // Bands with their own nodata value are mapped to the raster's.
    if (has_nodata && b > 0 && !(nd == r.nodata || (std::isnan(nd) && std::isnan(r.nodata))))
      for (float& v : r.bands.back())
        if (static_cast<double>(v) == nd) v = static_cast<float>(r.nodata);
    for (size_t i = 0; i < alpha.size(); ++i)
      if (alpha[i] == 0.0f) r.bands.back()[i] = static_cast<float>(r.nodata);
  }
  return r;
}

}  // namespace io
}  // namespace slope_monitor
