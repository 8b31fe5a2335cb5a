#include "slope_monitor/core/adjustment/survey_residuals.h"

#include <cmath>
#include <cstdio>
#include <set>

#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace adjustment {
namespace {

double Rms(const std::vector<SurveyResidual>& v) {
  if (v.empty()) return 0.0;
  double sum = 0.0;
  for (const SurveyResidual& r : v) sum += r.residual.squaredNorm();
  return std::sqrt(sum / static_cast<double>(v.size()));
}

}  // namespace

std::string ResidualLine(const SurveyResidual& r, const std::string& role) {
  char z[32] = "no height";
  if (r.has_height) std::snprintf(z, sizeof z, "%.3f", r.residual.z());
  char text[200];
  std::snprintf(text, sizeof text, "%s %s (%.3f, %.3f, %s) m", role.c_str(), r.name.c_str(),
                r.residual.x(), r.residual.y(), z);
  return text;
}

std::string SurveyResiduals::Brief() const {
  bool any_height = false;
  for (const auto* v : {&control, &check})
    for (const SurveyResidual& r : *v) any_height = any_height || r.has_height;
  char text[200];
  std::snprintf(text, sizeof text,
                "control rms %.3f m over %zu points, check rms %.3f m over %zu points%s",
                control_rms, control.size(), check_rms, check.size(),
                any_height || (control.empty() && check.empty())
                    ? ""
                    : ", horizontal only: the survey has no heights");
  std::string out = text;
  for (size_t i = 0; i < not_measured.size(); ++i)
    out += (i ? ", " : "; not measured (in fewer than two oriented photos): ") + not_measured[i];
  return out;
}

std::vector<std::string> SurveyResiduals::Lines() const {
  std::vector<std::string> out;
  for (const SurveyResidual& r : check) out.push_back(ResidualLine(r, "check"));
  for (const SurveyResidual& r : control) out.push_back(ResidualLine(r, "control"));
  return out;
}

SurveyResiduals ComputeSurveyResiduals(const Scene& scene, const std::vector<std::string>& listed,
                                       const std::map<std::string, std::string>& names) {
  auto name_of = [&](const std::string& id) {
    const auto it = names.find(id);
    return it == names.end() ? id : it->second;
  };
  // Only points the photos measured: seen in two photos or more.
  std::vector<std::set<int>> seen(scene.points.size());
  for (const Observation& o : scene.observations) seen[o.point].insert(o.image);
  SurveyResiduals out;
  for (size_t j = 0; j < scene.points.size(); ++j) {
    const ObjectPoint& p = scene.points[j];
    if (!p.surveyed || !p.position_known || seen[j].size() < 2) continue;
    if (p.role != PointRole::kControl && p.role != PointRole::kCheck) continue;
    SurveyResidual r;
    r.id = p.id;
    r.name = name_of(p.id);
    r.residual = p.position - *p.surveyed;
    r.has_height = !io::HeightUnknown(p.surveyed_covariance(2, 2));
    if (!r.has_height) r.residual.z() = 0.0;
    (p.role == PointRole::kControl ? out.control : out.check).push_back(r);
  }
  out.control_rms = Rms(out.control);
  out.check_rms = Rms(out.check);
  std::set<std::string> measured;
  for (const auto* v : {&out.control, &out.check})
    for (const SurveyResidual& r : *v) measured.insert(r.id);
  for (const std::string& id : listed)
    if (!measured.count(id)) out.not_measured.push_back(name_of(id));
  return out;
}

}  // namespace adjustment
}  // namespace slope_monitor
