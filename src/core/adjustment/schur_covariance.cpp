#include "slope_monitor/core/adjustment/schur_covariance.h"

#include <algorithm>
#include <map>
#include <unordered_map>

#include <ceres/cost_function.h>
#include <ceres/crs_matrix.h>
#include <ceres/manifold.h>
#include <Eigen/Cholesky>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

bool SchurCovarianceOptions::Check(std::string* error) const {
  if (!(min_reciprocal_condition >= 0.0 && min_reciprocal_condition < 1.0)) {
    *error = Message("SchurCovarianceOptions.min_reciprocal_condition must be in [0, 1), got ",
                     min_reciprocal_condition);
    return false;
  }
  if (num_threads < 1) {
    *error = Message("SchurCovarianceOptions.num_threads must be >= 1, got ", num_threads);
    return false;
  }
  return true;
}

namespace {

// The normal matrix split into the camera part, the 3x3 point blocks and the
// sparse coupling (per point: camera column -> row of Hcj^T).
struct NormalBlocks {
  Eigen::MatrixXd hcc;
  std::vector<Eigen::Matrix3d> hpp;
  std::vector<std::map<int, Eigen::RowVector3d>> hpc;  // Hjc: per point, camera column -> 3-vector
  std::string error;
};

NormalBlocks AssembleNormal(const ceres::CRSMatrix& j, int nc, int np) {
  NormalBlocks n;
  n.hcc = Eigen::MatrixXd::Zero(nc, nc);
  n.hpp.assign(np, Eigen::Matrix3d::Zero());
  n.hpc.resize(np);
  std::vector<std::pair<int, double>> cam;
  for (int r = 0; r < j.num_rows; ++r) {
    cam.clear();
    int point = -1;
    Eigen::RowVector3d jp = Eigen::RowVector3d::Zero();
    for (int k = j.rows[r]; k < j.rows[r + 1]; ++k) {
      const int col = j.cols[k];
      if (col < nc) {
        cam.emplace_back(col, j.values[k]);
        continue;
      }
      const int pj = (col - nc) / 3;
      if (point >= 0 && pj != point) {
        n.error = Message("residual row ", r,
                          " touches two points: the Schur covariance needs one at most");
        return n;
      }
      point = pj;
      jp((col - nc) % 3) = j.values[k];
    }
    for (const auto& a : cam)
      for (const auto& b : cam) n.hcc(a.first, b.first) += a.second * b.second;
    if (point < 0) continue;
    n.hpp[point] += jp.transpose() * jp;
    for (const auto& a : cam) {
      auto it = n.hpc[point].emplace(a.first, Eigen::RowVector3d::Zero()).first;
      it->second += a.second * jp;
    }
  }
  return n;
}

// W = Hcj (k x 3 over the cameras that see point j) and their columns.
void CouplingOf(const std::map<int, Eigen::RowVector3d>& hpc, std::vector<int>* cols,
                Eigen::MatrixX3d* w) {
  cols->clear();
  w->resize(static_cast<Eigen::Index>(hpc.size()), 3);
  int i = 0;
  for (const auto& e : hpc) {
    cols->push_back(e.first);
    w->row(i++) = e.second;
  }
}

// S -= sign * W Hjj^-1 W^T over the columns of W.
void AddPointTerm(const std::vector<int>& cols, const Eigen::MatrixX3d& w,
                  const Eigen::Matrix3d& hjj_inv, double sign, Eigen::MatrixXd* s) {
  const Eigen::MatrixXd t = w * hjj_inv * w.transpose();
  for (size_t a = 0; a < cols.size(); ++a)
    for (size_t b = 0; b < cols.size(); ++b) (*s)(cols[a], cols[b]) += sign * t(a, b);
}

// Sjj = Hjj^-1 + Hjj^-1 W^T Scc[cols] W Hjj^-1.
Eigen::Matrix3d PointCovariance(const std::vector<int>& cols, const Eigen::MatrixX3d& w,
                                const Eigen::Matrix3d& hjj_inv, const Eigen::MatrixXd& scc) {
  const Eigen::Index k = static_cast<Eigen::Index>(cols.size());
  Eigen::MatrixXd sub(k, k);
  for (Eigen::Index a = 0; a < k; ++a)
    for (Eigen::Index b = 0; b < k; ++b) sub(a, b) = scc(cols[a], cols[b]);
  const Eigen::Matrix<double, 3, Eigen::Dynamic> g = hjj_inv * w.transpose();
  return hjj_inv + g * sub * g.transpose();
}

// Inverse of a symmetric positive definite matrix, Jacobi-scaled first (the
// parameters differ by orders of magnitude in scale: metres, radians, k1
// [mm^-2]) so that the condition test sees the geometry, not the units.
bool InvertSpd(const Eigen::MatrixXd& s, double min_rcond, Eigen::MatrixXd* inverse) {
  if (s.rows() == 0) {
    inverse->resize(0, 0);
    return true;
  }
  const Eigen::ArrayXd diagonal = s.diagonal().array();
  if (!(diagonal > 0.0).all()) return false;
  const Eigen::VectorXd d = diagonal.rsqrt().matrix();
  const Eigen::MatrixXd scaled = d.asDiagonal() * s * d.asDiagonal();
  Eigen::LLT<Eigen::MatrixXd> llt(scaled);
  if (llt.info() != Eigen::Success || !(llt.rcond() >= min_rcond)) return false;
  *inverse =
      d.asDiagonal() * llt.solve(Eigen::MatrixXd::Identity(s.rows(), s.cols())) * d.asDiagonal();
  return true;
}

}  // namespace

SchurCovarianceResult ComputeSchurCovariance(const SchurCovarianceOptions& options,
                                             const std::vector<double*>& camera_blocks,
                                             const std::vector<double*>& point_blocks,
                                             const std::vector<int>& held,
                                             ceres::Problem* problem) {
  std::string error;
  if (!options.Check(&error)) throw InvalidArgument(error);
  SchurCovarianceResult result;
  std::vector<int> offset;
  int nc = 0;
  for (double* b : camera_blocks) {
    offset.push_back(nc);
    nc += problem->ParameterBlockTangentSize(b);
  }
  const int np = static_cast<int>(point_blocks.size());
  for (double* b : point_blocks) {
    if (problem->ParameterBlockTangentSize(b) != 3)
      throw InvalidArgument("ComputeSchurCovariance: a point block is not 3-d");
  }
  ceres::Problem::EvaluateOptions eo;
  eo.parameter_blocks = camera_blocks;
  eo.parameter_blocks.insert(eo.parameter_blocks.end(), point_blocks.begin(), point_blocks.end());
  eo.apply_loss_function = true;
  eo.num_threads = options.num_threads;
  ceres::CRSMatrix jacobian;
  if (!problem->Evaluate(eo, nullptr, nullptr, nullptr, &jacobian)) {
    result.message = "the Jacobian could not be evaluated";
    return result;
  }
  NormalBlocks n = AssembleNormal(jacobian, nc, np);
  if (!n.error.empty()) {
    result.message = n.error;
    return result;
  }

  // Marginalise the points.
  std::vector<Eigen::Matrix3d> hpp_inv(np);
  std::vector<std::vector<int>> cols(np);
  std::vector<Eigen::MatrixX3d> w(np);
  Eigen::MatrixXd s = n.hcc;
  for (int j = 0; j < np; ++j) {
    Eigen::LLT<Eigen::Matrix3d> llt(n.hpp[j]);
    if (llt.info() != Eigen::Success || !(llt.rcond() >= options.min_reciprocal_condition)) {
      result.message =
          Message("point block ", j, " is not determined (seen from fewer than two directions)");
      return result;
    }
    hpp_inv[j] = llt.solve(Eigen::Matrix3d::Identity());
    CouplingOf(n.hpc[j], &cols[j], &w[j]);
    AddPointTerm(cols[j], w[j], hpp_inv[j], -1.0, &s);
  }
  // The held points' terms added back: the system with those points held.
  std::vector<bool> is_held(np, false);
  Eigen::MatrixXd s_held;
  if (!held.empty()) {
    s_held = s;
    for (const int j : held) {
      if (j < 0 || j >= np)
        throw InvalidArgument(Message("ComputeSchurCovariance: held index ", j, " out of range"));
      is_held[j] = true;
      AddPointTerm(cols[j], w[j], hpp_inv[j], +1.0, &s_held);
    }
  }
  const char* singular =
      "the reduced camera system is singular (datum defect or unobservable self-calibration "
      "parameters)";
  Eigen::MatrixXd scc, scc_held;
  const bool absolute = InvertSpd(s, options.min_reciprocal_condition, &scc);
  const bool with_held =
      !held.empty() && InvertSpd(s_held, options.min_reciprocal_condition, &scc_held);
  if (!absolute && !with_held) {
    result.message = singular;
    return result;
  }
  if (!absolute) {
    // A datum the held points fix but the free system does not (control
    // without heights: the tilt): everything relative to the held points.
    result.relative_to_held = true;
    result.message = Message(singular, "; covariance relative to the held points");
  } else if (!held.empty() && !with_held) {
    result.message =
        "the reduced camera system with the held points is singular: no held covariance";
  }
  const Eigen::MatrixXd& inverse = absolute ? scc : scc_held;
  for (size_t b = 0; b < camera_blocks.size(); ++b) {
    const int t = problem->ParameterBlockTangentSize(camera_blocks[b]);
    const Eigen::MatrixXd tangent = inverse.block(offset[b], offset[b], t, t);
    const ceres::Manifold* m = problem->GetManifold(camera_blocks[b]);
    if (m == nullptr) {
      result.camera_covariance.push_back(tangent);
      continue;
    }
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> plus(m->AmbientSize(),
                                                                                t);
    m->PlusJacobian(camera_blocks[b], plus.data());
    result.camera_covariance.push_back(plus * tangent * plus.transpose());
  }
  result.point_covariance.assign(np, Eigen::Matrix3d::Zero());
  for (int j = 0; j < np; ++j)
    if (absolute || !is_held[j])
      result.point_covariance[j] = PointCovariance(cols[j], w[j], hpp_inv[j], inverse);
  if (with_held) {
    result.point_covariance_held.assign(np, Eigen::Matrix3d::Zero());
    for (int j = 0; j < np; ++j)
      if (!is_held[j])
        result.point_covariance_held[j] = PointCovariance(cols[j], w[j], hpp_inv[j], scc_held);
  }
  result.ok = true;
  return result;
}

std::vector<int> FindUndeterminedPoints(const SchurCovarianceOptions& options,
                                        const std::vector<double*>& point_blocks,
                                        ceres::Problem* problem) {
  std::string error;
  if (!options.Check(&error)) throw InvalidArgument(error);
  std::vector<int> undetermined;
  std::vector<double*> blocks;
  std::vector<double> residuals, jacobian;
  // Each point's residual blocks, from one pass over the problem (Ceres'
  // GetResidualBlocksForParameterBlock scans every residual block per call
  // without enable_fast_removal: hours for a 150-photo block).
  std::unordered_map<const double*, int> index_of;
  for (size_t j = 0; j < point_blocks.size(); ++j) index_of[point_blocks[j]] = static_cast<int>(j);
  std::vector<std::vector<ceres::ResidualBlockId>> residuals_of(point_blocks.size());
  std::vector<ceres::ResidualBlockId> all;
  problem->GetResidualBlocks(&all);
  for (const ceres::ResidualBlockId id : all) {
    problem->GetParameterBlocksForResidualBlock(id, &blocks);
    for (double* b : blocks) {
      const auto it = index_of.find(b);
      if (it != index_of.end()) residuals_of[it->second].push_back(id);
    }
  }
  for (size_t j = 0; j < point_blocks.size(); ++j) {
    if (problem->ParameterBlockTangentSize(point_blocks[j]) != 3)
      throw InvalidArgument("FindUndeterminedPoints: a point block is not 3-d");
    Eigen::Matrix3d hjj = Eigen::Matrix3d::Zero();
    bool evaluated = true;
    for (const ceres::ResidualBlockId id : residuals_of[j]) {
      problem->GetParameterBlocksForResidualBlock(id, &blocks);
      const int m = problem->GetCostFunctionForResidualBlock(id)->num_residuals();
      residuals.resize(m);
      jacobian.resize(3 * static_cast<size_t>(m));
      std::vector<double*> jacobians(blocks.size(), nullptr);
      for (size_t b = 0; b < blocks.size(); ++b)
        if (blocks[b] == point_blocks[j]) jacobians[b] = jacobian.data();
      double cost = 0.0;
      if (!problem->EvaluateResidualBlock(id, true, &cost, residuals.data(), jacobians.data())) {
        evaluated = false;
        break;
      }
      const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> jp(
          jacobian.data(), m, 3);
      hjj += jp.transpose() * jp;
    }
    const Eigen::LLT<Eigen::Matrix3d> llt(hjj);
    if (!evaluated || !hjj.allFinite() || llt.info() != Eigen::Success ||
        !(llt.rcond() >= options.min_reciprocal_condition))
      undetermined.push_back(static_cast<int>(j));
  }
  return undetermined;
}

}  // namespace adjustment
}  // namespace slope_monitor
