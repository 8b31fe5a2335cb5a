#include "slope_monitor/core/geometry/intersection.h"

#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <Eigen/Cholesky>
#include <Eigen/LU>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace geometry {

void IntersectionOptions::Check() const {
  if (!(min_angle_deg >= 0.0 && min_angle_deg < 180.0))
    throw ConfigError(
        Message("intersection min_angle_deg must be in [0, 180), got ", min_angle_deg));
  if (max_iterations < 0)
    throw ConfigError(Message("intersection max_iterations must be >= 0, got ", max_iterations));
}

namespace {
// Pixel of a point (orientation fixed), differentiable in the point.
struct PointProjection {
  PointProjection(const camera::CameraModel& m, const camera::ExteriorOrientation& e)
      : interior(m.interior()), exterior(e.ToArray()), sensor(m.sensor()) {}
  template <typename T>
  bool operator()(const T* point, T* pixel) const {
    T in[camera::kNumInterior], ex[camera::kNumExterior], xy[2] = {T(0), T(0)};
    for (int i = 0; i < camera::kNumInterior; ++i) in[i] = T(interior[i]);
    for (int i = 0; i < camera::kNumExterior; ++i) ex[i] = T(exterior[i]);
    camera::ProjectToImageMm(ex, in, point, xy);
    camera::MmToPixel(sensor, xy[0], xy[1], &pixel[0], &pixel[1]);
    return true;
  }
  std::array<double, camera::kNumInterior> interior;
  std::array<double, camera::kNumExterior> exterior;
  camera::Sensor sensor;
};
}  // namespace

IntersectionResult Intersect(const std::vector<RayObservation>& rays,
                             const IntersectionOptions& options) {
  options.Check();
  IntersectionResult r;
  if (rays.size() < 2) {
    r.message = Message("forward intersection needs rays from >= 2 images, got ", rays.size());
    return r;
  }
  std::vector<camera::Ray> lines;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (rays[i].model == nullptr)
      throw InvalidArgument(Message("intersection: ray ", i, " has no camera model"));
    if (!rays[i].pixel.allFinite())
      throw InvalidArgument(Message("intersection: ray ", i, " has a non-finite pixel"));
    lines.push_back(rays[i].model->ImageToRay(rays[i].exterior, rays[i].pixel));
  }
  double max_angle = 0.0;
  for (size_t i = 0; i < lines.size(); ++i)
    for (size_t j = i + 1; j < lines.size(); ++j)
      max_angle = std::max(
          max_angle, std::acos(std::clamp(lines[i].direction.dot(lines[j].direction), -1.0, 1.0)));
  r.max_angle_deg = max_angle * 180.0 / M_PI;
  if (r.max_angle_deg < options.min_angle_deg) {
    r.message = Message("rays nearly parallel: widest intersection angle ", r.max_angle_deg,
                        " deg < ", options.min_angle_deg, " deg");
    return r;
  }
  // Closest point to all lines: sum (I - d d^T) (X - o) = 0.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const camera::Ray& l : lines) {
    const Eigen::Matrix3d p = Eigen::Matrix3d::Identity() - l.direction * l.direction.transpose();
    a += p;
    b += p * l.origin;
  }
  Eigen::Vector3d x = a.fullPivLu().solve(b);
  // Gauss-Newton on the whitened pixel residuals.
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  for (int it = 0; it <= options.max_iterations; ++it) {
    normal.setZero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const RayObservation& ray : rays) {
      ceres::AutoDiffCostFunction<PointProjection, 2, 3> f(
          new PointProjection(*ray.model, ray.exterior));
      double px[2];
      Eigen::Matrix<double, 2, 3, Eigen::RowMajor> j;
      const double* params[] = {x.data()};
      double* jac[] = {j.data()};
      f.Evaluate(params, px, jac);
      const Eigen::Matrix2d w = ray.covariance.inverse();
      const Eigen::Vector2d e = Eigen::Vector2d(px[0], px[1]) - ray.pixel;
      normal += j.transpose() * w * j;
      g += j.transpose() * w * e;
    }
    if (it == options.max_iterations) break;
    const Eigen::Vector3d dx = normal.ldlt().solve(-g);
    if (!dx.allFinite()) break;
    x += dx;
    if (dx.norm() < 1e-10) {
      it =
          options.max_iterations - 1;  // one more pass to refresh the normal matrix at the solution
    }
  }
  double ss = 0.0;
  for (const RayObservation& ray : rays) {
    Eigen::Vector2d px;
    if (!ray.model->Project(ray.exterior, x, &px)) {
      r.message = "the intersected point lies behind an image";
      return r;
    }
    ss += (px - ray.pixel).squaredNorm();
  }
  r.position = x;
  r.covariance = normal.inverse();
  r.rms_px = std::sqrt(ss / rays.size());
  if (!r.position.allFinite() || !r.covariance.allFinite()) {
    r.message = "intersection is singular";
    return r;
  }
  r.success = true;
  r.message =
      Message(rays.size(), " rays, widest angle ", r.max_angle_deg, " deg, rms ", r.rms_px, " px");
  return r;
}

}  // namespace geometry
}  // namespace slope_monitor
