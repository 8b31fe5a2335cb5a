#include "slope_monitor/core/dense/change.h"

#include <cmath>
#include <sstream>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {

namespace {
int BandOf(const io::GeoRaster& r, const char* name, int fallback, const char* which) {
  int b = r.BandIndex(name);
  if (b < 0) b = fallback;
  if (b >= r.num_bands())
    throw InvalidArgument(Message("SurfaceChange: the ", which, " model has no '", name, "' band"));
  return b;
}
}  // namespace

void ChangeOptions::Check() const {
  if (!(lod_factor >= 0 && lod_factor <= 10))
    throw ConfigError(Message("change option 'lod_factor' = ", lod_factor, " must be in [0, 10]"));
  if (!(min_lod >= 0))
    throw ConfigError(Message("change option 'min_lod' = ", min_lod, " m must be >= 0"));
}

std::string ChangeSummary::BriefReport() const {
  std::ostringstream s;
  s << "surface change: " << cells_compared << " cells compared (" << cells_missing
    << " missing), gain " << volume_gain << " +- " << sigma_gain << " m3 over " << cells_gain
    << " cells, loss " << volume_loss << " +- " << sigma_loss << " m3 over " << cells_loss
    << " cells, net " << volume_net << " m3 (all cells, no LoD: " << volume_net_all << " m3)";
  return s.str();
}

ChangeResult SurfaceChange(const io::GeoRaster& before, const io::GeoRaster& after,
                           const ChangeOptions& options) {
  options.Check();
  if (before.width != after.width || before.height != after.height ||
      std::abs(before.origin_x - after.origin_x) > 1e-6 * before.cell_size ||
      std::abs(before.origin_y - after.origin_y) > 1e-6 * before.cell_size ||
      std::abs(before.cell_size - after.cell_size) > 1e-9 * before.cell_size)
    throw InvalidArgument(Message("SurfaceChange: the models' grids differ (", before.width, "x",
                                  before.height, " at (", before.origin_x, ", ", before.origin_y,
                                  ") cell ", before.cell_size, " vs ", after.width, "x",
                                  after.height, " at (", after.origin_x, ", ", after.origin_y,
                                  ") cell ", after.cell_size, ")"));
  const int hb = BandOf(before, "height", 0, "before"),
            ub = BandOf(before, "uncertainty", 1, "before");
  const int ha = BandOf(after, "height", 0, "after"), ua = BandOf(after, "uncertainty", 1, "after");
  ChangeResult out;
  io::GeoRaster& c = out.change;
  c = io::GeoRaster(before.width, before.height, before.origin_x, before.origin_y,
                    before.cell_size);
  c.epsg = before.epsg;
  c.AddBand("dz");
  c.AddBand("lod");
  c.AddBand("significant");
  ChangeSummary& s = out.summary;
  const double area = before.cell_size * before.cell_size;
  double var_gain = 0, var_loss = 0;
  for (int row = 0; row < c.height; ++row)
    for (int col = 0; col < c.width; ++col) {
      const float z0 = before.At(hb, row, col), z1 = after.At(ha, row, col);
      const float u0 = before.At(ub, row, col), u1 = after.At(ua, row, col);
      if (before.IsNoData(z0) || after.IsNoData(z1) || before.IsNoData(u0) || after.IsNoData(u1)) {
        ++s.cells_missing;
        continue;
      }
      ++s.cells_compared;
      const double dz = z1 - z0;
      s.volume_net_all += dz * area;
      const double u = std::sqrt(static_cast<double>(u0) * u0 + static_cast<double>(u1) * u1);
      const double lod = std::max(options.min_lod, options.lod_factor * u);
      c.At(kDz, row, col) = static_cast<float>(dz);
      c.At(kLod, row, col) = static_cast<float>(lod);
      float sig = 0.0f;
      if (std::abs(dz) > lod) {
        if (dz > 0) {
          sig = 1.0f;
          ++s.cells_gain;
          s.volume_gain += dz * area;
          var_gain += u * u * area * area;
        } else {
          sig = -1.0f;
          ++s.cells_loss;
          s.volume_loss += -dz * area;
          var_loss += u * u * area * area;
        }
        const Eigen::Vector2d xy = c.CellCentre(row, col);
        out.significant.push_back(
            {Eigen::Vector3d(xy.x(), xy.y(), z1), static_cast<float>(dz), static_cast<float>(lod)});
      }
      c.At(kSignificant, row, col) = sig;
    }
  s.volume_net = s.volume_gain - s.volume_loss;
  s.sigma_gain = std::sqrt(var_gain);
  s.sigma_loss = std::sqrt(var_loss);
  return out;
}

}  // namespace dense
}  // namespace slope_monitor
