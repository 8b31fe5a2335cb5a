// One survey epoch from collected observations to an adjusted scene, the way
// the bundle_adjuster nodelet runs it, with what UAV photos need on top of
// the plain adjustment:
//
//   1. InitializeScene(): resection / intersection from the control points.
//   2. Photos with a GNSS position prior that are still not oriented (they see
//      monitoring targets only, whose coordinates are not known yet) are
//      oriented from the APPROXIMATE coordinates of the listed targets they
//      see (ObjectPoint::approximate, e.g. hand-held GNSS, 0.3 m) with the
//      prior as projection centre. Those coordinates are used for this initial
//      orientation only; the points stay free unknowns of the adjustment.
//   3. NameUnidentified(): unidentified targets (circles, which the centroider
//      cannot name without a pose) are named in every oriented image by
//      projecting the listed targets of the same family: the unique
//      unidentified observation within a gate around the unique listed target
//      projected there gets its name; ambiguity leaves it unnamed (counted).
//   4. Initialise again (new points intersected), drop what cannot be
//      adjusted (PruneScene; photos with a GNSS prior need fewer image
//      observations), adjust. Then, with the adjusted orientations, name
//      what is still unnamed (tight gates) and adjust once more.
//   5. With tie points, a screening adjustment first removes the tie-point
//      observations whose whitened residual exceeds the outlier threshold.
//      Named observations whose whitened residual exceeds the outlier
//      threshold are wrong names: they are removed, reported (Summary::reason
//      and EpochAdjustmentResult::rejected_names), and the epoch is adjusted
//      again without them. A solution that is not usable with the named
//      observations is tried once more without any of them.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/initialization.h"

namespace slope_monitor {
namespace adjustment {

// A target seen in an image but not identified (id -1 from the centroider).
struct UnidentifiedObservation {
  int image = 0;                  // index into Scene::images
  std::string family = "circle";  // only listed targets of this family can name it
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();                  // [px]
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity() * 0.01;  // [px^2]
};

// A target of the site's list that may name unidentified observations.
struct ListedTarget {
  std::string id;    // "circle/12" (the point id in the scene)
  std::string name;  // what the crew calls it (io::TargetSpec::Label: "gcp03", else the id)
  std::string family = "circle";
  PointRole role = PointRole::kMonitoring;
  Eigen::Vector3d position =
      Eigen::Vector3d::Zero();  // [m] site: survey (control, check) or approximate (monitoring)
  double position_sigma = 0.3;  // [m] 1-sigma of `position`, > 0
  // Control / check: the survey used as the prior of a new point (as in the
  // scene's ObjectPoint).
  std::optional<Eigen::Vector3d> surveyed;
  Eigen::Matrix3d surveyed_covariance = Eigen::Matrix3d::Identity() * 1e-4;  // [m^2]
};

struct NamingOptions {
  // Gate around a listed target's projection: gate_sigma times its position
  // sigma projected into the image plus gate_extra_px for the orientation
  // error of the image; at least min_gate_px.
  double gate_sigma = 3.0;      // [-] > 0
  double gate_extra_px = 10.0;  // [px] >= 0
  double min_gate_px = 8.0;     // [px] > 0
  // Another unidentified observation within ambiguity_factor x gate of the
  // projection, or another listed target projected within ambiguity_factor x
  // gate of the observation: ambiguous, not named.
  double ambiguity_factor = 2.0;  // [-] >= 1
  // Images oriented only from approximate coordinates (tens of mrad off):
  // this instead of gate_extra_px. Circles are >= 10 m apart on a site; the
  // ambiguity test and the residual test after the adjustment guard the rest.
  double coarse_extra_px = 100.0;  // [px] >= 0
  void Check() const;              // throws ConfigError naming the field
};

struct NamingReport {
  int considered = 0;  // unidentified observations in oriented images
  int named = 0;
  int ambiguous = 0;                    // more than one candidate (target or observation) near
  int unmatched = 0;                    // no listed target projects within the gate
  int not_oriented = 0;                 // in images without an orientation: not tried
  std::vector<int> named_observations;  // indices into Scene::observations of the named ones
  std::vector<int> named_inputs;        // indices into `unidentified` of the named ones
  std::vector<std::string> notes;       // one line per ambiguous observation
  std::string Brief() const;  // "named 5 of 7 (1 ambiguous, 1 unmatched, 0 in unoriented images)"
};

// Names unidentified observations in the oriented images of *scene (step 3
// above) and appends them as observations (and, for targets not yet in the
// scene, as points: control / check with their survey, others unknown).
// Candidate positions: the scene's point when it has a position, else the
// listed one. Images flagged in `coarse` (may be null) get the coarse gate.
// Throws ConfigError from options.Check().
NamingReport NameUnidentified(Scene* scene,
                              const std::vector<UnidentifiedObservation>& unidentified,
                              const std::vector<ListedTarget>& targets,
                              const NamingOptions& options = {},
                              const std::vector<bool>* coarse = nullptr);

// Orients the images with a GNSS prior that InitializeScene() left without
// an orientation from the approximate coordinates of the points they see
// (step 2), or, when they see one such point only, with the attitude of the
// photo of the same camera nearest in time tilted onto that point, or, when
// they see none (tied to the block by tie points only), with that photo's
// attitude at their own GNSS position. Returns
// how many were oriented and flags them in *oriented (may be null; resized to
// the images). The points are left unknown.
int OrientFromApproximatePoints(Scene* scene, const InitializationOptions& options = {},
                                std::vector<bool>* oriented = nullptr);

struct EpochAdjustmentOptions {
  Options adjustment;
  InitializationOptions initialization;
  NamingOptions naming;
  std::vector<int> free_interior;  // self-calibrated interior parameters of every camera
  // Per camera (Camera::name): these instead of free_interior (an empty list
  // fixes that camera's interior), e.g. a UAV camera self-calibrated in
  // every flight while the fixed cameras keep their calibration.
  std::map<std::string, std::vector<int>> free_interior_by_camera;
  bool orient_from_approximate = true;  // step 2
  bool name_unidentified = true;        // step 3
  // The screening adjustment of the tie points removes what it flags (residual
  // above adjustment.outlier_threshold) only when that is at most this share
  // of the tie observations: more means the fit failed, not the points.
  double max_tie_outlier_share = 0.3;  // (0, 1]
  // Images with a GNSS position prior need adjustment.min_observations_with_prior
  // observations of initialised points to stay (the others
  // adjustment.min_observations_per_image).
  void Check() const;  // throws ConfigError naming the field
};

// What happened to the images that carry a GNSS prior (UAV photos).
struct PhotoStats {
  int total = 0;
  int kept = 0;
  int not_oriented =
      0;  // no resection, no attitude from the prior and the known / approximate points
  int too_few_observations = 0;
  std::string Brief() const;  // "UAV photos: 7 of 9 kept (1 not oriented, 1 too few observations)"
};

struct EpochAdjustmentResult {
  Scene scene;  // the adjusted scene (pruned and re-indexed); valid when summary is usable
  Summary summary;
  std::string
      initialization;  // InitializeScene's message of the last pass ("" = everything initialised)
  PruneReport pruned;
  NamingReport naming;
  PhotoStats photos;
  int oriented_from_approximate = 0;
  std::vector<std::string> rejected_names;  // "circle/12 in 'uav@...': 7.3 sigma (11.2 px)"
  bool retried_without_names = false;
  // Tie-point observations removed before the final adjustment: whitened
  // residual above the outlier threshold in a screening adjustment (a
  // mismatch; tie points are plentiful, and a few gross ones in the robust
  // loss's linear range keep the solver creeping for hundreds of steps).
  int tie_outliers_removed = 0;
  // Picks of points picked by hand (a gcp list) removed by the same screening.
  int wrong_picks_removed = 0;
  std::string tie_screening_refused;  // why the screening removed nothing although it flagged
                                      // (empty: applied)
};

// What an epoch's adjustment of `scene` holds: the interior parameters free
// for every camera (free_interior), or a camera's own list
// (free_interior_by_camera; empty: none free).
Config ConfigFor(const Scene& scene, const EpochAdjustmentOptions& options);

// Steps 1-5 on a copy of `scene`. Does not throw for bad observations (the
// Summary says why); throws ConfigError for bad options and InvalidArgument
// for indices that point nowhere.
EpochAdjustmentResult AdjustEpoch(const Scene& scene,
                                  const std::vector<UnidentifiedObservation>& unidentified,
                                  const std::vector<ListedTarget>& targets,
                                  const EpochAdjustmentOptions& options);

}  // namespace adjustment
}  // namespace slope_monitor
