#include "slope_monitor/core/geometry/resection.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <random>

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace geometry {

Eigen::Vector3d BearingOfPixel(const camera::CameraModel& model, const Eigen::Vector2d& pixel) {
  const Eigen::Vector2d ideal = model.UndistortMm(model.PixelToMm(pixel));
  return Eigen::Vector3d(ideal.x(), ideal.y(), -model.principal_distance()).normalized();
}

void ResectionOptions::Check() const {
  if (!(inlier_threshold_px > 0.0))
    throw ConfigError(
        Message("resection inlier_threshold_px must be > 0, got ", inlier_threshold_px));
  if (max_iterations <= 0)
    throw ConfigError(Message("resection max_iterations must be > 0, got ", max_iterations));
  if (!(pixel_sigma > 0.0))
    throw ConfigError(Message("resection pixel_sigma must be > 0, got ", pixel_sigma));
}

namespace {

// Real roots of a4 v^4 + a3 v^3 + a2 v^2 + a1 v + a0 (companion matrix,
// polished by Newton steps).
std::vector<double> RealQuarticRoots(double a4, double a3, double a2, double a1, double a0) {
  std::vector<double> roots;
  const double scale =
      std::max({std::abs(a4), std::abs(a3), std::abs(a2), std::abs(a1), std::abs(a0)});
  if (!(scale > 0.0)) return roots;
  if (std::abs(a4) < 1e-14 * scale) return roots;  // degenerate configuration
  Eigen::Matrix4d companion = Eigen::Matrix4d::Zero();
  companion(0, 0) = -a3 / a4;
  companion(0, 1) = -a2 / a4;
  companion(0, 2) = -a1 / a4;
  companion(0, 3) = -a0 / a4;
  companion(1, 0) = companion(2, 1) = companion(3, 2) = 1.0;
  Eigen::EigenSolver<Eigen::Matrix4d> es(companion, false);
  for (int i = 0; i < 4; ++i) {
    const std::complex<double> z = es.eigenvalues()(i);
    if (std::abs(z.imag()) > 1e-6 * std::max(1.0, std::abs(z.real()))) continue;
    double v = z.real();
    for (int it = 0; it < 5; ++it) {
      const double f = (((a4 * v + a3) * v + a2) * v + a1) * v + a0;
      const double df = ((4 * a4 * v + 3 * a3) * v + 2 * a2) * v + a1;
      if (df == 0.0) break;
      v -= f / df;
    }
    roots.push_back(v);
  }
  return roots;
}

// Rigid transform with q_i = R p_i + t (three or more points).
bool AbsoluteOrientation(const Eigen::Vector3d* p, const Eigen::Vector3d* q, int n,
                         Eigen::Matrix3d* r, Eigen::Vector3d* t) {
  Eigen::Vector3d mp = Eigen::Vector3d::Zero(), mq = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    mp += p[i];
    mq += q[i];
  }
  mp /= n;
  mq /= n;
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) h += (q[i] - mq) * (p[i] - mp).transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s(2, 2) = -1.0;
  *r = svd.matrixU() * s * svd.matrixV().transpose();
  *t = mq - *r * mp;
  return r->allFinite() && t->allFinite();
}

// Collinearity residual with the interior held fixed (refinement).
struct ResectionError {
  ResectionError(const camera::CameraModel& m, const Eigen::Vector2d& px, const Eigen::Vector3d& x)
      : interior(m.interior()), sensor(m.sensor()), pixel(px), point(x) {}
  template <typename T>
  bool operator()(const T* exterior, T* residuals) const {
    T in[camera::kNumInterior], x[3] = {T(point.x()), T(point.y()), T(point.z())},
                                xy[2] = {T(0), T(0)};
    for (int i = 0; i < camera::kNumInterior; ++i) in[i] = T(interior[i]);
    camera::ProjectToImageMm(exterior, in, x, xy);
    T col, row;
    camera::MmToPixel(sensor, xy[0], xy[1], &col, &row);
    residuals[0] = col - T(pixel.x());
    residuals[1] = row - T(pixel.y());
    return true;
  }
  std::array<double, camera::kNumInterior> interior;
  camera::Sensor sensor;
  Eigen::Vector2d pixel;
  Eigen::Vector3d point;
};

}  // namespace

std::vector<camera::ExteriorOrientation> ResectThreePoints(
    const Eigen::Vector3d bearings[3], const Eigen::Vector3d points_in_site[3]) {
  std::vector<camera::ExteriorOrientation> out;
  const Eigen::Vector3d j1 = bearings[0].normalized(), j2 = bearings[1].normalized(),
                        j3 = bearings[2].normalized();
  const Eigen::Vector3d& p1 = points_in_site[0];
  const Eigen::Vector3d& p2 = points_in_site[1];
  const Eigen::Vector3d& p3 = points_in_site[2];
  const double a2 = (p2 - p3).squaredNorm(), b2 = (p1 - p3).squaredNorm(),
               c2 = (p1 - p2).squaredNorm();
  if (!(a2 > 0.0 && b2 > 0.0 && c2 > 0.0)) return out;
  const double ca = j2.dot(j3), cb = j1.dot(j3), cg = j1.dot(j2);
  const double k1 = (a2 - c2) / b2, k2 = (a2 + c2) / b2;
  // Grunert's quartic in v = s3 / s1 (s_i the distance to point i).
  const double a4 = (k1 - 1) * (k1 - 1) - 4 * c2 / b2 * ca * ca;
  const double a3 = 4 * (k1 * (1 - k1) * cb - (1 - k2) * ca * cg + 2 * c2 / b2 * ca * ca * cb);
  const double a2c = 2 * (k1 * k1 - 1 + 2 * k1 * k1 * cb * cb + 2 * (b2 - c2) / b2 * ca * ca -
                          4 * k2 * ca * cb * cg + 2 * (b2 - a2) / b2 * cg * cg);
  const double a1 = 4 * (-k1 * (1 + k1) * cb + 2 * a2 / b2 * cg * cg * cb - (1 - k2) * ca * cg);
  const double a0 = (1 + k1) * (1 + k1) - 4 * a2 / b2 * cg * cg;
  for (double v : RealQuarticRoots(a4, a3, a2c, a1, a0)) {
    if (!(v > 0.0)) continue;
    const double den = 2 * (cg - v * ca);
    if (std::abs(den) < 1e-12) continue;
    const double u = ((-1 + k1) * v * v - 2 * k1 * cb * v + 1 + k1) / den;
    if (!(u > 0.0)) continue;
    const double d = 1 + v * v - 2 * v * cb;
    if (!(d > 0.0)) continue;
    const double s1 = std::sqrt(b2 / d), s2 = u * s1, s3 = v * s1;
    const Eigen::Vector3d q[3] = {s1 * j1, s2 * j2, s3 * j3};
    Eigen::Matrix3d r;
    Eigen::Vector3d t;
    if (!AbsoluteOrientation(points_in_site, q, 3, &r, &t)) continue;
    // u = M (X - X0) = R X + t  ->  M = R, X0 = -R^T t.
    camera::ExteriorOrientation e;
    e.position = -r.transpose() * t;
    e.angles = camera::AnglesFromRotation(r);
    out.push_back(e);
  }
  return out;
}

ResectionResult Resect(const camera::CameraModel& model, const std::vector<Eigen::Vector2d>& pixels,
                       const std::vector<Eigen::Vector3d>& points_in_site,
                       const ResectionOptions& options) {
  options.Check();
  ResectionResult result;
  const size_t n = pixels.size();
  if (n != points_in_site.size()) {
    throw InvalidArgument(
        Message("resection: ", n, " pixels but ", points_in_site.size(), " control points"));
  }
  for (size_t i = 0; i < n; ++i) {
    if (!pixels[i].allFinite() || !points_in_site[i].allFinite())
      throw InvalidArgument(
          Message("resection: control point ", i, " has a non-finite pixel or position"));
  }
  if (n < 4) {
    result.message =
        Message("too few control points: ", n, " (need >= 4: three to solve, one to choose)");
    return result;
  }
  if (AreCollinear(points_in_site)) {
    result.message = Message("all ", n, " control points are collinear: the pose is undetermined");
    return result;
  }
  std::vector<Eigen::Vector3d> bearings(n);
  for (size_t i = 0; i < n; ++i) bearings[i] = BearingOfPixel(model, pixels[i]);

  auto score = [&](const camera::ExteriorOrientation& e, std::vector<bool>* in, double* sum) {
    int k = 0;
    *sum = 0.0;
    for (size_t i = 0; i < n; ++i) {
      Eigen::Vector2d px;
      const bool front = model.Project(e, points_in_site[i], &px);
      const double err = front ? (px - pixels[i]).norm() : std::numeric_limits<double>::infinity();
      (*in)[i] = err < options.inlier_threshold_px;
      if ((*in)[i]) {
        ++k;
        *sum += err;
      }
    }
    return k;
  };

  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::vector<bool> best_in(n, false), in(n);
  int best_n = 0;
  double best_sum = 0.0;
  camera::ExteriorOrientation best;
  const bool exhaustive = n <= 8;  // all C(n,3) samples when few points
  std::vector<std::array<size_t, 3>> samples;
  if (exhaustive) {
    for (size_t a = 0; a < n; ++a)
      for (size_t b = a + 1; b < n; ++b)
        for (size_t c = b + 1; c < n; ++c) samples.push_back({a, b, c});
  }
  const int iterations = exhaustive ? static_cast<int>(samples.size()) : options.max_iterations;
  for (int it = 0; it < iterations; ++it) {
    std::array<size_t, 3> s;
    if (exhaustive) {
      s = samples[it];
    } else {
      s = {pick(rng), pick(rng), pick(rng)};
      if (s[0] == s[1] || s[1] == s[2] || s[0] == s[2]) continue;
    }
    const Eigen::Vector3d b[3] = {bearings[s[0]], bearings[s[1]], bearings[s[2]]};
    const Eigen::Vector3d p[3] = {points_in_site[s[0]], points_in_site[s[1]], points_in_site[s[2]]};
    const std::vector<camera::ExteriorOrientation> candidates = ResectThreePoints(b, p);
    for (const auto& e : candidates) {
      double sum;
      const int k = score(e, &in, &sum);
      if (k > best_n || (k == best_n && k > 0 && sum < best_sum)) {
        best_n = k;
        best_sum = sum;
        best_in = in;
        best = e;
        result.num_candidates_best_sample = static_cast<int>(candidates.size());
      }
    }
  }
  if (best_n < 4) {
    result.message = Message("no pose explains >= 4 control points within ",
                             options.inlier_threshold_px, " px (best: ", best_n, " of ", n, ")");
    return result;
  }
  result.exterior = best;
  result.inliers = best_in;
  result.num_inliers = best_n;
  if (options.refine) {
    std::array<double, camera::kNumExterior> e = best.ToArray();
    ceres::Problem problem;
    for (size_t i = 0; i < n; ++i) {
      if (!best_in[i]) continue;
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<ResectionError, 2, camera::kNumExterior>(
              new ResectionError(model, pixels[i], points_in_site[i])),
          nullptr, e.data());
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = 50;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    if (summary.IsSolutionUsable()) {
      result.exterior = camera::ExteriorOrientation::FromArray(e.data());
      ceres::Covariance::Options co;
      co.algorithm_type = ceres::DENSE_SVD;
      ceres::Covariance cov(co);
      std::vector<std::pair<const double*, const double*>> blocks = {{e.data(), e.data()}};
      if (cov.Compute(blocks, &problem)) {
        Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
        cov.GetCovarianceBlock(e.data(), e.data(), c.data());
        result.covariance = options.pixel_sigma * options.pixel_sigma * c;
      }
    }
    // Recount inliers with the refined pose.
    double sum;
    result.num_inliers = score(result.exterior, &result.inliers, &sum);
  }
  double ss = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (!result.inliers[i]) continue;
    Eigen::Vector2d px;
    model.Project(result.exterior, points_in_site[i], &px);
    ss += (px - pixels[i]).squaredNorm();
  }
  result.rms_px = std::sqrt(ss / std::max(1, result.num_inliers));
  result.success = true;
  result.message =
      Message(result.num_inliers, " of ", n, " control points inliers, rms ", result.rms_px, " px");
  return result;
}

}  // namespace geometry
}  // namespace slope_monitor
