#include "slope_monitor/core/adjustment/leave_one_out.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace adjustment {

namespace {

// The scene moved by `t` (x -> s R x + t): every image and point.
void Transform(const geometry::Similarity3& t, Scene* scene) {
  for (Image& im : scene->images) im.exterior = geometry::TransformExterior(t, im.exterior);
  for (ObjectPoint& p : scene->points) p.position = t * p.position;
}

// The block placed on the control points but `left_out` (PlacementOnControl).
void PlaceOnTheOthers(const std::vector<SurveyResidual>& control, const std::string& left_out,
                      Scene* scene) {
  std::vector<Eigen::Vector3d> from, to;
  std::vector<double> weights;
  bool heights = false;
  for (const SurveyResidual& c : control) {
    if (c.id == left_out) continue;
    const ObjectPoint& p = scene->points[scene->FindPoint(c.id)];
    from.push_back(p.position);
    to.push_back(*p.surveyed);
    weights.push_back(1.0 / std::max(p.surveyed_covariance(0, 0), 1e-12));
    heights = heights || c.has_height;
  }
  if (const auto t = PlacementOnControl(from, to, weights, heights)) Transform(*t, scene);
}

}  // namespace

std::optional<geometry::Similarity3> PlacementOnControl(
    const std::vector<Eigen::Vector3d>& adjusted, const std::vector<Eigen::Vector3d>& surveyed,
    const std::vector<double>& weights, bool heights) {
  if (adjusted.size() < 3) return std::nullopt;
  std::vector<Eigen::Vector3d> from = adjusted, to = surveyed;
  if (!heights)
    for (size_t k = 0; k < from.size(); ++k) from[k].z() = to[k].z() = 0.0;
  try {
    return geometry::FitSimilarity(from, to, true, weights);
  } catch (const InvalidArgument&) {
    return std::nullopt;  // collinear
  }
}

void LeaveOneOutOptions::Check() const {
  RequireOption("leave-one-out", max_iterations > 0, "max_iterations", "must be > 0");
}

std::string LeaveOneOutReport::Brief() const {
  if (residuals.empty() && failed.empty()) return "";
  char text[120];
  std::snprintf(text, sizeof text, "leave-one-out rms %.3f m over %zu control points", rms,
                residuals.size());
  std::string out = text;
  for (size_t i = 0; i < failed.size(); ++i)
    out += (i ? "; " : "; not adjusted without: ") + failed[i];
  return out;
}

std::vector<std::string> LeaveOneOutReport::Lines() const {
  std::vector<std::string> out;
  for (const SurveyResidual& r : residuals) out.push_back(ResidualLine(r, "left out"));
  return out;
}

LeaveOneOutReport LeaveOneOut(const Scene& adjusted, const EpochAdjustmentOptions& options,
                              const std::map<std::string, std::string>& names,
                              const LeaveOneOutOptions& leave_one_out) {
  leave_one_out.Check();
  const auto start = std::chrono::steady_clock::now();
  LeaveOneOutReport out;
  Options o = options.adjustment;
  o.compute_covariance = false;
  o.compute_datum_free_covariance = false;
  o.max_sigma0 = 1e12;  // the datum is what is tested here, not the fit
  o.max_outlier_fraction = 1.0;
  o.max_iterations = std::min(o.max_iterations, leave_one_out.max_iterations);
  const BundleAdjuster adjuster(o, ConfigFor(adjusted, options));
  const SurveyResiduals measured = ComputeSurveyResiduals(adjusted, {}, names);
  double sum = 0.0;
  for (const SurveyResidual& control : measured.control) {
    Scene without = adjusted;
    const int j = without.FindPoint(control.id);
    without.points[j].role = PointRole::kCheck;  // free: its survey is not a prior any more
    PlaceOnTheOthers(measured.control, control.id, &without);
    const Summary s = adjuster.Solve(&without);
    if (!s.IsSolutionUsable()) {
      out.failed.push_back(control.name + " (" + s.reason + ")");
      continue;
    }
    SurveyResidual r = control;
    r.residual = without.points[j].position - *without.points[j].surveyed;
    if (!r.has_height) r.residual.z() = 0.0;
    sum += r.residual.squaredNorm();
    out.residuals.push_back(r);
  }
  if (!out.residuals.empty()) out.rms = std::sqrt(sum / static_cast<double>(out.residuals.size()));
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return out;
}

}  // namespace adjustment
}  // namespace slope_monitor
