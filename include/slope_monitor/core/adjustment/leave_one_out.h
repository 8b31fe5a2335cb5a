// Leave-one-out over the control points of an adjusted epoch: each control
// point the photos measured (seen in two images or more) is in turn made a
// check point (its survey out of the adjustment), the block is placed on
// the other control points (PlacementOnControl) and adjusted again with the
// epoch's own options, and that point's residual (adjusted - surveyed) is
// taken. It says how well the block places
// a point the survey does not hold, for every control point, where the check
// points say it only for the few set aside (COLMAP #767, ODM #883: what
// crews ask for). process_flight reports the same for a folder
// (flight_orientation.h).
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/survey_residuals.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace adjustment {

struct LeaveOneOutOptions {
  // Iterations of each adjustment without one point: it starts from the
  // epoch's solution placed on the other control points, a few steps reach
  // the new minimum (> 0).
  int max_iterations = 50;
  void Check() const;  // throws ConfigError naming the field
};

struct LeaveOneOutReport {
  std::vector<SurveyResidual> residuals;  // one per control point left out, scene order
  double rms = 0.0;                       // [m] 3-D (dz 0 without a height); 0 when none
  std::vector<std::string> failed;        // "gcp05: <why the adjustment without it failed>"
  double seconds = 0.0;                   // [s] wall clock
  // "leave-one-out rms 1.780 m over 6 control points" (+ "; not adjusted
  // without: gcp05 (...)"); "" when no control point was left out.
  std::string Brief() const;
  // "left out gcp03 (0.512, -1.234, no height) m", one per point.
  std::vector<std::string> Lines() const;
};

// The similarity that places a block on control points: from their adjusted
// positions to their surveys, weighted by `weights` (1 / horizontal
// variance), in x and y only when `heights` is false (nothing but a loose
// prior holds the block's height and tilt then, and the similarity leaves
// them). nullopt for fewer than 3 points or collinear ones. Leaving a control
// point out starts from it: from the solution with the point, Levenberg-
// Marquardt's damped first steps would not move a block along a weak datum
// (control to 1 m, no GNSS: its shift is 1e-15 of the normal matrix) and the
// function tolerance stops it there (copr: every residual came back as the
// control residual).
std::optional<geometry::Similarity3> PlacementOnControl(
    const std::vector<Eigen::Vector3d>& adjusted, const std::vector<Eigen::Vector3d>& surveyed,
    const std::vector<double>& weights, bool heights);

// `adjusted`: an epoch's adjusted scene (EpochAdjustmentResult::scene);
// `options`: the options it was adjusted with (covariance and the
// usability limits other than the datum are not needed here and left out);
// `names`: a point's name by its id (ComputeSurveyResiduals).
LeaveOneOutReport LeaveOneOut(const Scene& adjusted, const EpochAdjustmentOptions& options,
                              const std::map<std::string, std::string>& names = {},
                              const LeaveOneOutOptions& leave_one_out = {});

}  // namespace adjustment
}  // namespace slope_monitor
