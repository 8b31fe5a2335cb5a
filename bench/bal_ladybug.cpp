// Benchmark: ladybug shrink-1800 (49 cameras, 1800 points, 10863 observations)
// solved by our adjustment path and by Ceres' own recommended setup for BAL
// in the same process, from the same start, with the same stopping rules.
//
//   ours:  SnavelyReprojectionErrorAnalytic (hand-written Jacobian),
//          linear solver "auto" (DENSE_SCHUR for <= 200 cameras), points eliminated first.
//   ceres: the setup of Ceres' examples/bundle_adjuster.cc: autodiff Snavely
//          cost, Levenberg-Marquardt, automatic Schur ordering, run with each of
//          DENSE_SCHUR, SPARSE_SCHUR (JACOBI) and ITERATIVE_SCHUR (SCHUR_JACOBI);
//          the baseline is the fastest of them that reaches the best final cost.
// Also: ours with autodiff (what the analytic Jacobian alone gains).
// Prints final costs and `ratio ours/ceres = x` (process CPU time, single thread,
// best of 5 runs each: CPU time rather than wall time because the machine is shared).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <string>

#include <ceres/ceres.h>

#include "slope_monitor/core/adjustment/bal.h"
#include "slope_monitor/core/adjustment/cost_functions/snavely_reprojection_error.h"

namespace {

using slope_monitor::adjustment::BalProblem;

constexpr int kMaxIterations = 50;
constexpr double kFunctionTolerance = 1e-6;
constexpr double kGradientTolerance = 1e-10;
constexpr double kParameterTolerance = 1e-8;

struct Run {
  double time = 1e30;
  double cost = 0.0;
  int iterations = 0;
};

Run CeresExampleSetup(const BalProblem& start, ceres::LinearSolverType solver) {
  BalProblem p = start;
  ceres::Problem problem;
  for (const auto& o : p.observations) {
    problem.AddResidualBlock(slope_monitor::adjustment::SnavelyReprojectionError::Create(o.x, o.y),
                             nullptr, p.cameras[o.camera].data(), p.points[o.point].data());
  }
  ceres::Solver::Options so;
  so.linear_solver_type = solver;
  so.preconditioner_type = solver == ceres::ITERATIVE_SCHUR ? ceres::SCHUR_JACOBI : ceres::JACOBI;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.max_num_iterations = kMaxIterations;
  so.function_tolerance = kFunctionTolerance;
  so.gradient_tolerance = kGradientTolerance;
  so.parameter_tolerance = kParameterTolerance;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary s;
  const std::clock_t t0 = std::clock();
  ceres::Solve(so, &problem, &s);
  Run r;
  r.time = static_cast<double>(std::clock() - t0) / CLOCKS_PER_SEC;
  r.cost = s.final_cost;
  r.iterations = static_cast<int>(s.iterations.size()) - 1;
  return r;
}

Run Ours(const BalProblem& start, bool analytic) {
  BalProblem p = start;
  slope_monitor::adjustment::Options o;
  o.loss = "none";
  o.max_iterations = kMaxIterations;
  o.function_tolerance = kFunctionTolerance;
  o.gradient_tolerance = kGradientTolerance;
  o.parameter_tolerance = kParameterTolerance;
  o.num_threads = 1;
  const std::clock_t t0 = std::clock();
  const auto rep = slope_monitor::adjustment::SolveBal(&p, o, analytic);
  Run r;
  r.time = static_cast<double>(std::clock() - t0) / CLOCKS_PER_SEC;
  r.cost = rep.solve.final_cost;
  r.iterations = rep.solve.iterations;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string path =
      argc > 1 ? argv[1]
               : std::string(SM_SOURCE_DIR) +
                     "/test/data/bal/bal-ladybug-problem-49-7776-pre-shrink-1800.txt";
  const BalProblem start = BalProblem::Load(path);
  std::printf("problem %s\ninitial cost %.6e\n", path.c_str(), start.Cost());
  // Ceres' example in each Schur solver (same threads as ours: 1); the
  // baseline is the fastest that reaches the best final cost (within 1e-6).
  const ceres::LinearSolverType solvers[3] = {ceres::DENSE_SCHUR, ceres::SPARSE_SCHUR,
                                              ceres::ITERATIVE_SCHUR};
  const char* names[3] = {"DENSE_SCHUR", "SPARSE_SCHUR", "ITERATIVE_SCHUR+SCHUR_JACOBI"};
  Run ceres_runs[3], ours_best, ours_ad_best;
  for (int rep = 0; rep < 5; ++rep) {
    for (int k = 0; k < 3; ++k) {
      const Run c = CeresExampleSetup(start, solvers[k]);
      if (c.time < ceres_runs[k].time) ceres_runs[k] = c;
    }
    const Run a = Ours(start, true);
    const Run d = Ours(start, false);
    if (a.time < ours_best.time) ours_best = a;
    if (d.time < ours_ad_best.time) ours_ad_best = d;
  }
  double best_cost = 1e300;
  for (const Run& c : ceres_runs) best_cost = std::min(best_cost, c.cost);
  int best = -1;
  for (int k = 0; k < 3; ++k) {
    std::printf("ceres_example (autodiff, %s): final cost %.6e, %d iterations, %.3f s CPU\n",
                names[k], ceres_runs[k].cost, ceres_runs[k].iterations, ceres_runs[k].time);
    if (ceres_runs[k].cost <= best_cost * (1.0 + 1e-6) &&
        (best < 0 || ceres_runs[k].time < ceres_runs[best].time))
      best = k;
  }
  const Run& ceres_best = ceres_runs[best];
  std::printf("ceres best: %s\n", names[best]);
  std::printf(
      "ours (analytic, auto->DENSE_SCHUR):     final cost %.6e, %d iterations, %.3f s CPU\n",
      ours_best.cost, ours_best.iterations, ours_best.time);
  std::printf(
      "ours_autodiff (autodiff, auto->DENSE_SCHUR): final cost %.6e, %d iterations, %.3f s CPU\n",
      ours_ad_best.cost, ours_ad_best.iterations, ours_ad_best.time);
  std::printf("final cost ours %.6e, best %.6e\n", ours_best.cost, ceres_best.cost);
  std::printf("cost ratio ours/best = %.7f\n", ours_best.cost / ceres_best.cost);
  std::printf("ratio ours_autodiff/best = %.3f\n", ours_ad_best.time / ceres_best.time);
  std::printf("ratio ours/best = %.3f\n", ours_best.time / ceres_best.time);
  return 0;
}
