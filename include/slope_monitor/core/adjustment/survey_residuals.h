// How far an adjusted block's control and check points lie from their
// survey: per point the photogrammetric position minus the survey [m] in the
// site frame, and the 3-D RMS over each role. Check points never enter the
// adjustment (bundle_adjuster.h), so theirs is the independent measure of
// the block's accuracy; the control points' shows how the block and the
// survey agree. A survey without a height (io::HeightUnknown: a gcp list
// whose heights are all 0) gives its point's residual in x and y only.
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"

namespace slope_monitor {
namespace adjustment {

struct SurveyResidual {
  std::string id;    // "gcp/3"
  std::string name;  // "gcp03" (the survey's name), else the id
  Eigen::Vector3d residual =
      Eigen::Vector3d::Zero();  // [m] adjusted - surveyed (dz 0 without height)
  bool has_height = true;
};

struct SurveyResiduals {
  std::vector<SurveyResidual> control, check;  // scene order
  double control_rms = 0.0, check_rms = 0.0;   // [m] 3-D, 0 when none
  // Listed control and check points the photos did not measure (list
  // order), by name.
  std::vector<std::string> not_measured;
  // "control rms 1.547 m over 6 points, check rms 2.017 m over 2 points"
  // (", horizontal only: the survey has no heights" when no point has one;
  // "; not measured (in fewer than two oriented photos): gcp04, gcp10").
  std::string Brief() const;
  // "check gcp03 (0.512, -1.234, 0.000) m", one per point, check points first.
  std::vector<std::string> Lines() const;
};

// "check gcp03 (0.512, -1.234, no height) m" for `role` "check".
std::string ResidualLine(const SurveyResidual& r, const std::string& role);

// The control and check points of `scene` (role, a survey, an adjusted
// position, observed in two images or more) after an adjustment; `listed`:
// the ids of the target list's control and check points, those not among
// them go to not_measured; `names`: a point's name by its id (none: the id).
SurveyResiduals ComputeSurveyResiduals(const Scene& scene,
                                       const std::vector<std::string>& listed = {},
                                       const std::map<std::string, std::string>& names = {});

}  // namespace adjustment
}  // namespace slope_monitor
