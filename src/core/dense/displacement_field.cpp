#include "slope_monitor/core/dense/displacement_field.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace dense {
namespace {

constexpr double kPixelStep = 0.25;   // [px] numeric derivative steps
constexpr double kAngleStep = 1e-6;   // [rad]
constexpr double kHeightStep = 0.05;  // [m]

// A coordinate for messages: metres with one decimal, never in exponent form.
std::string Metres(double v) {
  char b[64];
  std::snprintf(b, sizeof(b), "%.1f", v);
  return b;
}

// Surface height at (x, y) shifted by dh; NaN outside or on nodata.
double Height(const io::GeoRaster& dem, double x, double y, double dh) {
  return dem.Interpolate(0, x, y) + dh;
}

// The ray's parameter interval inside the DEM's footprint (xy box), or false.
bool ClipToDem(const io::GeoRaster& dem, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
               double max_range, double* t0, double* t1) {
  const double lo[2] = {dem.origin_x, dem.origin_y - dem.height * dem.cell_size};
  const double hi[2] = {dem.origin_x + dem.width * dem.cell_size, dem.origin_y};
  *t0 = 0.0;
  *t1 = max_range;
  for (int k = 0; k < 2; ++k) {
    if (std::abs(d(k)) < 1e-15) {
      if (o(k) < lo[k] || o(k) > hi[k]) return false;
      continue;
    }
    double a = (lo[k] - o(k)) / d(k), b = (hi[k] - o(k)) / d(k);
    if (a > b) std::swap(a, b);
    *t0 = std::max(*t0, a);
    *t1 = std::min(*t1, b);
  }
  return *t0 < *t1;
}

// First crossing of the ray below the DEM (shifted by dh): marched at half a
// cell, then bisected.
bool Intersect(const io::GeoRaster& dem, const Eigen::Vector3d& o, const Eigen::Vector3d& d,
               double max_range, double dh, double* t) {
  double t0, t1;
  if (!ClipToDem(dem, o, d, max_range, &t0, &t1)) return false;
  const double step = 0.5 * dem.cell_size;
  auto above = [&](double s, bool* valid) {
    const Eigen::Vector3d p = o + s * d;
    const double h = Height(dem, p.x(), p.y(), dh);
    *valid = std::isfinite(h);
    return p.z() - h;
  };
  bool prev_valid = false;
  double prev_f = 0.0, prev_t = t0;
  for (double s = t0; s <= t1; s += step) {
    bool valid;
    const double f = above(s, &valid);
    if (valid && prev_valid && prev_f > 0.0 && f <= 0.0) {
      double a = prev_t, b = s;
      for (int i = 0; i < 60 && b - a > 1e-9; ++i) {
        const double m = 0.5 * (a + b);
        bool v;
        const double fm = above(m, &v);
        if (v && fm > 0.0)
          a = m;
        else
          b = m;
      }
      *t = 0.5 * (a + b);
      return true;
    }
    if (valid && f <= 0.0 && !prev_valid && s == t0) return false;  // starts under the surface
    prev_valid = valid;
    prev_f = f;
    prev_t = s;
  }
  return false;
}

// Site point where pixel x of (model, pose) meets the DEM (shifted by dh).
bool PixelOnDem(const io::GeoRaster& dem, const camera::CameraModel& model,
                const camera::ExteriorOrientation& pose, const Eigen::Vector2d& x, double dh,
                double max_range, Eigen::Vector3d* p) {
  const camera::Ray ray = model.ImageToRay(pose, x);
  const Eigen::Vector3d d = ray.direction.normalized();
  double t;
  if (!Intersect(dem, ray.origin, d, max_range, dh, &t)) return false;
  *p = ray.origin + t * d;
  return true;
}

// Unit upward normal of the DEM at (x, y) from central differences.
Eigen::Vector3d DemNormal(const io::GeoRaster& dem, double x, double y) {
  const double s = dem.cell_size;
  const double hx = (dem.Interpolate(0, x + s, y) - dem.Interpolate(0, x - s, y)) / (2 * s);
  const double hy = (dem.Interpolate(0, x, y + s) - dem.Interpolate(0, x, y - s)) / (2 * s);
  if (!std::isfinite(hx) || !std::isfinite(hy)) return Eigen::Vector3d::UnitZ();
  return Eigen::Vector3d(-hx, -hy, 1.0).normalized();
}

// Probe pixels of the reference photo.
std::vector<Eigen::Vector2d> Probes(const io::GeoRaster& dem, const FieldInput& in,
                                    const DisplacementFieldOptions& o) {
  const camera::Sensor& s = in.model.sensor();
  auto inside = [&](const Eigen::Vector2d& x) {
    return x.x() >= o.border_px && x.y() >= o.border_px && x.x() <= s.width - 1 - o.border_px &&
           x.y() <= s.height - 1 - o.border_px &&
           (!in.monitored || in.monitored(x) || (in.stable && in.stable(x)));
  };
  std::vector<Eigen::Vector2d> probes;
  if (o.spacing_m > 0) {
    const int step = std::max(1, static_cast<int>(std::lround(o.spacing_m / dem.cell_size)));
    for (int r = 0; r < dem.height; r += step)
      for (int c = 0; c < dem.width; c += step) {
        const Eigen::Vector2d xy = dem.CellCentre(r, c);
        const double h = dem.Interpolate(0, xy.x(), xy.y());
        if (!std::isfinite(h)) continue;
        Eigen::Vector2d px;
        if (!in.model.Project(in.reference, Eigen::Vector3d(xy.x(), xy.y(), h), &px) || !inside(px))
          continue;
        probes.push_back(px);
      }
    return probes;
  }
  for (double v = o.border_px; v <= s.height - 1 - o.border_px; v += o.spacing_px)
    for (double u = o.border_px; u <= s.width - 1 - o.border_px; u += o.spacing_px)
      if (inside({u, v})) probes.emplace_back(u, v);
  return probes;
}

// Displacement of one matched probe: d, its covariance and the flags.
void Project(const io::GeoRaster& dem, const FieldInput& in, const DisplacementFieldOptions& o,
             const Eigen::Vector3d& x_ref, FieldPoint* p) {
  const double max_range = o.max_range;
  auto on_dem = [&](const Eigen::Vector2d& xb, const Eigen::Vector3d& angles, double dh,
                    Eigen::Vector3d* x) {
    camera::ExteriorOrientation pose = in.current;
    pose.angles.theta = angles(0);
    pose.angles.phi = angles(1);
    pose.angles.kappa = angles(2);
    return PixelOnDem(in.current_dem ? *in.current_dem : dem, in.model, pose, xb, dh, max_range, x);
  };
  const Eigen::Vector3d angles(in.current.angles.theta, in.current.angles.phi,
                               in.current.angles.kappa);
  Eigen::Vector3d x_new;
  if (!on_dem(p->xb, angles, 0.0, &x_new)) {
    p->flag = "no_surface";
    return;
  }
  p->displacement = x_new - x_ref;
  // Jacobians by central differences: d(x_new)/d(xb), d(x_new)/d(angles), d(d)/d(dh).
  Eigen::Matrix<double, 3, 2> j_xb;
  Eigen::Matrix3d j_att;
  for (int k = 0; k < 2; ++k) {
    Eigen::Vector2d e = Eigen::Vector2d::Zero();
    e(k) = kPixelStep;
    Eigen::Vector3d a, b;
    if (!on_dem(p->xb + e, angles, 0.0, &a) || !on_dem(p->xb - e, angles, 0.0, &b)) {
      p->flag = "no_surface";
      return;
    }
    j_xb.col(k) = (a - b) / (2 * kPixelStep);
  }
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e(k) = kAngleStep;
    Eigen::Vector3d a, b;
    if (!on_dem(p->xb, angles + e, 0.0, &a) || !on_dem(p->xb, angles - e, 0.0, &b)) {
      p->flag = "no_surface";
      return;
    }
    j_att.col(k) = (a - b) / (2 * kAngleStep);
  }
  Eigen::Vector3d ra, rb, na, nb;
  if (!PixelOnDem(dem, in.model, in.reference, p->xa, kHeightStep, max_range, &ra) ||
      !PixelOnDem(dem, in.model, in.reference, p->xa, -kHeightStep, max_range, &rb) ||
      !on_dem(p->xb, angles, kHeightStep, &na) || !on_dem(p->xb, angles, -kHeightStep, &nb)) {
    p->flag = "no_surface";
    return;
  }
  const Eigen::Vector3d j_h = ((na - ra) - (nb - rb)) / (2 * kHeightStep);
  double dem_sigma = o.dem_sigma;
  const int sigma_band = dem.BandIndex("sigma");
  if (sigma_band >= 0) {
    const double s = dem.Interpolate(sigma_band, x_ref.x(), x_ref.y());
    if (std::isfinite(s)) dem_sigma = s;
  }
  p->covariance = j_xb * p->covariance_px * j_xb.transpose() +
                  j_att * in.attitude_covariance * j_att.transpose() +
                  j_h * j_h.transpose() * dem_sigma * dem_sigma;
  if (in.dt != 0) p->velocity = p->displacement / in.dt;

  // Geometry of the view: incidence on the surface, displacement vs line of sight.
  const Eigen::Vector3d los = (x_ref - in.reference.position).normalized();
  const Eigen::Vector3d n = DemNormal(dem, x_ref.x(), x_ref.y());
  p->incidence_deg = std::asin(std::min(1.0, std::abs(los.dot(n)))) * kDegPerRad;
  const double norm = p->displacement.norm();
  if (norm > 0) {
    const Eigen::Vector3d u = p->displacement / norm;
    p->los_angle_deg = std::acos(std::min(1.0, std::abs(u.dot(los)))) * kDegPerRad;
    const double sigma_along = std::sqrt(std::max(0.0, u.dot(p->covariance * u)));
    if (p->los_angle_deg < o.min_los_angle_deg && norm > 3.0 * sigma_along)
      p->flag = "line_of_sight";
  }
  if (p->incidence_deg < o.min_incidence_deg) p->flag = "grazing";
}

// The LSC covariance scaled to what the stable ground shows: the median of
// r^T C^-1 r (r = xb - predicted, C the LSC covariance) over the usable probes
// on stable ground, over the median of chi^2 with 2 degrees of freedom
// (2 ln 2); at least 1, and 1 with fewer than min_stable_probes of them.
double StableVarianceFactor(const std::vector<FieldPoint>& points,
                            const std::vector<Eigen::Vector2d>& predicted, const FieldInput& in,
                            const DisplacementFieldOptions& o) {
  if (!in.stable) return 1.0;
  std::vector<double> q;
  for (size_t i = 0; i < points.size(); ++i) {
    const FieldPoint& p = points[i];
    if (!p.IsUsable() || !p.stable || p.covariance_px.determinant() <= 0) continue;
    const Eigen::Vector2d r = p.xb - predicted[i];
    q.push_back(r.dot(p.covariance_px.inverse() * r));
  }
  if (static_cast<int>(q.size()) < o.min_stable_probes) return 1.0;
  std::nth_element(q.begin(), q.begin() + q.size() / 2, q.end());
  return std::max(1.0, q[q.size() / 2] / (2.0 * std::log(2.0)));
}

// "inconsistent": a usable probe whose horizontal displacement differs from
// the median of its usable neighbours on the ground (within 1.5 x the median
// nearest-neighbour distance; at least 3) by more than max_sigma x its sigma
// in x or y. Such a probe sees motion that differs from its surroundings: a
// match pulled by the moving part of its window at a body's margin, or a
// blunder; its LSC covariance does not know it.
void FlagInconsistent(double max_sigma, std::vector<FieldPoint>* points) {
  if (max_sigma <= 0) return;
  std::vector<size_t> usable;
  for (size_t i = 0; i < points->size(); ++i)
    if ((*points)[i].IsUsable()) usable.push_back(i);
  if (usable.size() < 4) return;
  auto ground = [&](size_t i) { return (*points)[i].x_ref.head<2>(); };
  std::vector<double> nearest;
  for (size_t i : usable) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t j : usable)
      if (j != i) best = std::min(best, (ground(i) - ground(j)).norm());
    nearest.push_back(best);
  }
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  const double radius = 1.5 * nearest[nearest.size() / 2];
  std::vector<std::string> flags(points->size());
  for (size_t i : usable) {
    std::vector<double> dx, dy;
    for (size_t j : usable) {
      if (j == i || (ground(i) - ground(j)).norm() > radius) continue;
      dx.push_back((*points)[j].displacement.x());
      dy.push_back((*points)[j].displacement.y());
    }
    if (dx.size() < 3) continue;
    std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
    std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
    const FieldPoint& p = (*points)[i];
    const Eigen::Vector3d s = p.Sigma();
    if (std::abs(p.displacement.x() - dx[dx.size() / 2]) > max_sigma * s.x() ||
        std::abs(p.displacement.y() - dy[dy.size() / 2]) > max_sigma * s.y())
      flags[i] = "inconsistent";
  }
  for (size_t i : usable)
    if (!flags[i].empty()) (*points)[i].flag = flags[i];
}

}  // namespace

// The window-straddle term: a usable probe whose LSC window (half width h
// px) sees ground that moves differently. For each usable neighbour j
// (within 1.5 x the median nearest-neighbour distance in the reference
// photo, r_ij px) whose displacement differs from the probe's by Delta
// significantly in the horizontal (|Delta_xy| > min_sigma x its sigma,
// sqrt(u^T (C_i + C_j) u), u = Delta_xy / |Delta_xy|), the motion changes
// across the probe's window by about w = Delta min(1, h / r_ij) (linear
// between the probes). LSC then returns a texture-weighted blend of the
// window's motions, not the centre's. The motion over the window spans
// -w..w; its variance, that of a uniform spread, w w^T / 3 of the largest
// such w, is added to the probe's covariance (returned per probe, zero where
// no neighbour differs significantly).
std::vector<Eigen::Matrix3d> WindowStraddleTerms(double min_sigma, int half_window,
                                                 const std::vector<FieldPoint>& points) {
  std::vector<Eigen::Matrix3d> terms(points.size(), Eigen::Matrix3d::Zero());
  if (min_sigma <= 0) return terms;
  std::vector<size_t> usable;
  for (size_t i = 0; i < points.size(); ++i)
    if (points[i].IsUsable()) usable.push_back(i);
  if (usable.size() < 2) return terms;
  std::vector<double> nearest;
  for (size_t i : usable) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t j : usable)
      if (j != i) best = std::min(best, (points[i].xa - points[j].xa).norm());
    nearest.push_back(best);
  }
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  const double radius = 1.5 * nearest[nearest.size() / 2];
  for (size_t i : usable) {
    const FieldPoint& p = points[i];
    Eigen::Vector3d largest = Eigen::Vector3d::Zero();
    for (size_t j : usable) {
      const double r = (p.xa - points[j].xa).norm();
      if (j == i || r > radius) continue;
      const FieldPoint& q = points[j];
      const Eigen::Vector3d delta = q.displacement - p.displacement;
      const double norm = delta.head<2>().norm();
      if (norm <= 0) continue;
      const Eigen::Vector2d u = delta.head<2>() / norm;
      const double var = u.dot((p.covariance + q.covariance).topLeftCorner<2, 2>() * u);
      const Eigen::Vector3d w = delta * std::min(1.0, half_window / r);
      if (norm > min_sigma * std::sqrt(var) && w.norm() > largest.norm()) largest = w;
    }
    terms[i] = largest * largest.transpose() / 3.0;
  }
  return terms;
}

void DisplacementFieldOptions::Check() const {
  if (!(spacing_px > 0))
    throw InvalidArgument(Message("displacement field: spacing_px must be > 0, got ", spacing_px));
  if (!(max_neighbour_sigma >= 0))
    throw InvalidArgument(
        Message("displacement field: max_neighbour_sigma must be >= 0, got ", max_neighbour_sigma));
  if (!(straddle_min_sigma >= 0))
    throw InvalidArgument(
        Message("displacement field: straddle_min_sigma must be >= 0, got ", straddle_min_sigma));
  if (!(spacing_m >= 0))
    throw InvalidArgument(Message("displacement field: spacing_m must be >= 0, got ", spacing_m));
  if (border_px < 0)
    throw InvalidArgument(Message("displacement field: border_px must be >= 0, got ", border_px));
  if (search_radius < 0 || search_radius > 50)
    throw InvalidArgument(
        Message("displacement field: search_radius must be in [0, 50], got ", search_radius));
  if (!(prefilter_sigma >= 0 && prefilter_sigma <= 5))
    throw InvalidArgument(
        Message("displacement field: prefilter_sigma must be in [0, 5], got ", prefilter_sigma));
  if (half_window < 2 || half_window > 50)
    throw InvalidArgument(
        Message("displacement field: half_window must be in [2, 50], got ", half_window));
  if (!(dem_sigma >= 0))
    throw InvalidArgument(Message("displacement field: dem_sigma must be >= 0, got ", dem_sigma));
  if (!(min_incidence_deg >= 0 && min_incidence_deg < 90))
    throw InvalidArgument(Message("displacement field: min_incidence_deg must be in [0, 90), got ",
                                  min_incidence_deg));
  if (!(min_los_angle_deg >= 0 && min_los_angle_deg < 90))
    throw InvalidArgument(Message("displacement field: min_los_angle_deg must be in [0, 90), got ",
                                  min_los_angle_deg));
  if (min_stable_probes < 1)
    throw InvalidArgument(
        Message("displacement field: min_stable_probes must be >= 1, got ", min_stable_probes));
  if (!(max_range > 0))
    throw InvalidArgument(Message("displacement field: max_range must be > 0, got ", max_range));
}

bool IntersectDem(const io::GeoRaster& dem, const Eigen::Vector3d& origin,
                  const Eigen::Vector3d& direction, double max_range, double* t) {
  return Intersect(dem, origin, direction.normalized(), max_range, 0.0, t);
}

DisplacementField ComputeDisplacementField(const cv::Mat& reference_image, const cv::Mat& new_image,
                                           const io::GeoRaster& dem, const FieldInput& in,
                                           const DisplacementFieldOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  o.Check();
  in.model.Check();
  dem.Check(in.dem_name);
  if (dem.num_bands() < 1) throw InvalidArgument(Message(in.dem_name, ": no height band"));
  if (in.current_dem) {
    in.current_dem->Check(in.dem_name + " (new epoch)");
    if (in.current_dem->num_bands() < 1)
      throw InvalidArgument(Message(in.dem_name, " (new epoch): no height band"));
  }
  const camera::Sensor& s = in.model.sensor();
  for (const auto& [image, name] : {std::make_pair(&reference_image, "reference image"),
                                    std::make_pair(&new_image, "new image")})
    if (image->cols != s.width || image->rows != s.height || image->channels() != 1)
      throw InvalidArgument(Message("displacement field: the ", name, " is ", image->cols, "x",
                                    image->rows, "x", image->channels(), ", the camera ", s.width,
                                    "x", s.height, "x1"));
  if (!std::isfinite(in.dt))
    throw InvalidArgument(Message("displacement field: dt must be finite, got ", in.dt));

  cv::Mat a = matching::ToFloat(reference_image, "reference image");
  cv::Mat b = matching::ToFloat(new_image, "new image");
  if (o.prefilter_sigma > 0) {
    a = matching::GaussianBlur(a, o.prefilter_sigma);
    b = matching::GaussianBlur(b, o.prefilter_sigma);
  }
  matching::LscOptions lsc;
  lsc.half_window = o.half_window;
  lsc.search_radius = o.search_radius;
  lsc.max_shift = o.search_radius + 2.0;

  DisplacementField field;
  std::vector<Eigen::Vector2d> predicted;  // where stable ground is in the new photo
  for (const Eigen::Vector2d& xa : Probes(dem, in, o)) {
    Eigen::Vector3d x_ref;
    if (!PixelOnDem(dem, in.model, in.reference, xa, 0.0, o.max_range, &x_ref)) continue;
    FieldPoint p;
    p.xa = xa;
    p.x_ref = x_ref;
    p.stable = in.stable && in.stable(xa);
    Eigen::Vector2d x;
    if (!in.model.Project(in.current, x_ref, &x) || x.x() < 0 || x.y() < 0 || x.x() > s.width - 1 ||
        x.y() > s.height - 1) {
      p.flag = "off_image";
    } else {
      const matching::LscSummary m = matching::MatchLsc(a, b, xa, x, lsc);
      p.xb = m.xb;
      p.covariance_px = m.covariance;
      p.correlation = m.correlation;
      p.affine = m.affine;
      if (!m.IsSolutionUsable()) p.flag = std::string("lsc_") + matching::LscStatusName(m.status);
    }
    field.points.push_back(p);
    predicted.push_back(x);
  }
  field.summary.probes = static_cast<int>(field.points.size());
  field.summary.lsc_variance_factor = StableVarianceFactor(field.points, predicted, in, o);
  for (FieldPoint& p : field.points) {
    if (p.IsUsable()) {
      p.covariance_px *= field.summary.lsc_variance_factor;
      Project(dem, in, o, p.x_ref, &p);
    }
  }
  const std::vector<Eigen::Matrix3d> straddle =
      WindowStraddleTerms(o.straddle_min_sigma, o.half_window, field.points);
  for (size_t i = 0; i < field.points.size(); ++i) {
    field.points[i].covariance += straddle[i];
    if (!straddle[i].isZero()) ++field.summary.straddling;
  }
  FlagInconsistent(o.max_neighbour_sigma, &field.points);
  for (FieldPoint& p : field.points) {
    if (p.IsUsable())
      ++field.summary.usable;
    else
      ++field.summary.flags[p.flag];
  }
  if (field.summary.probes == 0)
    throw InvalidArgument(
        Message(in.dem_name, " does not cover the view: no probe ray of the ",
                in.monitored ? "monitored area" : "photo", " meets its surface (DEM x ",
                Metres(dem.origin_x), "..", Metres(dem.origin_x + dem.width * dem.cell_size),
                ", y ", Metres(dem.origin_y - dem.height * dem.cell_size), "..",
                Metres(dem.origin_y), "; camera at ", Metres(in.reference.position.x()), ", ",
                Metres(in.reference.position.y()), ")"));
  field.summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return field;
}

}  // namespace dense
}  // namespace slope_monitor
