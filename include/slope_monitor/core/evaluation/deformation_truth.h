// Measures a deformation history against the simulator's truth: for every
// point, the latest fused estimate and its error against the true
// displacement at the same time; for every source, the RMS error of its raw
// measurements; for the fused series, the RMS error of every stored estimate;
// and the forecast failure time against the true one. Used by the demo's
// summary table and by the full-graph rostest.
//
// The history is the deformation estimator's SQLite file (schema:
// include/slope_monitor/core/deformation/history.h), read-only.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace evaluation {

struct PointEvaluation {
  std::string id;      // point id ("tag36h11/10", "tx1")
  std::string role;    // control | monitoring | check | radio | unknown
  double stamp = 0.0;  // [s] of the latest estimate
  Eigen::Vector3d reference_position = Eigen::Vector3d::Zero();  // [m] site
  Eigen::Vector3d estimate = Eigen::Vector3d::Zero();            // [m] fused displacement
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();          // [m^2]
  Eigen::Vector3d truth = Eigen::Vector3d::Zero();               // [m] true displacement at stamp
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();            // [m/s] fused
  double true_speed = 0.0;                                       // [m/s] at stamp
  int alert_level = 0;                                           // DeformationPoint.ALERT_*
  bool forecast_valid = false;
  double forecast_time = 0.0;       // [s]
  double forecast_sigma = 0.0;      // [s]
  std::map<int, int> measurements;  // source -> count
  Eigen::Vector3d Error() const { return estimate - truth; }
  // Error in units of its standard deviation along the error: |e| / sigma_e.
  double NormalisedError() const;
  double Sigma() const { return std::sqrt(covariance.trace()); }  // [m] 3-D
};

struct SourceEvaluation {
  int source = 0;    // PointDisplacement.SOURCE_*
  std::string name;  // "target", "radio", ...
  int count = 0;     // measurements compared
  double rms = 0.0;  // [m] 3-D RMS error of raw measurements vs truth
  double fused_rms =
      0.0;  // [m] 3-D RMS of the fused estimates of the same points at the same times
};

struct DeformationEvaluation {
  std::vector<PointEvaluation> points;
  std::vector<SourceEvaluation> sources;
  double fused_rms = 0.0;  // [m] 3-D RMS of the latest estimates of moving-body points
  int fused_count = 0;
  double true_failure_time = 0.0;  // [s]; 0 when the truth has no failure
  double reference_stamp = 0.0;    // [s] datum of the history

  const PointEvaluation* Find(const std::string& id) const;
};

// Reads `database` (never writes it) and compares with `truth`. Throws IoError
// naming the file when it cannot be read.
DeformationEvaluation EvaluateHistory(const std::string& database, const sim::SurveyTruth& truth);

// A fixed-width table for people: point, |d|, d, v, sigma, alert, forecast, truth, error.
std::string FormatTable(const DeformationEvaluation& e);

std::string SourceName(int source);
std::string AlertName(int level);

}  // namespace evaluation
}  // namespace slope_monitor
