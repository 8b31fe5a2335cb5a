// Covariance of a bundle block through the reduced camera system (Schur
// complement), computed only for the blocks that are used.
//
// With the parameters split into camera blocks c (exterior, interior: few)
// and points p (many, each 3-d, each residual touching at most one point), the
// normal matrix H = J^T J (J: the Jacobian at the solution, robust loss
// applied as ceres::Covariance does) is
//   H = [Hcc Hcp; Hpc Hpp],  Hpp block diagonal (3x3 per point).
// Marginalising the points gives the reduced camera system
//   S = Hcc - sum_j Hcj Hjj^-1 Hjc,
// which is inverted once (dense Cholesky) to give the camera covariance
// Scc = S^-1; a point's covariance follows by back-substitution
//   Sjj = Hjj^-1 + Hjj^-1 Hjc Scc Hcj Hjj^-1
// (the camera columns of Hjc are only the cameras that see point j).
// Holding points (the datum-free covariance: surveyed control held) removes
// their terms from the sum: S_held = S + sum_{j held} Hcj Hjj^-1 Hjc, a
// second Cholesky of the small camera system, from the same assembled pieces.
// When S is singular but S_held is not (a datum only the held points fix:
// control without heights leaves a nadir block's tilt free), every result is
// the held system's, and relative_to_held says so.
// Covariances are unscaled ((J^T J)^-1) and in the ambient parameter space
// (manifolds, e.g. SubsetManifold, are lifted with their PlusJacobian).
#pragma once

#include <string>
#include <vector>

#include <ceres/problem.h>
#include <Eigen/Core>

namespace slope_monitor {
namespace adjustment {

struct SchurCovarianceOptions {
  // Reciprocal condition number of S (Jacobi-scaled) and of each Hjj below which the
  // system is reported singular (datum defect, unobservable parameter).
  double min_reciprocal_condition = 1e-14;
  int num_threads = 1;  // for the Jacobian evaluation
  bool Check(std::string* error) const;
};

struct SchurCovarianceResult {
  bool ok = false;
  std::string message;  // why not ok; when ok, what was left (relative, no held covariance)
  // S was singular and S_held not: camera_covariance and point_covariance are
  // those with the held points held (zero for them), as point_covariance_held.
  bool relative_to_held = false;
  std::vector<Eigen::MatrixXd> camera_covariance;  // per camera block, ambient size
  std::vector<Eigen::Matrix3d> point_covariance;   // per point block
  // Per point block with the points `held` held constant (zero for held
  // points); empty when `held` is empty or that system is singular (message
  // says so; the other results stay valid).
  std::vector<Eigen::Matrix3d> point_covariance_held;
};

// camera_blocks: the non-constant parameter blocks that are not points;
// point_blocks: non-constant 3-d blocks, each residual touching at most one
// of them; held: indices into point_blocks for the second covariance.
SchurCovarianceResult ComputeSchurCovariance(const SchurCovarianceOptions& options,
                                             const std::vector<double*>& camera_blocks,
                                             const std::vector<double*>& point_blocks,
                                             const std::vector<int>& held, ceres::Problem* problem);

// The point blocks (indices into point_blocks) that the problem does not
// determine at their current values: the 3x3 normal block Hjj = sum J^T J
// over the point's residual blocks (robust loss applied, as above) is not
// positive definite or its reciprocal condition is below
// options.min_reciprocal_condition -- exactly the blocks ComputeSchurCovariance
// would refuse. A point observed by one image only, or whose other
// observations the robust loss has weighted to nothing, or whose rays are
// parallel, is such a block.
std::vector<int> FindUndeterminedPoints(const SchurCovarianceOptions& options,
                                        const std::vector<double*>& point_blocks,
                                        ceres::Problem* problem);

}  // namespace adjustment
}  // namespace slope_monitor
