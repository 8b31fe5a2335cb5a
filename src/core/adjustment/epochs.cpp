#include "slope_monitor/core/adjustment/epochs.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

void DisplacementOptions::Check() const {
  if (!(stable_threshold > 0.0))
    throw ConfigError(Message("stable_threshold must be > 0, got ", stable_threshold));
  if (min_stable_points < 3)
    throw ConfigError(Message("min_stable_points must be >= 3, got ", min_stable_points));
  if (!(significance_threshold > 0.0))
    throw ConfigError(Message("significance_threshold must be > 0, got ", significance_threshold));
}

EpochPoints EpochPointsFromSolution(const Scene& scene, const Summary& summary, int epoch,
                                    double stamp, bool datum_free) {
  if (!summary.IsSolutionUsable())
    throw InvalidArgument(
        Message("epoch ", epoch, ": the adjustment is not usable (", summary.reason, ")"));
  EpochPoints e;
  e.epoch = epoch;
  e.stamp = stamp;
  for (size_t j = 0; j < scene.points.size(); ++j) {
    const ObjectPoint& p = scene.points[j];
    if (!p.position_known) continue;
    PointState s;
    s.role = p.role;
    s.position = p.position;
    if (summary.precision.valid && j < summary.precision.point_covariance.size())
      s.covariance = summary.precision.point_covariance[j];
    if (datum_free && summary.precision.valid &&
        j < summary.precision.point_covariance_datum_free.size())
      s.covariance = summary.precision.point_covariance_datum_free[j];
    e.points[p.id] = s;
  }
  return e;
}

double Significance(const Eigen::Vector3d& d, const Eigen::Matrix3d& covariance) {
  const double n2 = d.squaredNorm();
  if (n2 == 0.0) return 0.0;
  const double var_along = d.dot(covariance * d) / n2;
  if (!(var_along > 0.0)) return std::numeric_limits<double>::infinity();
  return std::sqrt(n2) / std::sqrt(var_along);
}

EpochComparison CompareEpochs(const EpochPoints& reference, const EpochPoints& current,
                              const DisplacementOptions& options) {
  options.Check();
  EpochComparison out;
  std::vector<std::string> ids;
  std::vector<Eigen::Vector3d> src, dst;
  for (const auto& [id, cur] : current.points) {
    if (cur.role != PointRole::kControl && cur.role != PointRole::kCheck) continue;
    auto it = reference.points.find(id);
    if (it == reference.points.end()) continue;
    ids.push_back(id);
    src.push_back(cur.position);
    dst.push_back(it->second.position);
  }
  if (static_cast<int>(ids.size()) < options.min_stable_points) {
    out.message =
        Message("epochs ", reference.epoch, " and ", current.epoch, " share only ", ids.size(),
                " stable points (min_stable_points = ", options.min_stable_points, ")");
    return out;
  }
  geometry::HelmertOptions h;
  h.estimate_scale = options.estimate_scale;
  h.inlier_threshold = options.stable_threshold;
  const geometry::HelmertResult fit = geometry::FitSimilarityRobust(src, dst, h);
  if (!fit.success || fit.num_inliers < options.min_stable_points) {
    out.message = Message("co-registration of epoch ", current.epoch, " onto ", reference.epoch,
                          " failed: ", fit.message);
    return out;
  }
  out.reference_from_current = fit.target_from_source;
  out.coregistration_rms = fit.rms;
  for (size_t i = 0; i < ids.size(); ++i)
    (fit.inliers[i] ? out.stable_points_used : out.stable_points_rejected).push_back(ids[i]);
  const geometry::Similarity3& t = out.reference_from_current;
  for (const auto& [id, cur] : current.points) {
    if (cur.role != PointRole::kMonitoring) continue;
    auto it = reference.points.find(id);
    if (it == reference.points.end()) continue;
    Displacement d;
    d.id = id;
    d.role = cur.role;
    d.reference_position = it->second.position;
    d.displacement = t * cur.position - it->second.position;
    d.covariance = t.TransformCovariance(cur.covariance) + it->second.covariance;
    d.significance = Significance(d.displacement, d.covariance);
    d.significant = d.significance > options.significance_threshold;
    out.displacements.push_back(d);
  }
  out.success = true;
  out.message = Message("co-registered on ", out.stable_points_used.size(), " stable points (rms ",
                        out.coregistration_rms, " m, ", out.stable_points_rejected.size(),
                        " rejected); ", out.displacements.size(), " displacements");
  return out;
}

}  // namespace adjustment
}  // namespace slope_monitor
