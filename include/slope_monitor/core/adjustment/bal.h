// Bundle Adjustment in the Large (Agarwal, Snavely, Seitz, Szeliski, ECCV 2010):
// the problem file format and its solution with the adjustment's own solver
// path (SolveCeresProblem: Schur ordering, linear solver choice, tolerances)
// and the Snavely camera as the alternative camera model
// (cost_functions/snavely_reprojection_error.h).
//
// File format (text):
//   <num_cameras> <num_points> <num_observations>
//   <camera_index> <point_index> <x> <y>          x num_observations
//   <camera parameter>                            x 9 * num_cameras (w, t, f, k1, k2)
//   <point coordinate>                            x 3 * num_points
#pragma once

#include <array>
#include <string>
#include <vector>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"

namespace slope_monitor {
namespace adjustment {

struct BalObservation {
  int camera = 0;
  int point = 0;
  double x = 0.0;
  double y = 0.0;
};

struct BalProblem {
  std::vector<std::array<double, 9>> cameras;
  std::vector<std::array<double, 3>> points;
  std::vector<BalObservation> observations;

  // Throws IoError naming the file and what is wrong (count, index, token).
  static BalProblem Load(const std::string& path);
  // 0.5 * sum of squared reprojection errors at the current values.
  double Cost() const;
};

struct BalReport {
  SolveReport solve;
  int num_cameras = 0;
  int num_points = 0;
  int num_observations = 0;
};

// Solves in place. analytic_jacobians selects SnavelyReprojectionErrorAnalytic
// (else the autodiff functor). options.loss is applied as for the collinearity
// adjustment ("none" reproduces the BAL cost).
BalReport SolveBal(BalProblem* problem, const Options& options, bool analytic_jacobians);

}  // namespace adjustment
}  // namespace slope_monitor
