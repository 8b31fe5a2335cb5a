#include "slope_monitor/core/dense/dem_change.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/dense/surface.h"

namespace slope_monitor {
namespace dense {

namespace {

void CheckSameGrid(const io::GeoRaster& a, const io::GeoRaster& b) {
  if (a.width != b.width || a.height != b.height ||
      std::abs(a.origin_x - b.origin_x) > 1e-6 * a.cell_size ||
      std::abs(a.origin_y - b.origin_y) > 1e-6 * a.cell_size ||
      std::abs(a.cell_size - b.cell_size) > 1e-9)
    throw InvalidArgument(Message("DEM change: the DEMs' grids differ (", a.width, "x", a.height,
                                  " at (", a.origin_x, ", ", a.origin_y, ") cell ", a.cell_size,
                                  " m vs ", b.width, "x", b.height, " at (", b.origin_x, ", ",
                                  b.origin_y, ") cell ", b.cell_size, " m)"));
  if (a.num_bands() <= kUncertainty || b.num_bands() <= kUncertainty)
    throw InvalidArgument("DEM change: a DEM lacks the height and uncertainty bands");
}

// Band `band` of `r` at site (x, y): bilinear, else the cell's own value.
double Sample(const io::GeoRaster& r, int band, double x, double y) {
  const double v = r.Interpolate(band, x, y);
  if (!std::isnan(v)) return v;
  int row, col;
  if (!r.CellOf(x, y, &row, &col) || r.IsNoData(r.At(band, row, col))) return NAN;
  return r.At(band, row, col);
}

double Plane(const Coregistration& c, const Eigen::Vector2d& xy) {
  return c.vertical + c.tilt.dot(xy - c.centre);
}

// The after DEM on the reference grid with the co-registration applied.
io::GeoRaster Apply(const io::GeoRaster& after, const Coregistration& c) {
  io::GeoRaster out(after.width, after.height, after.origin_x, after.origin_y, after.cell_size);
  out.epsg = after.epsg;
  out.AddBand("height");
  out.AddBand("uncertainty");
  const bool shifted = c.shift.norm() > 1e-6 * after.cell_size;
  for (int r = 0; r < out.height; ++r)
    for (int k = 0; k < out.width; ++k) {
      const Eigen::Vector2d xy = out.CellCentre(r, k);
      double z = after.At(kHeight, r, k), u = after.At(kUncertainty, r, k);
      if (shifted) {
        z = Sample(after, kHeight, xy.x() + c.shift.x(), xy.y() + c.shift.y());
        u = Sample(after, kUncertainty, xy.x() + c.shift.x(), xy.y() + c.shift.y());
      }
      if (after.IsNoData(z) || after.IsNoData(u) || std::isnan(z) || std::isnan(u)) continue;
      out.At(kHeight, r, k) = static_cast<float>(z - Plane(c, xy));
      out.At(kUncertainty, r, k) = static_cast<float>(u);
    }
  return out;
}

struct StableResiduals {
  std::vector<int> cells;  // row * width + col
  std::vector<double> dz;
  std::vector<bool> inlier;
  double rms = 0.0;      // over inliers
  double mean_u2 = 0.0;  // mean u_ref^2 + u_after^2 over inliers
  int inliers = 0;
};

StableResiduals Residuals(const io::GeoRaster& ref, const io::GeoRaster& aft,
                          const std::vector<uint8_t>& stable, double clip) {
  StableResiduals s;
  for (int i = 0; i < ref.width * ref.height; ++i) {
    if (!stable[i]) continue;
    const float z0 = ref.bands[kHeight][i], z1 = aft.bands[kHeight][i];
    if (ref.IsNoData(z0) || aft.IsNoData(z1)) continue;
    s.cells.push_back(i);
    s.dz.push_back(static_cast<double>(z1) - z0);
  }
  const double med = UpperMedian(s.dz);
  std::vector<double> dev(s.dz.size());
  for (size_t i = 0; i < dev.size(); ++i) dev[i] = std::abs(s.dz[i] - med);
  const double sigma = 1.4826 * UpperMedian(dev);
  double sum2 = 0, sumu = 0;
  for (size_t i = 0; i < s.dz.size(); ++i) {
    const bool in = sigma <= 0 || dev[i] <= clip * sigma;
    s.inlier.push_back(in);
    if (!in) continue;
    ++s.inliers;
    sum2 += s.dz[i] * s.dz[i];
    const double u0 = ref.bands[kUncertainty][s.cells[i]], u1 = aft.bands[kUncertainty][s.cells[i]];
    sumu += u0 * u0 + u1 * u1;
  }
  if (s.inliers > 0) {
    s.rms = std::sqrt(sum2 / s.inliers);
    s.mean_u2 = sumu / s.inliers;
  }
  return s;
}

// Height gradient of the reference at a cell (central, else one-sided differences).
bool Gradient(const io::GeoRaster& r, int row, int col, Eigen::Vector2d* g) {
  auto z = [&](int rr, int cc) -> double {
    if (rr < 0 || cc < 0 || rr >= r.height || cc >= r.width) return NAN;
    const float v = r.At(kHeight, rr, cc);
    return r.IsNoData(v) ? NAN : v;
  };
  auto diff = [&](double minus, double centre, double plus, double* d) {
    if (!std::isnan(minus) && !std::isnan(plus))
      *d = (plus - minus) / (2 * r.cell_size);
    else if (!std::isnan(plus))
      *d = (plus - centre) / r.cell_size;
    else if (!std::isnan(minus))
      *d = (centre - minus) / r.cell_size;
    else
      return false;
    return true;
  };
  const double c = z(row, col);
  // Rows run north to south: +y is row - 1.
  return diff(z(row, col - 1), c, z(row, col + 1), &(*g)[0]) &&
         diff(z(row + 1, col), c, z(row - 1, col), &(*g)[1]);
}

// Exponential correlation range [m] of the inlier residuals: where the
// autocorrelation along rows and columns falls to 1/e.
double CorrelationLength(const io::GeoRaster& grid, const StableResiduals& s, double max_length) {
  std::vector<double> r(static_cast<size_t>(grid.width) * grid.height, NAN);
  double mean = 0;
  for (size_t i = 0; i < s.cells.size(); ++i)
    if (s.inlier[i]) mean += s.dz[i] / s.inliers;
  double var = 0;
  for (size_t i = 0; i < s.cells.size(); ++i)
    if (s.inlier[i]) {
      r[s.cells[i]] = s.dz[i] - mean;
      var += (s.dz[i] - mean) * (s.dz[i] - mean) / s.inliers;
    }
  if (var <= 0) return grid.cell_size;
  const int max_lag = std::max(1, static_cast<int>(max_length / grid.cell_size));
  double previous = 1.0;
  for (int lag = 1; lag <= max_lag; ++lag) {
    double sum = 0;
    int n = 0;
    for (int row = 0; row < grid.height; ++row)
      for (int col = 0; col < grid.width; ++col) {
        const double a = r[static_cast<size_t>(row) * grid.width + col];
        if (std::isnan(a)) continue;
        if (col + lag < grid.width) {
          const double b = r[static_cast<size_t>(row) * grid.width + col + lag];
          if (!std::isnan(b)) sum += a * b, ++n;
        }
        if (row + lag < grid.height) {
          const double b = r[static_cast<size_t>(row + lag) * grid.width + col];
          if (!std::isnan(b)) sum += a * b, ++n;
        }
      }
    if (n < 10) break;
    const double rho = sum / n / var;
    if (rho < std::exp(-1.0))
      return grid.cell_size *
             (lag - 1 + (previous - std::exp(-1.0)) / std::max(1e-12, previous - rho));
    previous = rho;
  }
  return max_length;
}

double CorrelatedCells(double length, double cell_area) {
  return std::max(1.0, 2 * M_PI * length * length / cell_area);
}

// Normal equations of the co-registration step over the stable inliers:
// unknowns (shift x, shift y, vertical, tilt x, tilt y), one row per cell
// with a gradient of the reference, right-hand side its dz.
void StableNormals(const io::GeoRaster& reference, const StableResiduals& s,
                   const Coregistration& c, Eigen::Matrix<double, 5, 5>* n,
                   Eigen::Matrix<double, 5, 1>* b) {
  n->setZero();
  b->setZero();
  for (size_t i = 0; i < s.cells.size(); ++i) {
    if (!s.inlier[i]) continue;
    const int row = s.cells[i] / reference.width, col = s.cells[i] % reference.width;
    Eigen::Vector2d g;
    if (!Gradient(reference, row, col, &g)) continue;
    const Eigen::Vector2d xy = reference.CellCentre(row, col) - c.centre;
    Eigen::Matrix<double, 5, 1> a;
    a << -g.x(), -g.y(), 1.0, xy.x(), xy.y();
    *n += a * a.transpose();
    *b += a * s.dz[i];
  }
}

// 1-sigma of the horizontal shift at the final state (see Coregistration::shift_sigma).
Eigen::Vector2d ShiftSigma(const io::GeoRaster& reference, const StableResiduals& s,
                           const Coregistration& c, double correlated_cells) {
  Eigen::Matrix<double, 5, 5> n;
  Eigen::Matrix<double, 5, 1> b;
  StableNormals(reference, s, c, &n, &b);
  const double inf = std::numeric_limits<double>::infinity();
  Eigen::FullPivLU<Eigen::Matrix<double, 5, 5>> lu(n);
  if (lu.rank() < 5) return Eigen::Vector2d(inf, inf);
  const Eigen::Matrix<double, 5, 5> q = lu.inverse();
  const double v = s.rms * s.rms * correlated_cells;
  return Eigen::Vector2d(std::sqrt(std::max(0.0, v * q(0, 0))),
                         std::sqrt(std::max(0.0, v * q(1, 1))));
}

// Predictors of the error model at every cell with a reference height:
// slope [deg] of the least-squares plane of the heights in the (2r+1)^2
// window and roughness [m], their RMS about it (with fewer than 4 heights
// or a degenerate window: the cell's own gradient and 0). NaN elsewhere.
void Predictors(const io::GeoRaster& ref, int radius, std::vector<double>* slope,
                std::vector<double>* roughness) {
  const size_t n = static_cast<size_t>(ref.width) * ref.height;
  slope->assign(n, NAN);
  roughness->assign(n, NAN);
  for (int row = 0; row < ref.height; ++row)
    for (int col = 0; col < ref.width; ++col) {
      const size_t i = static_cast<size_t>(row) * ref.width + col;
      if (ref.IsNoData(ref.bands[kHeight][i])) continue;
      Eigen::Vector2d g;
      (*slope)[i] = Gradient(ref, row, col, &g) ? std::atan(g.norm()) * kDegPerRad : 0.0;
      Eigen::Matrix3d n3 = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      double zz = 0, z0 = ref.bands[kHeight][i];
      int count = 0;
      for (int dr = -radius; dr <= radius; ++dr)
        for (int dc = -radius; dc <= radius; ++dc) {
          const int rr = row + dr, cc = col + dc;
          if (rr < 0 || cc < 0 || rr >= ref.height || cc >= ref.width) continue;
          const float v = ref.At(kHeight, rr, cc);
          if (ref.IsNoData(v)) continue;
          const Eigen::Vector3d a(1.0, dc, dr);
          const double z = v - z0;
          n3 += a * a.transpose();
          b += a * z;
          zz += z * z;
          ++count;
        }
      if (count < 4) {
        (*roughness)[i] = 0.0;
        continue;
      }
      Eigen::FullPivLU<Eigen::Matrix3d> lu(n3);
      if (lu.rank() < 3) {
        (*roughness)[i] = 0.0;
        continue;
      }
      const Eigen::Vector3d plane = lu.solve(b);
      (*roughness)[i] = std::sqrt(std::max(0.0, zz - b.dot(plane)) / count);
      // The window's plane: a slope less noisy than the cell's own differences.
      (*slope)[i] = std::atan(plane.tail<2>().norm() / ref.cell_size) * kDegPerRad;
    }
}

struct ModelSample {
  double slope, roughness, dz;
};

// The bin's spread (ErrorModelOptions::spread) of dz about `median`.
double Spread(const std::vector<double>& dz, double median, const ErrorModelOptions& o,
              double lod_factor) {
  std::vector<double> dev(dz.size());
  for (size_t i = 0; i < dz.size(); ++i) dev[i] = std::abs(dz[i] - median);
  if (o.spread == ErrorModelOptions::Spread::kNmad) return 1.4826 * UpperMedian(dev);
  const double coverage = std::erf(lod_factor / std::sqrt(2.0));
  const size_t k = std::min(dev.size() - 1, static_cast<size_t>(coverage * dev.size()));
  std::nth_element(dev.begin(), dev.begin() + k, dev.end());
  return dev[k] / lod_factor;
}

// Equal-count bins by slope, then by roughness within each slope bin; fewer
// bins when there are fewer than min_bin_cells per bin.
ErrorModel FitErrorModel(std::vector<ModelSample> s, const ErrorModelOptions& o,
                         double lod_factor) {
  ErrorModel m;
  const int n = static_cast<int>(s.size());
  int ns = o.slope_bins, nr = o.roughness_bins;
  while (ns * nr > 1 && ns * nr * o.min_bin_cells > n) (ns >= nr ? ns : nr) -= 1;
  if (n < o.min_bin_cells || n == 0) return m;
  m.slope_bins = ns;
  m.roughness_bins = nr;
  std::sort(s.begin(), s.end(),
            [](const ModelSample& a, const ModelSample& b) { return a.slope < b.slope; });
  for (int i = 0; i < ns; ++i) {
    const auto b0 = s.begin() + static_cast<long>(n) * i / ns;
    const auto b1 = s.begin() + static_cast<long>(n) * (i + 1) / ns;
    std::vector<double> slopes;
    for (auto it = b0; it != b1; ++it) slopes.push_back(it->slope);
    const double slope_median = UpperMedian(slopes);
    std::sort(b0, b1,
              [](const ModelSample& a, const ModelSample& b) { return a.roughness < b.roughness; });
    const long m_i = b1 - b0;
    for (int j = 0; j < nr; ++j) {
      const auto c0 = b0 + m_i * j / nr, c1 = b0 + m_i * (j + 1) / nr;
      ErrorBin bin;
      bin.slope = slope_median;
      bin.slope_min = *std::min_element(slopes.begin(), slopes.end());
      bin.slope_max = *std::max_element(slopes.begin(), slopes.end());
      std::vector<double> rough, dz;
      for (auto it = c0; it != c1; ++it) rough.push_back(it->roughness), dz.push_back(it->dz);
      bin.cells = static_cast<int>(dz.size());  // >= min_bin_cells (the loop above)
      bin.roughness = UpperMedian(rough);
      bin.roughness_min = rough.front();
      bin.roughness_max = rough.back();
      bin.median = UpperMedian(dz);
      bin.sigma = Spread(dz, bin.median, o, lod_factor);
      m.bins.push_back(bin);
    }
  }
  return m;
}

// Linear weights of `x` between sorted `centres` (clamped outside).
void Bracket(const std::vector<double>& centres, double x, int* i0, int* i1, double* w1) {
  const int n = static_cast<int>(centres.size());
  *i0 = *i1 = 0;
  *w1 = 0.0;
  if (n == 0 || x <= centres.front()) return;
  if (x >= centres.back()) {
    *i0 = *i1 = n - 1;
    return;
  }
  int k = static_cast<int>(std::upper_bound(centres.begin(), centres.end(), x) - centres.begin());
  *i0 = k - 1;
  *i1 = k;
  const double d = centres[k] - centres[k - 1];
  *w1 = d > 0 ? (x - centres[k - 1]) / d : 0.0;
}

// Per-cell model sigma of the compared cells (0 where no model or no predictor).
std::vector<double> ModelSigma(const ErrorModel& m, const std::vector<double>& slope,
                               const std::vector<double>& roughness) {
  std::vector<double> out(slope.size(), 0.0);
  if (m.empty()) return out;
  for (size_t i = 0; i < out.size(); ++i)
    if (!std::isnan(slope[i])) out[i] = m.Sigma(slope[i], roughness[i]);
  return out;
}

}  // namespace

double ErrorModel::Sigma(double slope_deg, double roughness) const {
  if (bins.empty()) return 0.0;
  std::vector<double> sc;
  sc.reserve(static_cast<size_t>(slope_bins));
  for (int i = 0; i < slope_bins; ++i)
    sc.push_back(bins[static_cast<size_t>(i) * roughness_bins].slope);
  int i0, i1;
  double w;
  Bracket(sc, slope_deg, &i0, &i1, &w);
  auto along_roughness = [&](int i) {
    std::vector<double> rc;
    rc.reserve(static_cast<size_t>(roughness_bins));
    for (int j = 0; j < roughness_bins; ++j)
      rc.push_back(bins[static_cast<size_t>(i) * roughness_bins + j].roughness);
    int j0, j1;
    double v;
    Bracket(rc, roughness, &j0, &j1, &v);
    const size_t b = static_cast<size_t>(i) * roughness_bins;
    return (1 - v) * bins[b + j0].sigma + v * bins[b + j1].sigma;
  };
  return (1 - w) * along_roughness(i0) + w * along_roughness(i1);
}

void ErrorModelOptions::Check() const {
  RequireOption("DEM change", slope_bins >= 1 && slope_bins <= 50, "error_model.slope_bins",
                Message("= ", slope_bins, " must be in [1, 50]"));
  RequireOption("DEM change", roughness_bins >= 1 && roughness_bins <= 50,
                "error_model.roughness_bins", Message("= ", roughness_bins, " must be in [1, 50]"));
  RequireOption("DEM change", roughness_radius >= 1 && roughness_radius <= 20,
                "error_model.roughness_radius",
                Message("= ", roughness_radius, " must be in [1, 20]"));
  RequireOption("DEM change", min_bin_cells >= 5, "error_model.min_bin_cells",
                Message("= ", min_bin_cells, " must be >= 5"));
  RequireOption("DEM change", holdout_block >= 0, "error_model.holdout_block",
                Message("= ", holdout_block, " m must be >= 0"));
}

void DemChangeOptions::Check() const {
  error_model.Check();
  RequireOption("DEM change", lod_factor > 0 && lod_factor <= 10, "lod_factor",
                Message("= ", lod_factor, " must be in (0, 10]"));
  RequireOption("DEM change", coregistration_iterations >= 0 && coregistration_iterations <= 20,
                "coregistration_iterations",
                Message("= ", coregistration_iterations, " must be in [0, 20]"));
  RequireOption("DEM change", clip_sigmas >= 1 && clip_sigmas <= 10, "clip_sigmas",
                Message("= ", clip_sigmas, " must be in [1, 10]"));
  RequireOption("DEM change", max_shift > 0, "max_shift",
                Message("= ", max_shift, " m must be > 0"));
  RequireOption("DEM change", min_stable_cells >= 4, "min_stable_cells",
                Message("= ", min_stable_cells, " must be >= 4"));
  RequireOption("DEM change", max_correlation_length > 0, "max_correlation_length",
                Message("= ", max_correlation_length, " m must be > 0"));
}

std::string DemChangeSummary::BriefReport() const {
  const Coregistration& c = coregistration;
  std::ostringstream s;
  s << "co-registration on " << c.inliers << "/" << c.stable_cells << " stable cells: shift ("
    << c.shift.x() << ", " << c.shift.y() << ") m, vertical " << c.vertical << " m, tilt ("
    << c.tilt.x() << ", " << c.tilt.y() << "), residual " << c.residual_before << " -> "
    << c.residual << " m RMS, L " << c.correlation_length << " m; " << cells_compared
    << " cells compared (" << cells_missing << " missing), inside the outline " << cells_inside
    << " (" << cells_significant << " significant); net " << volume_net << " +- " << sigma_net
    << " m3, fill " << volume_fill << " +- " << sigma_fill << " m3, cut " << volume_cut << " +- "
    << sigma_cut << " m3 (1 sigma)";
  return s.str();
}

std::vector<uint8_t> StableMask(const io::GeoRaster& grid, const std::vector<Polygon>& outlines,
                                const std::vector<uint8_t>& mask, const std::string& mask_name) {
  const size_t n = static_cast<size_t>(grid.width) * grid.height;
  if (!mask.empty() && mask.size() != n)
    throw InvalidArgument(Message("stable mask '", mask_name, "' has ", mask.size(),
                                  " cells, the DEM grid ", grid.width, " x ", grid.height, " = ",
                                  n));
  std::vector<std::vector<cv::Point2f>> polys;
  for (const Polygon& p : outlines) {
    polys.emplace_back();
    for (const Eigen::Vector2d& v : p)
      polys.back().emplace_back(static_cast<float>(v.x()), static_cast<float>(v.y()));
  }
  std::vector<uint8_t> stable(n, 1);
  for (int r = 0; r < grid.height; ++r)
    for (int k = 0; k < grid.width; ++k) {
      const size_t i = static_cast<size_t>(r) * grid.width + k;
      const Eigen::Vector2d xy = grid.CellCentre(r, k);
      if (!mask.empty() && !mask[i]) stable[i] = 0;
      for (const auto& p : polys)
        if (p.size() >= 3 && cv::pointPolygonTest(p, cv::Point2f(xy.x(), xy.y()), false) >= 0)
          stable[i] = 0;
    }
  return stable;
}

Coregistration Coregister(const io::GeoRaster& reference, const io::GeoRaster& after,
                          const std::vector<uint8_t>& stable, const DemChangeOptions& o) {
  o.Check();
  CheckSameGrid(reference, after);
  if (stable.size() != reference.bands[kHeight].size())
    throw InvalidArgument(Message("co-registration: stable mask of ", stable.size(),
                                  " cells for a grid of ", reference.bands[kHeight].size()));
  Coregistration c;
  c.centre = reference.CellCentre(reference.height / 2, reference.width / 2);
  StableResiduals s = Residuals(reference, Apply(after, c), stable, o.clip_sigmas);
  c.stable_cells = static_cast<int>(s.cells.size());
  c.residual_before = s.rms;
  if (s.inliers < o.min_stable_cells)
    throw InvalidArgument(
        Message("co-registration: only ", s.inliers, " stable cells (outside the monitored ",
                "outline and inside the stable mask) have a height in both DEMs; need ",
                o.min_stable_cells, " (min_stable_cells)"));
  for (int it = 0; it < o.coregistration_iterations; ++it) {
    Eigen::Matrix<double, 5, 5> n;
    Eigen::Matrix<double, 5, 1> b;
    StableNormals(reference, s, c, &n, &b);
    // Ridge on the shift: a direction the terrain does not reveal stays put.
    const double ridge = 0.05 * (n(0, 0) + n(1, 1)) / 2 + 1e-9;
    n(0, 0) += ridge;
    n(1, 1) += ridge;
    const Eigen::Matrix<double, 5, 1> d = n.ldlt().solve(b);
    if (!d.allFinite()) break;
    const Eigen::Vector2d ds = d.head<2>();
    c.vertical += c.tilt.dot(ds) + d[2] + d.tail<2>().dot(ds);
    c.tilt += d.tail<2>();
    c.shift += ds;
    if (c.shift.norm() > o.max_shift)
      throw InvalidArgument(Message("co-registration: horizontal shift ", c.shift.norm(),
                                    " m exceeds max_shift ", o.max_shift,
                                    " m (the epochs do not match on stable ground)"));
    s = Residuals(reference, Apply(after, c), stable, o.clip_sigmas);
  }
  c.inliers = s.inliers;
  c.residual = s.rms;
  c.correlation_length = CorrelationLength(reference, s, o.max_correlation_length);
  const double area = reference.cell_size * reference.cell_size;
  c.level_sigma =
      s.rms / std::sqrt(std::max(1.0, s.inliers / CorrelatedCells(c.correlation_length, area)));
  c.shift_sigma = ShiftSigma(reference, s, c, CorrelatedCells(c.correlation_length, area));
  return c;
}

DemChangeResult DemChange(const io::GeoRaster& reference, const io::GeoRaster& after,
                          const std::vector<Polygon>& outlines, const std::vector<uint8_t>& stable,
                          const DemChangeOptions& o) {
  DemChangeResult out;
  DemChangeSummary& sum = out.summary;
  Coregistration& c = sum.coregistration;
  c = Coregister(reference, after, stable, o);
  out.after_coregistered = Apply(after, c);
  const io::GeoRaster& a = out.after_coregistered;
  const StableResiduals s = Residuals(reference, a, stable, o.clip_sigmas);
  sum.sigma_extra = std::sqrt(std::max(0.0, s.rms * s.rms - s.mean_u2));

  io::GeoRaster& ch = out.change;
  ch = io::GeoRaster(reference.width, reference.height, reference.origin_x, reference.origin_y,
                     reference.cell_size);
  ch.epsg = reference.epsg;
  ch.AddBand("change");
  ch.AddBand("lod");
  ch.AddBand("class");
  // No outline: the whole DEM is the monitored area.
  const std::vector<uint8_t> outside = outlines.empty()
                                           ? std::vector<uint8_t>(ch.bands[kChange].size(), 0)
                                           : StableMask(reference, outlines, {}, "");
  const double area = reference.cell_size * reference.cell_size;
  // The heteroscedastic model (file comment): predictors, the stable cells'
  // dz (unclipped: every stable cell counts), the model on all of them and
  // the two-fold held-out check on a checkerboard of blocks.
  std::vector<double> model_sigma;
  if (o.error_model.enabled) {
    const ErrorModelOptions& e = o.error_model;
    std::vector<double> slope, roughness;
    Predictors(reference, e.roughness_radius, &slope, &roughness);
    const double block_m = e.holdout_block > 0 ? e.holdout_block : 4 * c.correlation_length;
    const int block = std::max(8, static_cast<int>(std::ceil(block_m / reference.cell_size)));
    sum.holdout_block = block * reference.cell_size;
    std::vector<ModelSample> all, fold[2];
    std::vector<double> fold_u2[2];
    for (size_t i = 0; i < s.cells.size(); ++i) {
      const size_t k = s.cells[i];
      if (std::isnan(slope[k])) continue;
      const float u0 = reference.bands[kUncertainty][k], u1 = a.bands[kUncertainty][k];
      if (reference.IsNoData(u0) || a.IsNoData(u1)) continue;
      const ModelSample m{slope[k], roughness[k], s.dz[i]};
      all.push_back(m);
      const int row = static_cast<int>(k) / reference.width,
                col = static_cast<int>(k) % reference.width;
      const int f = (row / block + col / block) % 2;
      fold[f].push_back(m);
      fold_u2[f].push_back(static_cast<double>(u0) * u0 + static_cast<double>(u1) * u1);
    }
    sum.error_model = FitErrorModel(all, e, o.lod_factor);
    int flagged = 0;
    for (int f = 0; f < 2; ++f) {
      const ErrorModel other = FitErrorModel(fold[1 - f], e, o.lod_factor);
      if (other.empty() || fold[f].empty()) continue;
      for (size_t i = 0; i < fold[f].size(); ++i) {
        const double sg =
            std::max(other.Sigma(fold[f][i].slope, fold[f][i].roughness), std::sqrt(fold_u2[f][i]));
        flagged += std::abs(fold[f][i].dz) > o.lod_factor * sg;
        ++sum.holdout_cells;
      }
    }
    sum.holdout_flagged =
        sum.holdout_cells > 0 ? static_cast<double>(flagged) / sum.holdout_cells : 0.0;
    if (!sum.error_model.empty()) model_sigma = ModelSigma(sum.error_model, slope, roughness);
  }
  double var_net = 0, var_fill = 0, var_cut = 0;
  int n_fill = 0, n_cut = 0;
  for (size_t i = 0; i < ch.bands[kChange].size(); ++i) {
    const float z0 = reference.bands[kHeight][i], z1 = a.bands[kHeight][i];
    const float u0 = reference.bands[kUncertainty][i], u1 = a.bands[kUncertainty][i];
    if (reference.IsNoData(z0) || a.IsNoData(z1) || reference.IsNoData(u0) || a.IsNoData(u1)) {
      ++sum.cells_missing;
      continue;
    }
    ++sum.cells_compared;
    const double dz = static_cast<double>(z1) - z0;
    const double u2 = static_cast<double>(u0) * u0 + static_cast<double>(u1) * u1;
    const double var = model_sigma.empty() ? u2 + sum.sigma_extra * sum.sigma_extra
                                           : std::max(model_sigma[i] * model_sigma[i], u2);
    const double lod = o.lod_factor * std::sqrt(var);
    const int cls = std::abs(dz) > 2 * lod ? 2 : std::abs(dz) > lod ? 1 : 0;
    ch.bands[kChange][i] = static_cast<float>(dz);
    ch.bands[kLodBand][i] = static_cast<float>(lod);
    ch.bands[kClass][i] = static_cast<float>(dz < 0 ? -cls : cls);
    if (outside[i]) continue;
    ++sum.cells_inside;
    sum.volume_net += dz * area;
    var_net += var * area * area;
    if (cls == 0) continue;
    ++sum.cells_significant;
    if (dz > 0) {
      sum.volume_fill += dz * area, var_fill += var * area * area, ++n_fill;
    } else {
      sum.volume_cut -= dz * area, var_cut += var * area * area, ++n_cut;
    }
  }
  // Random part correlated over L, systematic level error over the whole area.
  const double m = CorrelatedCells(c.correlation_length, area);
  auto sigma = [&](double var_sum, int cells) {
    const double sys = c.level_sigma * cells * area;
    return std::sqrt(var_sum * std::min<double>(std::max(cells, 1), m) + sys * sys);
  };
  sum.sigma_net = sigma(var_net, sum.cells_inside);
  sum.sigma_fill = sigma(var_fill, n_fill);
  sum.sigma_cut = sigma(var_cut, n_cut);
  return out;
}

}  // namespace dense
}  // namespace slope_monitor
