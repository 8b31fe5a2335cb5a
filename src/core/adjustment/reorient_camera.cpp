#include "slope_monitor/core/adjustment/reorient_camera.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <ceres/ceres.h>
#include <Eigen/Geometry>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/resect_camera.h"
#include "slope_monitor/core/adjustment/small_problem.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/geometry/resection.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr double kFar =
    1000.0;  // [m] depth of the reference rays (any > 0 works with the position held)

struct Pass {
  bool ok = false;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double cost = 0.0;
};

// One adjustment of the attitude in e (position held) over the inliers.
Pass Adjust(const camera::CameraModel& model, const std::vector<Eigen::Vector3d>& points,
            const std::vector<StableTiePoint>& ties, const std::vector<bool>& in, double sigma,
            double huber, std::array<double, camera::kNumExterior>* e) {
  std::array<double, camera::kNumInterior> interior = model.interior();
  std::vector<Eigen::Vector3d> pts = points;
  ceres::Problem problem;
  const Eigen::Matrix2d sqrt_info = Eigen::Matrix2d::Identity() / sigma;
  for (size_t i = 0; i < ties.size(); ++i) {
    if (!in[i]) continue;
    problem.AddResidualBlock(CollinearityError::Create(model.sensor(), ties[i].xb, sqrt_info),
                             huber > 0 ? new ceres::HuberLoss(huber / sigma) : nullptr, e->data(),
                             interior.data(), pts[i].data());
    problem.SetParameterBlockConstant(pts[i].data());
  }
  problem.SetParameterBlockConstant(interior.data());
  problem.SetManifold(e->data(), new ceres::SubsetManifold(camera::kNumExterior, {0, 1, 2}));
  const ceres::Solver::Summary ss = SolveSmallProblem(&problem, 100, 1e-14);
  Pass p;
  if (!ss.IsSolutionUsable()) return p;
  p.cost = ss.final_cost;
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance cov(co);
  const std::vector<std::pair<const double*, const double*>> pairs = {{e->data(), e->data()}};
  if (!cov.Compute(pairs, &problem)) return p;
  Eigen::Matrix<double, 6, 6, Eigen::RowMajor> c;
  cov.GetCovarianceBlock(e->data(), e->data(), c.data());
  p.covariance = c.bottomRightCorner<3, 3>();
  p.ok = true;
  return p;
}

}  // namespace

void ReorientOptions::Check() const {
  if (!(pixel_sigma > 0))
    throw InvalidArgument(Message("reorient: pixel_sigma must be > 0, got ", pixel_sigma));
  if (!(huber_px > 0))
    throw InvalidArgument(Message("reorient: huber_px must be > 0, got ", huber_px));
  if (!(outlier_factor > 0))
    throw InvalidArgument(Message("reorient: outlier_factor must be > 0, got ", outlier_factor));
  if (min_points < 3)
    throw InvalidArgument(Message("reorient: min_points must be >= 3, got ", min_points));
}

ReorientSummary ReorientCamera(const camera::CameraModel& model,
                               const camera::ExteriorOrientation& reference,
                               const std::vector<StableTiePoint>& ties,
                               const ReorientOptions& options) {
  options.Check();
  model.Check();
  ReorientSummary out;
  const size_t n = ties.size();
  for (size_t i = 0; i < n; ++i) {
    if (!ties[i].xa.allFinite() || !ties[i].xb.allFinite())
      throw InvalidArgument(Message("reorient: tie point ", i, " is not finite"));
  }
  if (static_cast<int>(n) < options.min_points) {
    out.message = Message("too few stable tie points: ", n, " (need ", options.min_points, ")");
    return out;
  }
  // Reference rays, relative to the projection centre (held at the origin).
  camera::ExteriorOrientation ref0 = reference;
  ref0.position.setZero();
  std::vector<Eigen::Vector3d> points(n), dirs(n), bearings(n);
  for (size_t i = 0; i < n; ++i) {
    dirs[i] = model.ImageToRay(ref0, ties[i].xa).direction;
    points[i] = kFar * dirs[i];
    bearings[i] = geometry::BearingOfPixel(model, ties[i].xb);
  }
  camera::ExteriorOrientation start = ref0;
  start.angles = camera::AnglesFromRotation(RotationFromDirections(dirs, bearings));
  std::array<double, camera::kNumExterior> e = start.ToArray();
  std::vector<bool> in(n, true);
  Pass p = Adjust(model, points, ties, in, options.pixel_sigma, options.huber_px, &e);
  if (!p.ok) {
    out.message = "robust adjustment failed";
    return out;
  }
  auto residual = [&](size_t i) {
    Eigen::Vector2d px;
    model.Project(camera::ExteriorOrientation::FromArray(e.data()), points[i], &px);
    return Eigen::Vector2d(px - ties[i].xb);
  };
  std::vector<double> norms(n);
  for (size_t i = 0; i < n; ++i) norms[i] = residual(i).norm();
  std::vector<double> sorted = norms;
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  const double median = sorted[n / 2];
  for (double& v : sorted) v = std::abs(v - median);
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
  const double robust = std::max(1.4826 * sorted[n / 2], 0.1 * options.pixel_sigma);
  int kept = 0;
  for (size_t i = 0; i < n; ++i) {
    in[i] = norms[i] <= median + options.outlier_factor * robust;
    kept += in[i];
  }
  if (kept < options.min_points) {
    out.message = Message("too few stable tie points after removing outliers: ", kept);
    return out;
  }
  p = Adjust(model, points, ties, in, options.pixel_sigma, 0.0, &e);
  if (!p.ok) {
    out.message = "adjustment failed";
    return out;
  }
  double ss = 0.0;
  for (size_t i = 0; i < n; ++i)
    if (in[i]) ss += residual(i).squaredNorm();
  out.num_points = kept;
  out.num_outliers = static_cast<int>(n) - kept;
  out.inliers = in;
  out.rms_px = std::sqrt(ss / kept);
  const int redundancy = 2 * kept - 3;
  out.sigma0 = redundancy > 0 ? std::sqrt(2.0 * p.cost / redundancy) : 0.0;
  out.covariance = p.covariance * std::max(1.0, out.sigma0 * out.sigma0);
  out.sigma = out.covariance.diagonal().cwiseSqrt();
  out.exterior = camera::ExteriorOrientation::FromArray(e.data());
  out.exterior.position = reference.position;
  out.delta = Eigen::Vector3d(out.exterior.angles.theta - reference.angles.theta,
                              out.exterior.angles.phi - reference.angles.phi,
                              out.exterior.angles.kappa - reference.angles.kappa);
  for (int k = 0; k < 3; ++k) out.delta(k) = std::remainder(out.delta(k), 2 * M_PI);
  const Eigen::Matrix3d r = camera::RotationFromAngles(out.exterior.angles) *
                            camera::RotationFromAngles(reference.angles).transpose();
  out.rotation_angle = Eigen::AngleAxisd(r).angle();
  out.success = true;
  out.message = Message(kept, " stable points, rms ", out.rms_px, " px");
  return out;
}

}  // namespace adjustment
}  // namespace slope_monitor
