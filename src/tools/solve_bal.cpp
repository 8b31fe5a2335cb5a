// solve_bal: solve a Bundle Adjustment in the Large problem with the
// adjustment's solver path and print initial and final cost, iterations, time.
//
//   solve_bal <problem.txt> [--solver auto|dense_schur|sparse_schur|iterative_schur]
//             [--autodiff] [--iterations N] [--threads N] [--loss none|huber|cauchy] [--progress]
//
// Exit status: 0 solved; 1 a usage error, a bad file or a failed solve.
#include <cstdio>
#include <cstdlib>
#include <string>

#include "slope_monitor/core/adjustment/bal.h"
#include "slope_monitor/core/common/error.h"

int main(int argc, char** argv) {
  using namespace slope_monitor;
  const bool help = argc >= 2 && (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help");
  if (argc < 2 || help) {
    std::fprintf(
        help ? stdout : stderr,  // --help on stdout, a usage error on stderr
        "usage: %s <problem.txt> [--solver auto|dense_schur|sparse_schur|iterative_schur] "
        "[--autodiff]\n"
        "          [--iterations N] [--threads N] [--loss none|huber|cauchy] [--progress]\n",
        argv[0]);
    return help ? 0 : 1;  // a usage error: 1 (the tools' convention, doc/security.md)
  }
  adjustment::Options options;
  options.loss = "none";
  options.max_iterations = 50;
  options.function_tolerance = 1e-6;
  options.gradient_tolerance = 1e-10;
  options.parameter_tolerance = 1e-8;
  bool analytic = true;
  try {
    for (int i = 2; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw InvalidArgument("option " + a + " needs a value");
        return argv[++i];
      };
      if (a == "--solver")
        options.linear_solver = next();
      else if (a == "--autodiff")
        analytic = false;
      else if (a == "--iterations")
        options.max_iterations = std::stoi(next());
      else if (a == "--threads")
        options.num_threads = std::stoi(next());
      else if (a == "--loss")
        options.loss = next();
      else if (a == "--progress")
        options.minimizer_progress = true;
      else
        throw InvalidArgument("unknown option '" + a + "'");
    }
    options.Check();
    adjustment::BalProblem problem = adjustment::BalProblem::Load(argv[1]);
    const double initial = problem.Cost();
    const adjustment::BalReport r = adjustment::SolveBal(&problem, options, analytic);
    std::printf("problem %s: %d cameras, %d points, %d observations\n", argv[1], r.num_cameras,
                r.num_points, r.num_observations);
    std::printf("jacobians %s, linear solver %s\n", analytic ? "analytic" : "autodiff",
                options.linear_solver.c_str());
    std::printf("initial cost %.6e\nfinal cost %.6e\niterations %d\ntime %.3f s\ntermination %s\n",
                initial, r.solve.final_cost, r.solve.iterations, r.solve.time,
                r.solve.termination.c_str());
    return r.solve.failed ? 1 : 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "solve_bal: %s\n", e.what());
    return 1;
  }
}
