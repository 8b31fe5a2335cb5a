// Epochs: the adjusted points of each epoch, their co-registration onto the
// reference epoch through the stable (control and check) points, and the
// displacement of every monitoring point with its covariance and a
// significance test (|d| / sigma of d along d).
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace adjustment {

struct PointState {
  PointRole role = PointRole::kTie;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    // [m] site
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // [m^2]
};

struct EpochPoints {
  int epoch = 0;
  double stamp = 0.0;  // [s]
  std::map<std::string, PointState> points;
};

// The adjusted points of a usable solution (points without precision get a
// zero covariance). Throws InvalidArgument when the summary is not usable.
// With `datum_free` and Precision::point_covariance_datum_free computed, the
// points carry that covariance (control survey error left out: it is the same
// in every epoch and the co-registration removes it).
EpochPoints EpochPointsFromSolution(const Scene& scene, const Summary& summary, int epoch,
                                    double stamp, bool datum_free = false);

struct DisplacementOptions {
  bool estimate_scale = false;  // co-registration: rigid (false) or similarity
  double stable_threshold =
      0.02;                   // [m] residual above which a "stable" point is rejected as moved, > 0
  int min_stable_points = 3;  // >= 3
  double significance_threshold = 3.0;  // [-] |d| / sigma above which a displacement is significant
  void Check() const;
};

struct Displacement {
  std::string id;
  PointRole role = PointRole::kMonitoring;
  Eigen::Vector3d reference_position = Eigen::Vector3d::Zero();  // [m] site, reference epoch
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();        // [m] current minus reference
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();          // [m^2]
  double significance = 0.0;                                     // [-]
  bool significant = false;
};

struct EpochComparison {
  bool success = false;
  std::string message;
  geometry::Similarity3 reference_from_current;  // co-registration
  std::vector<std::string> stable_points_used;
  std::vector<std::string> stable_points_rejected;  // moved "stable" points
  double coregistration_rms = 0.0;                  // [m]
  std::vector<Displacement> displacements;          // monitoring points in both epochs
};

EpochComparison CompareEpochs(const EpochPoints& reference, const EpochPoints& current,
                              const DisplacementOptions& options = {});

// |d| / sqrt(d^T C d / |d|^2); 0 for d = 0.
double Significance(const Eigen::Vector3d& d, const Eigen::Matrix3d& covariance);

}  // namespace adjustment
}  // namespace slope_monitor
