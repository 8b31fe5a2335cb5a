#include "slope_monitor/core/adjustment/control_check.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr int kNumParameters = 7;  // rotation update (3), translation (3), log(scale) (1)

// r = L (exp(log_scale) * R(update) * m0 + translation - s), where m0 is the
// measured point already turned by the start rotation and L^T L the inverse
// covariance of the difference. Blocks: update [rad, angle-axis],
// translation [m], log_scale [-].
struct HelmertResidual {
  HelmertResidual(const Eigen::Vector3d& m0, const Eigen::Vector3d& s, const Eigen::Matrix3d& l)
      : m0_(m0), s_(s), l_(l) {}

  template <typename T>
  bool operator()(const T* update, const T* translation, const T* log_scale, T* r) const {
    using std::exp;
    const T m[3] = {T(m0_.x()), T(m0_.y()), T(m0_.z())};
    T rm[3];
    ceres::AngleAxisRotatePoint(update, m, rm);
    const T k = exp(log_scale[0]);
    T d[3];
    for (int i = 0; i < 3; ++i) d[i] = k * rm[i] + translation[i] - T(s_(i));
    for (int i = 0; i < 3; ++i) r[i] = T(l_(i, 0)) * d[0] + T(l_(i, 1)) * d[1] + T(l_(i, 2)) * d[2];
    return true;
  }

  static ceres::CostFunction* Create(const Eigen::Vector3d& m0, const Eigen::Vector3d& s,
                                     const Eigen::Matrix3d& l) {
    return new ceres::AutoDiffCostFunction<HelmertResidual, 3, 3, 3, 1>(
        new HelmertResidual(m0, s, l));
  }

  Eigen::Vector3d m0_, s_;
  Eigen::Matrix3d l_;
};

// Upper Cholesky factor U of the inverse (U^T U = c^-1); throws naming `what`.
Eigen::Matrix3d SqrtInformation(const Eigen::Matrix3d& c, const std::string& what) {
  const double size = c.cwiseAbs().maxCoeff();
  if (!c.allFinite() || !(size > 0.0) || (c - c.transpose()).cwiseAbs().maxCoeff() > 1e-9 * size)
    throw InvalidArgument(Message(what, " is not a finite symmetric matrix"));
  Eigen::LLT<Eigen::Matrix3d> llt(c.inverse());
  if (llt.info() != Eigen::Success || !c.inverse().allFinite())
    throw InvalidArgument(Message(what, " is not positive definite"));
  return llt.matrixU();
}

struct Fit {
  geometry::Similarity3 transform;
  std::vector<double> w;  // per active point
  std::vector<Eigen::Vector3d> residual;
};

geometry::Similarity3 StartTransform(const std::vector<ControlPointPair>& points,
                                     const std::vector<int>& active,
                                     const ControlCheckOptions& options) {
  std::vector<Eigen::Vector3d> m, s;
  std::vector<double> sigma;
  for (int i : active) {
    m.push_back(points[i].measured);
    s.push_back(points[i].surveyed);
    sigma.push_back(
        std::sqrt((points[i].surveyed_covariance + points[i].measured_covariance).trace()));
  }
  std::nth_element(sigma.begin(), sigma.begin() + sigma.size() / 2, sigma.end());
  geometry::HelmertOptions h;
  h.estimate_scale = options.estimate_scale;
  h.inlier_threshold = options.loss_scale * sigma[sigma.size() / 2];
  const geometry::HelmertResult r = geometry::FitSimilarityRobust(m, s, h);
  return r.success ? r.target_from_source : geometry::FitSimilarity(m, s, options.estimate_scale);
}

// Robust fit over the active points and their standardized residuals.
Fit RobustFit(const std::vector<ControlPointPair>& points, const std::vector<int>& active,
              const geometry::Similarity3& start, const ControlCheckOptions& options) {
  double update[3] = {0.0, 0.0, 0.0};
  double translation[3] = {start.translation.x(), start.translation.y(), start.translation.z()};
  double log_scale = std::log(start.scale);
  ceres::Problem problem;
  std::vector<ceres::CostFunction*> costs;
  for (int i : active) {
    const ControlPointPair& p = points[i];
    const Eigen::Matrix3d c =
        p.surveyed_covariance + start.TransformCovariance(p.measured_covariance);
    costs.push_back(HelmertResidual::Create(start.rotation * p.measured, p.surveyed,
                                            SqrtInformation(c, "covariance of " + p.id)));
    problem.AddResidualBlock(costs.back(), new ceres::CauchyLoss(options.loss_scale), update,
                             translation, &log_scale);
  }
  if (!options.estimate_scale) problem.SetParameterBlockConstant(&log_scale);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);

  Fit fit;
  double r_update[9];
  ceres::AngleAxisToRotationMatrix(update, ceres::ColumnMajorAdapter3x3(r_update));
  fit.transform.rotation = Eigen::Map<const Eigen::Matrix3d>(r_update) * start.rotation;
  fit.transform.scale = std::exp(log_scale);
  fit.transform.translation = Eigen::Vector3d(translation[0], translation[1], translation[2]);

  // Whitened residuals, Jacobians and loss weights at the solution.
  const int n = static_cast<int>(active.size());
  const int p = options.estimate_scale ? kNumParameters : kNumParameters - 1;
  const double* parameters[3] = {update, translation, &log_scale};
  std::vector<Eigen::Vector3d> l(n);
  std::vector<Eigen::Matrix<double, 3, Eigen::Dynamic>> j(n);
  std::vector<double> weight(n);
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(p, p);
  for (int k = 0; k < n; ++k) {
    Eigen::Matrix<double, 3, 3, Eigen::RowMajor> j_update, j_translation;
    Eigen::Matrix<double, 3, 1> j_scale;
    double* jacobians[3] = {j_update.data(), j_translation.data(), j_scale.data()};
    costs[k]->Evaluate(parameters, l[k].data(), jacobians);
    j[k].resize(3, p);
    j[k].leftCols<3>() = j_update;
    j[k].middleCols<3>(3) = j_translation;
    if (options.estimate_scale) j[k].col(6) = j_scale;
    weight[k] = 1.0 / (1.0 + l[k].squaredNorm() / (options.loss_scale * options.loss_scale));
    normal += weight[k] * j[k].transpose() * j[k];
  }
  const Eigen::MatrixXd normal_inverse = normal.inverse();
  fit.w.resize(n);
  fit.residual.resize(n);
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    for (int k = 0; k < n; ++k) {
      Eigen::Matrix3d a = -j[i] * normal_inverse * j[k].transpose() * weight[k];
      if (k == i) a += Eigen::Matrix3d::Identity();
      c += a * a.transpose();
    }
    // Pseudo-inverse: the fit may take up a direction of the residual entirely.
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(c);
    const Eigen::Vector3d u = eig.eigenvectors().transpose() * l[i];
    double t = 0.0;
    for (int d = 0; d < 3; ++d)
      if (eig.eigenvalues()(d) > 1e-9 * eig.eigenvalues().maxCoeff())
        t += u(d) * u(d) / eig.eigenvalues()(d);
    fit.w[i] = std::sqrt(t);
    const ControlPointPair& q = points[active[i]];
    fit.residual[i] = q.surveyed - fit.transform * q.measured;
  }
  return fit;
}

}  // namespace

void ControlCheckOptions::Check() const {
  if (!(loss_scale > 0.0)) throw ConfigError(Message("loss_scale must be > 0, got ", loss_scale));
  if (!(critical_value > 0.0))
    throw ConfigError(Message("critical_value must be > 0, got ", critical_value));
  if (max_iterations <= 0)
    throw ConfigError(Message("max_iterations must be > 0, got ", max_iterations));
}

ControlCheckSummary CheckControlPoints(const std::vector<ControlPointPair>& points,
                                       const ControlCheckOptions& options) {
  options.Check();
  ControlCheckSummary s;
  std::vector<int> active;
  for (size_t i = 0; i < points.size(); ++i) {
    const ControlPointPair& p = points[i];
    if (!p.surveyed.allFinite() || !p.measured.allFinite())
      throw InvalidArgument(Message("control point ", p.id, ": position is not finite"));
    SqrtInformation(p.surveyed_covariance, "survey covariance of control point " + p.id);
    SqrtInformation(p.measured_covariance, "measured covariance of control point " + p.id);
    s.points.push_back({p.id, Eigen::Vector3d::Zero(), 0.0, false});
    active.push_back(static_cast<int>(i));
  }
  auto collinear = [&](const std::vector<int>& idx) {
    std::vector<Eigen::Vector3d> m, v;
    for (int i : idx) {
      m.push_back(points[i].measured);
      v.push_back(points[i].surveyed);
    }
    return geometry::AreCollinear(m) || geometry::AreCollinear(v);
  };
  if (active.size() < 4 || collinear(active)) {
    s.message =
        Message(active.size(),
                " control points: need >= 4 not on one line to tell a blunder from the others");
    return s;
  }
  while (true) {
    const Fit fit = RobustFit(points, active, StartTransform(points, active, options), options);
    s.surveyed_from_measured = fit.transform;
    int worst = 0;
    for (size_t k = 0; k < active.size(); ++k) {
      s.points[active[k]].w = fit.w[k];
      if (fit.w[k] > fit.w[worst]) worst = static_cast<int>(k);
    }
    if (!(fit.w[worst] > options.critical_value)) break;
    const int b = active[worst];
    s.points[b].blunder = true;
    s.blunders.push_back(points[b].id);
    s.notes.push_back(Message("control point ", points[b].id, " disagrees with the others by ",
                              Fixed(fit.residual[worst].norm() * 1e3, 1), " mm (w = ",
                              Fixed(fit.w[worst], 1), " > ", options.critical_value, ")"));
    std::vector<int> rest = active;
    rest.erase(rest.begin() + worst);
    if (rest.size() < 4 || collinear(rest)) break;
    active = rest;
  }
  for (size_t i = 0; i < points.size(); ++i)
    s.points[i].residual = points[i].surveyed - s.surveyed_from_measured * points[i].measured;
  s.success = true;
  if (s.blunders.empty()) {
    const auto top = std::max_element(
        s.points.begin(), s.points.end(),
        [](const ControlPointTest& a, const ControlPointTest& b) { return a.w < b.w; });
    s.message = Message(points.size(), " control points agree (largest w = ", Fixed(top->w, 2),
                        " for ", top->id, ", critical ", options.critical_value, ")");
  } else {
    s.message = Message(points.size(), " control points, ", s.blunders.size(), " blunder(s): ");
    for (size_t k = 0; k < s.notes.size(); ++k) s.message += (k ? "; " : "") + s.notes[k];
  }
  return s;
}

}  // namespace adjustment
}  // namespace slope_monitor
