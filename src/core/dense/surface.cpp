#include "slope_monitor/core/dense/surface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace dense {

namespace {}  // namespace

void SurfaceOptions::Check() const {
  correlation.Check();
  rectify.Check();
  RequireOption("dense surface", cell_size > 0 && cell_size <= 100, "cell_size",
                Message("= ", cell_size, " m must be in (0, 100]"));
  RequireOption("dense surface", min_points_per_cell >= 1 && min_points_per_cell <= 1000,
                "min_points_per_cell", Message("= ", min_points_per_cell, " must be in [1, 1000]"));
  RequireOption("dense surface", parallax_sigma > 0 && parallax_sigma <= 10, "parallax_sigma",
                Message("= ", parallax_sigma, " px must be in (0, 10]"));
  RequireOption("dense surface", max_ray_gap >= 0, "max_ray_gap",
                Message("= ", max_ray_gap, " m must be >= 0"));
  RequireOption("dense surface", ortho_cell_size >= 0, "ortho_cell_size",
                Message("= ", ortho_cell_size, " m must be >= 0"));
}

std::string SurfaceSummary::BriefReport() const {
  std::ostringstream s;
  s << correlation.BriefReport() << "; " << patches << " patches, " << points << " points ("
    << rejected_points << " rejected), " << filled_cells << "/" << cells
    << " cells filled, overlap " << 100.0 * rectified_overlap << "%, " << seconds << " s";
  return s.str();
}

io::GeoRaster GridSurface(const std::vector<SurfacePoint>& points, double cell_size,
                          int min_points_per_cell, const Eigen::Vector4d& region_in,
                          double points_per_window) {
  if (!(points_per_window >= 1.0))
    throw InvalidArgument(
        Message("GridSurface: points_per_window ", points_per_window, " must be >= 1"));
  if (!(cell_size > 0))
    throw InvalidArgument(Message("GridSurface: cell_size ", cell_size, " must be > 0"));
  Eigen::Vector4d region = region_in;
  if (region.isZero()) {
    if (points.empty()) throw InvalidArgument("GridSurface: no points and no region");
    double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
    for (const auto& p : points) {
      x0 = std::min(x0, p.x_in_site.x());
      x1 = std::max(x1, p.x_in_site.x());
      y0 = std::min(y0, p.x_in_site.y());
      y1 = std::max(y1, p.x_in_site.y());
    }
    region << std::floor(x0 / cell_size) * cell_size, (std::floor(x1 / cell_size) + 1) * cell_size,
        std::floor(y0 / cell_size) * cell_size, (std::floor(y1 / cell_size) + 1) * cell_size;
  }
  if (!(region[1] > region[0] && region[3] > region[2]))
    throw InvalidArgument(Message("GridSurface: region [", region.transpose(), "] is empty"));
  const int w =
      std::max(1, static_cast<int>(std::ceil((region[1] - region[0]) / cell_size - 1e-9)));
  const int h =
      std::max(1, static_cast<int>(std::ceil((region[3] - region[2]) / cell_size - 1e-9)));
  if (static_cast<double>(w) * h > 1e8)
    throw InvalidArgument(
        Message("GridSurface: ", w, "x", h, " cells is too many (cell_size ", cell_size, " m)"));
  io::GeoRaster r(w, h, region[0], region[3], cell_size);
  r.AddBand("height");
  r.AddBand("uncertainty");
  r.AddBand("count", 0.0f);
  r.AddBand("spread");
  const size_t n = static_cast<size_t>(w) * h;
  std::vector<double> sw(n, 0.0), swz(n, 0.0), swzz(n, 0.0);
  std::vector<int> cnt(n, 0);
  for (const auto& p : points) {
    int row, col;
    if (!r.CellOf(p.x_in_site.x(), p.x_in_site.y(), &row, &col)) continue;
    const size_t k = static_cast<size_t>(row) * w + col;
    const double wt = 1.0 / std::max(1e-12, static_cast<double>(p.sigma_z) * p.sigma_z);
    sw[k] += wt;
    swz[k] += wt * p.x_in_site.z();
    swzz[k] += wt * p.x_in_site.z() * p.x_in_site.z();
    ++cnt[k];
  }
  for (size_t k = 0; k < n; ++k) {
    r.bands[kCount][k] = static_cast<float>(cnt[k]);
    if (cnt[k] < min_points_per_cell || sw[k] <= 0) continue;
    const double z = swz[k] / sw[k];
    const double var = std::max(0.0, swzz[k] / sw[k] - z * z);
    r.bands[kHeight][k] = static_cast<float>(z);
    r.bands[kSpread][k] = static_cast<float>(std::sqrt(var));
    // Points closer than a correlation window share pixels: about
    // cnt / points_per_window of them are independent.
    const double n_eff = std::max(1.0, cnt[k] / points_per_window);
    r.bands[kUncertainty][k] =
        static_cast<float>(std::sqrt((1.0 / sw[k]) * (cnt[k] / n_eff) + var / n_eff));
  }
  return r;
}

SurfaceResult MeasureSurface(const OrientedImage& left, const OrientedImage& right,
                             const SurfaceOptions& options, const SurfaceConfig& config,
                             SurfaceSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  options.Check();
  SurfaceSummary sum;
  const RectifiedPair pair =
      Rectify(left, right, config.min_depth, config.max_depth, options.rectify);
  const RectifiedGeometry& g = pair.geometry;
  sum.rectified_overlap = pair.overlap;
  sum.patches = static_cast<int>(pair.patches.size());

  CorrelationOptions copt = options.correlation;
  const double d_near = g.DisparityAtDepth(config.min_depth),
               d_far = g.DisparityAtDepth(config.max_depth);
  copt.min_disparity = std::min(d_near, d_far);
  copt.max_disparity = std::max(d_near, d_far);
  if (copt.max_disparity - copt.min_disparity < 1.0) copt.max_disparity = copt.min_disparity + 1.0;
  const double max_gap = options.max_ray_gap > 0 ? options.max_ray_gap : 10.0 * options.cell_size;

  SurfaceResult result;
  result.geometry = g;
  for (const RectifiedPatch& patch : pair.patches) {
    CorrelationSummary cs;
    const ParallaxGrid grid =
        MatchRectified(patch.left, patch.right, copt, &cs, patch.valid_left, patch.valid_right);
    sum.correlation.levels = cs.levels;
    sum.correlation.nodes += cs.nodes;
    sum.correlation.valid_nodes += cs.valid_nodes;
    sum.correlation.rejected_correlation += cs.rejected_correlation;
    sum.correlation.rejected_order += cs.rejected_order;
    sum.correlation.rejected_left_right += cs.rejected_left_right;
    sum.correlation.seconds += cs.seconds;
    for (int i = 0; i < grid.disparity.rows; ++i)
      for (int j = 0; j < grid.disparity.cols; ++j) {
        if (!grid.Valid(i, j)) continue;
        const double x = patch.roi.x + j * grid.spacing, y = patch.roi.y + i * grid.spacing;
        const double d = grid.disparity.at<float>(i, j);
        double gap;
        const Eigen::Vector3d p = g.Intersect(x, y, d, &gap);
        if (!p.allFinite() || gap > max_gap) {
          ++sum.rejected_points;
          continue;
        }
        SurfacePoint sp;
        sp.x_in_site = p;
        const double depth = (g.site_from_rect.transpose() * (p - g.centre[0])).z();
        sp.sigma_z =
            static_cast<float>(options.parallax_sigma * depth * depth / (g.f * g.baseline));
        sp.correlation = grid.correlation.at<float>(i, j);
        sp.intensity = patch.left.at<float>(i * grid.spacing, j * grid.spacing);
        result.points.push_back(sp);
      }
  }
  sum.points = static_cast<int>(result.points.size());
  if (result.points.empty())
    throw InvalidArgument(Message("dense pair '", left.name, "'/'", right.name,
                                  "': no parallax could be measured (",
                                  sum.correlation.BriefReport(), ")"));
  const int window = copt.final_window > 0 ? copt.final_window : copt.window;
  const double per_window =
      std::max(1.0, std::pow(static_cast<double>(window) / copt.final_grid_spacing, 2));
  result.model = GridSurface(result.points, options.cell_size, options.min_points_per_cell,
                             config.region, per_window);
  sum.cells = result.model.width * result.model.height;
  for (float v : result.model.bands[kHeight]) sum.filled_cells += !result.model.IsNoData(v);
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return result;
}

SurfaceResult MeasureSurfaceToFiles(const OrientedImage& left, const OrientedImage& right,
                                    const SurfaceOptions& options, const SurfaceConfig& config,
                                    const std::string& stem, SurfaceSummary* summary,
                                    const SiteCrs* site) {
  SurfaceResult s = MeasureSurface(left, right, options, config, summary);
  const io::GeoRaster ortho =
      io::MapRasterFromSite(MakeOrthophoto(s.model, left, options.ortho_cell_size), site);
  const io::GeoRaster model = io::MapRasterFromSite(s.model, site);
  const std::string surface_path = stem + "_surface.tif", ortho_path = stem + "_ortho.tif";
  io::WriteGeoTiff(surface_path, model);
  try {
    io::WriteGeoTiff(ortho_path, ortho);
  } catch (...) {
    std::remove(surface_path.c_str());
    throw;
  }
  return s;
}

io::GeoRaster MakeOrthophoto(const io::GeoRaster& model, const OrientedImage& image,
                             double cell_size) {
  if (model.num_bands() < 1) throw InvalidArgument("MakeOrthophoto: surface model has no band");
  if (!image.oriented)
    throw InvalidArgument(Message("MakeOrthophoto: image '", image.name, "' is not oriented"));
  if (cell_size <= 0) cell_size = model.cell_size;
  const double width_m = model.width * model.cell_size, height_m = model.height * model.cell_size;
  const int w = std::max(1, static_cast<int>(std::lround(width_m / cell_size)));
  const int h = std::max(1, static_cast<int>(std::lround(height_m / cell_size)));
  io::GeoRaster ortho(w, h, model.origin_x, model.origin_y, cell_size);
  ortho.epsg = model.epsg;
  ortho.AddBand("gray");
  const cv::Mat gray = ToGrayFloat(image.image, "orthophoto image '" + image.name + "'");
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const Eigen::Vector2d c = ortho.CellCentre(row, col);
      double z = model.Interpolate(kHeight, c.x(), c.y());
      if (std::isnan(z)) {
        // At the model's outer half cell: the nearest cell's height.
        int r, k;
        if (model.CellOf(c.x(), c.y(), &r, &k) && !model.IsNoData(model.At(kHeight, r, k)))
          z = model.At(kHeight, r, k);
      }
      if (std::isnan(z)) continue;
      Eigen::Vector2d px;
      if (!image.camera.Project(image.pose, Eigen::Vector3d(c.x(), c.y(), z), &px)) continue;
      if (!matching::CanSample(gray, px.x(), px.y(), matching::Interpolation::kBilinear)) continue;
      ortho.At(0, row, col) = matching::SampleBilinear(gray, px.x(), px.y());
    }
  return ortho;
}

}  // namespace dense
}  // namespace slope_monitor
