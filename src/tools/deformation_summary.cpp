// Prints the deformation summary of a replay against the simulator's truth:
//   deformation_summary --database slope.db --truth demo.truth.yaml
// Reads the deformation estimator's SQLite history (read-only) and the truth
// file; prints one row per point (displacement, velocity, sigma, alert,
// error against truth), the RMS error of each source and of the fused
// estimate, and the failure-time forecast beside the true one.
// Exit status (the tools' convention, doc/security.md): 0 the table printed;
// 1 a usage error, an unreadable file or a history without estimates.
#include <cstdio>
#include <iostream>
#include <string>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/evaluation/deformation_truth.h"

int main(int argc, char** argv) {
  std::string database, truth_path;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--database" && i + 1 < argc) {
      database = argv[++i];
    } else if (a == "--truth" && i + 1 < argc) {
      truth_path = argv[++i];
    } else if (a == "-h" || a == "--help") {
      std::cout << "usage: deformation_summary --database FILE.db --truth FILE.truth.yaml\n";
      return 0;
    } else {
      std::cerr << "deformation_summary: unknown argument '" << a << "'\n"
                << "usage: deformation_summary --database FILE.db --truth FILE.truth.yaml\n";
      return 1;
    }
  }
  if (database.empty() || truth_path.empty()) {
    std::cerr << "deformation_summary: --database and --truth are required\n"
              << "usage: deformation_summary --database FILE.db --truth FILE.truth.yaml\n";
    return 1;
  }
  try {
    const auto truth = slope_monitor::sim::SurveyTruth::Load(truth_path);
    const auto evaluation = slope_monitor::evaluation::EvaluateHistory(database, truth);
    if (evaluation.points.empty()) {
      std::cerr << "deformation_summary: the history '" << database << "' holds no estimate\n";
      return 1;
    }
    std::cout << slope_monitor::evaluation::FormatTable(evaluation);
  } catch (const slope_monitor::Error& e) {
    std::cerr << "deformation_summary: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
