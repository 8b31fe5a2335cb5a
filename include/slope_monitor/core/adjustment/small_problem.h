// The solve of the adjustment module's small dense problems: one camera's
// exterior (and interior) orientation against fixed points
// (reorient_camera.h, resect_camera.h). Dense QR, no log output; converged
// when the cost or the parameters change by less than `tolerance` (relative).
#pragma once

#include <ceres/ceres.h>

namespace slope_monitor {
namespace adjustment {

inline ceres::Solver::Summary SolveSmallProblem(ceres::Problem* problem, int max_iterations,
                                                double tolerance) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations;
  so.function_tolerance = tolerance;
  so.parameter_tolerance = tolerance;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, problem, &summary);
  return summary;
}

}  // namespace adjustment
}  // namespace slope_monitor
