#include "slope_monitor/core/dense/change_polygons.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>

#include <gdal_alg.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {
namespace {

struct GdalCloser {
  void operator()(GDALDataset* d) const { GDALClose(d); }
};
using Dataset = std::unique_ptr<GDALDataset, GdalCloser>;

int BandOf(const io::GeoRaster& r, const char* name) {
  const int b = r.BandIndex(name);
  if (b < 0) throw InvalidArgument(Message("change polygons: the DoD has no band '", name, "'"));
  return b;
}

// Region labels: 1..n for the regions of one sign, one int32 raster for both
// signs (gains first). `sign_of[label]` and the per-label sums are filled.
cv::Mat LabelRegions(const io::GeoRaster& change, const ChangePolygonOptions& o,
                     std::vector<ChangePolygon>* regions) {
  const int cls = BandOf(change, "class"), dz = BandOf(change, "change");
  cv::Mat labels(change.height, change.width, CV_32S, cv::Scalar(0));
  const double cell_area = change.cell_size * change.cell_size;
  for (int sign : {+1, -1}) {
    cv::Mat mask(change.height, change.width, CV_8U, cv::Scalar(0));
    for (int r = 0; r < change.height; ++r)
      for (int c = 0; c < change.width; ++c) {
        const float k = change.At(cls, r, c);
        if (!change.IsNoData(k) && k * sign >= o.min_class) mask.at<uint8_t>(r, c) = 1;
      }
    cv::Mat own;
    const int n = cv::connectedComponents(mask, own, 4, CV_32S);
    const int first = static_cast<int>(regions->size());
    regions->resize(first + n - 1);
    for (int k = first; k < first + n - 1; ++k) (*regions)[k].sign = sign;
    for (int r = 0; r < change.height; ++r)
      for (int c = 0; c < change.width; ++c) {
        const int k = own.at<int32_t>(r, c);
        if (k == 0) continue;
        labels.at<int32_t>(r, c) = first + k;  // 1-based over both signs
        ChangePolygon& p = (*regions)[first + k - 1];
        const double d = change.At(dz, r, c);
        ++p.cells;
        p.volume += d * cell_area;
        if (std::abs(d) > std::abs(p.max_change)) p.max_change = d;
      }
  }
  for (ChangePolygon& p : *regions) {
    p.area = p.cells * cell_area;
    p.mean_change = p.area > 0.0 ? p.volume / p.area : 0.0;
  }
  return labels;
}

Polygon Ring(const OGRLinearRing* ring) {
  Polygon out;
  const int n = ring->getNumPoints();
  for (int i = 0; i + 1 < n; ++i) out.emplace_back(ring->getX(i), ring->getY(i));  // last = first
  return out;
}

}  // namespace

void ChangePolygonOptions::Check() const {
  if (min_class != 1 && min_class != 2)
    throw InvalidArgument(Message("change polygons: min_class ", min_class, " must be 1 or 2"));
  if (!(min_area >= 0.0))
    throw InvalidArgument(Message("change polygons: min_area ", min_area, " m^2 must be >= 0"));
}

std::vector<ChangePolygon> ChangePolygons(const io::GeoRaster& change,
                                          const ChangePolygonOptions& options) {
  options.Check();
  std::vector<ChangePolygon> regions;
  cv::Mat labels = LabelRegions(change, options, &regions);
  if (regions.empty()) return {};

  GDALAllRegister();
  GDALDriver* mem = GetGDALDriverManager()->GetDriverByName("MEM");
  GDALDriver* memory = GetGDALDriverManager()->GetDriverByName("Memory");  // OGR's
  if (!mem || !memory) throw IoError("change polygons: GDAL has no MEM / Memory driver");
  Dataset raster(mem->Create("", change.width, change.height, 1, GDT_Int32, nullptr));
  Dataset vector(memory->Create("", 0, 0, 0, GDT_Unknown, nullptr));
  if (!raster || !vector) throw IoError("change polygons: GDAL cannot create a memory dataset");
  double transform[6] = {change.origin_x,  change.cell_size, 0.0, change.origin_y, 0.0,
                         -change.cell_size};
  raster->SetGeoTransform(transform);
  GDALRasterBand* band = raster->GetRasterBand(1);
  if (band->RasterIO(GF_Write, 0, 0, change.width, change.height, labels.ptr<int32_t>(),
                     change.width, change.height, GDT_Int32, 0, 0, nullptr) != CE_None)
    throw IoError(
        Message("change polygons: GDAL cannot fill the label raster: ", CPLGetLastErrorMsg()));
  OGRLayer* layer = vector->CreateLayer("regions", nullptr, wkbPolygon, nullptr);
  OGRFieldDefn field("label", OFTInteger);
  if (!layer || layer->CreateField(&field) != OGRERR_NONE)
    throw IoError("change polygons: GDAL cannot create the polygon layer");
  // The label band masks itself: label 0 (no significant change) is not traced.
  if (GDALPolygonize(band, band, layer, 0, nullptr, nullptr, nullptr) != CE_None)
    throw IoError(Message("change polygons: GDALPolygonize failed: ", CPLGetLastErrorMsg()));

  std::vector<ChangePolygon> out;
  layer->ResetReading();
  for (OGRFeature* f; (f = layer->GetNextFeature()) != nullptr; OGRFeature::DestroyFeature(f)) {
    const int label = f->GetFieldAsInteger(0);
    const OGRGeometry* g = f->GetGeometryRef();
    if (label < 1 || label > static_cast<int>(regions.size()) || !g ||
        wkbFlatten(g->getGeometryType()) != wkbPolygon)
      continue;
    ChangePolygon p = regions[label - 1];
    if (p.area < options.min_area) continue;
    const OGRPolygon* poly = g->toPolygon();
    p.outline = Ring(poly->getExteriorRing());
    for (int i = 0; i < poly->getNumInteriorRings(); ++i)
      p.holes.push_back(Ring(poly->getInteriorRing(i)));
    out.push_back(std::move(p));
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const ChangePolygon& a, const ChangePolygon& b) { return a.area > b.area; });
  return out;
}

}  // namespace dense
}  // namespace slope_monitor
