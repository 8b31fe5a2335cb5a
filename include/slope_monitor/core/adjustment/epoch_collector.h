// Epoch collection for the bundle adjuster, with no ROS in it: what is
// collected (target observations, tie points, GNSS position priors), when a
// survey epoch is complete, which images belong to it and which to the next,
// and (EpochStore) what an accepted epoch changes (poses, calibration, the
// reference epoch). The bundle_adjuster nodelet and the process_bag tool feed
// the same EpochCollector, so both give the same epochs.
//
// Completion is decided by the messages, never by a clock:
//   * every configured camera (with none configured: any source) has sent its
//     end marker (EpochEnd), and
//   * every image a marker announced (EpochEnd::count) has delivered its
//     targets, or the camera's next image (stamp after its marker) has come:
//     a camera's images arrive in order, so a missing one is not coming, and
//   * with tie points expected, every image b of a tie_point_camera up to its
//     marker has all the tie-point messages its matcher announced (pairs_b).
//   * A camera that sent no end marker while another source already ended its
//     NEXT epoch is incomplete (a UAV flight cut short): the complete cameras
//     are solved, the incomplete one is named in CollectedEpoch::incomplete
//     and its images of this epoch are left out.
//   * Without any end marker, an image more than epoch_gap after the latest
//     collected one ends the epoch collected so far.
// Poll(now) is the only place time counts: the time-outs of live sensors
// (epoch_wait, tie_point_wait, epoch_gap in the caller's clock). When one fires,
// CollectedEpoch::incomplete names the input given up on. Finish() ends the
// input (end of a bag): what is collected is returned with what is missing.
//
// Bad observations (non-finite pixel, covariance not finite, not positive
// definite or with a sigma above max_pixel_sigma) are dropped one by one and
// named in CollectedEpoch::dropped; the rest of the epoch is solved.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace adjustment {

// A message stamp: nanoseconds in the time base of the messages (ROS / bag time).
using StampNs = int64_t;
StampNs MakeStamp(int64_t sec, int64_t nsec);
double StampSeconds(StampNs stamp);  // sec + 1e-9 nsec, as ros::Time::toSec()
// "north_ridge@1700000000.500000000": the image's name in the scene.
std::string ImageKey(const std::string& camera, StampNs stamp);
// A UAV camera (self-calibrated per flight, never keeps a pose between
// epochs): one of `uav_cameras`, the cameras of kind uav of the site file
// (or of io::DefaultCameras()); never decided by the name.
bool IsUavCamera(const std::string& camera, const std::vector<std::string>& uav_cameras);
// The cameras of kind uav of io::DefaultCameras(): ["uav"].
std::vector<std::string> DefaultUavCameras();

// One target observation of an image (TargetObservation).
struct TargetInput {
  int id = -1;         // -1: unidentified (a circle the centroider could not name)
  std::string family;  // "tag36h11", "circle"
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();       // [px]
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2]; zero: not given (pixel_sigma)
};

// All targets of one image (TargetObservationArray).
struct ImageTargets {
  std::string camera;
  std::string frame_id;  // "" -> "<camera>_optical"
  StampNs stamp = 0;
  uint32_t epoch = 0;  // 0: unknown
  std::vector<TargetInput> targets;
};

// One match between images a and b (TiePoint).
struct TieInput {
  int64_t id = 0;  // track id; 0: no track
  double quality = 1.0;
  Eigen::Vector2d a = Eigen::Vector2d::Zero(), b = Eigen::Vector2d::Zero();  // [px]
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2]; zero: not given
};

// The matches of one image pair (TiePointArray).
struct ImageTies {
  std::string camera_a, camera_b;  // camera_a "": image b found no partner
  std::string frame_a, frame_b;
  StampNs stamp_a = 0, stamp_b = 0;
  uint32_t pairs_b = 0;  // messages image b gets (sequence mode); 0: not counted
  std::vector<TieInput> points;
};

// A GNSS projection centre (PoseWithCovarianceStamped, position part) and,
// when the flight log gives one, the photo's attitude (orientation part: the
// optical frame in site, its variances about x, y, z of site).
struct PositionPrior {
  StampNs stamp = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();        // [m] site
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();  // [m^2]
  Eigen::Quaterniond site_from_optical = Eigen::Quaterniond::Identity();
  Eigen::Vector3d attitude_variance =
      Eigen::Vector3d::Constant(1e6);  // [rad^2]; >= 1e6: no attitude
};

// An epoch end marker (EpochMarker with end = true).
struct EpochEnd {
  std::string source;
  StampNs stamp = 0;
  uint32_t epoch = 0;
  uint32_t count = 0;  // images of the epoch
};

struct CollectedImage {
  std::string key, camera, frame_id;
  StampNs stamp = 0;
};

struct CollectedObservation {
  std::string image_key;
  std::string point_id;  // "" for an unidentified target
  std::string family;
  PointRole role = PointRole::kTie;
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();  // with the floors added
};

// One complete epoch, ready for BuildScene().
struct CollectedEpoch {
  uint32_t epoch = 0;
  std::map<std::string, CollectedImage> images;  // by ImageKey
  std::vector<CollectedObservation> observations, unidentified;
  std::vector<PositionPrior> priors;
  StampNs latest_stamp = 0;  // of its images
  // Inputs given up on: "drone: no end marker (3 images left out)",
  // "gully_2: 1 of 2 announced images", "tie points of 'drone@...': 1 of 3 messages".
  std::vector<std::string> incomplete;
  std::vector<std::string>
      dropped;         // bad observations: "north_ridge@...: tag36h11/3: covariance not finite"
  std::string reason;  // what completed it: "end markers", "time-out", "end of input", ...
};

struct EpochCollectorOptions {
  std::vector<std::string> cameras;            // cameras that must end an epoch; empty: any source
  std::vector<std::string> tie_point_cameras;  // cameras whose images wait for their tie points
  std::vector<std::string> uav_cameras = DefaultUavCameras();  // kind uav (site file)
  double pixel_sigma = 0.3;            // [px] observations without a covariance, > 0
  double pixel_sigma_floor = 0.05;     // [px] added in quadrature, fixed cameras, >= 0
  double uav_pixel_sigma_floor = 1.0;  // [px] added in quadrature, UAV cameras, >= 0
  double tie_pixel_sigma_floor = 0.2;  // [px] added in quadrature to tie points, >= 0
  double min_tie_quality = 0.25;       // [0..1] tie points at or below are skipped
  double max_pixel_sigma =
      100.0;                      // [px] an observation with a larger sigma is absurd: dropped, > 0
  double epoch_gap = 600.0;       // [s] message gap ending an epoch without markers; 0: off
  double epoch_wait = 30.0;       // [s] live time-out after the last end marker, >= 0
  double tie_point_wait = 300.0;  // [s] live time-out for tie points, >= 0
  void Check() const;             // throws ConfigError naming the field
};

class EpochCollector {
 public:
  // `targets` (may be null) gives the roles of identified targets; it must
  // outlive the collector. Throws ConfigError from options.Check().
  EpochCollector(const EpochCollectorOptions& options, const io::TargetList* targets);

  // Each input returns the epochs it completed (none, or one; a message that
  // also completes the deferred next epoch may give two). `now` [s] is the
  // caller's clock, used only by Poll().
  std::vector<CollectedEpoch> AddTargets(const ImageTargets& image, double now);
  std::vector<CollectedEpoch> AddTies(const ImageTies& ties, double now);
  void AddPrior(const PositionPrior& prior);
  std::vector<CollectedEpoch> AddEnd(const EpochEnd& end, double now);
  // Live time-outs at `now` (same clock as the Add calls).
  std::vector<CollectedEpoch> Poll(double now);
  // End of input: the epoch collected so far (complete or not, what is
  // missing named); nullopt when nothing was collected.
  std::optional<CollectedEpoch> Finish();
  // The epoch being collected, now (the run_adjustment service).
  CollectedEpoch TakeNow();

  // False while nothing publishes tie points (a matcher not started or
  // failed): images do not wait for them. True by default.
  void SetTiePointsExpected(bool expected) { tie_points_expected_ = expected; }

  uint32_t current_epoch() const { return current_epoch_; }
  size_t num_images() const { return images_.size(); }
  size_t num_observations() const { return observations_.size(); }
  uint64_t unidentified_received() const { return unidentified_received_; }
  uint64_t tie_points_used() const { return tie_points_used_; }
  uint64_t tie_points_low_quality() const { return tie_points_low_quality_; }
  uint64_t observations_dropped() const { return observations_dropped_; }
  // Input that was ignored (duplicate or stale end markers, a camera in
  // another camera's frame), one line each.
  const std::vector<std::string>& ignored() const { return ignored_; }

 private:
  struct TieCount {
    uint32_t received = 0, expected = 0;
  };
  void RememberImage(const std::string& key, const std::string& camera, const std::string& frame_id,
                     StampNs stamp);
  // Validates and floors a covariance; nullopt (reason in *why) for a bad one.
  std::optional<Eigen::Matrix2d> Covariance(const Eigen::Matrix2d& given, double floor,
                                            std::string* why) const;
  // An end marker: of this epoch, of the next one (deferred), or ignored.
  void Route(const EpochEnd& end, double now);
  bool InEpoch(const std::string& camera, StampNs stamp) const;
  bool LeftOut(const std::string& camera) const;  // a configured camera without an end marker
  StampNs Cutoff() const;                         // latest end marker stamp
  std::vector<std::string> MissingEnds() const;   // configured cameras without an end marker
  // Ended sources short of their announced count (blocking_only: and no later
  // image of that camera has come).
  std::vector<std::string> MissingImages(bool blocking_only) const;
  std::vector<std::string> MissingTies() const;  // images short of their tie-point messages
  std::vector<std::string> AllMissing() const;
  bool Ready() const;
  // Takes every ready epoch (a deferred marker may make the next one ready).
  std::vector<CollectedEpoch> TakeReady(double now);
  CollectedEpoch Take(const std::string& reason, std::vector<std::string> incomplete, double now);

  EpochCollectorOptions options_;
  const io::TargetList* targets_ = nullptr;
  bool tie_points_expected_ = true;

  std::map<std::string, CollectedImage> images_;
  std::map<std::string, std::string> frame_owner_;  // optical frame -> the camera that uses it
  // Images whose targets message is in (every camera's centroider sends one
  // per photo, empty on a site without targets): only these count against
  // an end marker's image count. An image known only from tie points (the
  // matcher is faster than the centroider) is not complete yet.
  std::set<std::string> targets_in_;
  std::vector<CollectedObservation> observations_, unidentified_;
  std::vector<std::pair<std::string, std::string>> dropped_;  // image key, line
  std::vector<PositionPrior> priors_;
  std::map<std::string, TieCount> tie_counts_;  // per image b
  // The epoch's end markers: stamp and announced count per source.
  std::map<std::string, EpochEnd> ends_;
  std::vector<EpochEnd> deferred_ends_;        // next epoch's markers, while this one waits
  std::set<std::string> cut_short_;            // cameras declared incomplete by a next-epoch marker
  std::map<std::string, StampNs> solved_end_;  // last solved end marker per source
  std::map<std::string, StampNs> latest_image_;  // per camera
  double ended_at_ = 0.0, last_input_at_ = 0.0;
  uint32_t current_epoch_ = 0;
  uint64_t unidentified_received_ = 0, tie_points_used_ = 0, tie_points_low_quality_ = 0,
           observations_dropped_ = 0;
  std::vector<std::string> ignored_;
};

struct BuildSceneOptions {
  double position_prior_max_dt = 0.1;      // [s] prior to image stamp, >= 0
  double position_prior_min_sigma = 0.01;  // [m] floor of the prior's sigma, > 0
  // A UAV photo whose prior carries an attitude with every sigma at most this
  // starts from it (GNSS centre + flight-log attitude) instead of being
  // resected or oriented incrementally; 0 ignores the priors' attitudes.
  double attitude_prior_max_sigma = 5.0 * 3.14159265358979323846 / 180.0;  // [rad], >= 0
  int min_images = 2;                                          // images with a camera model, >= 1
  std::vector<std::string> uav_cameras = DefaultUavCameras();  // kind uav (site file)
  void Check() const;  // throws ConfigError naming the field
};

// Accepted epochs: the poses and calibration the next epoch starts from, the
// adjusted points of every epoch and the reference epoch.
class EpochStore {
 public:
  const camera::CameraModel* Calibrated(const std::string& camera) const;
  const camera::ExteriorOrientation* LastPose(const std::string& camera) const;
  // A usable solution: remembers the poses (by camera) and calibrations, stores
  // its points; the first accepted epoch becomes the reference.
  EpochPoints Accept(const Scene& scene, const Summary& summary, int epoch, double stamp,
                     bool datum_free);
  // Displacements of `current` against the reference; nullopt without a
  // reference or when `current` is the reference.
  std::optional<EpochComparison> CompareWithReference(const EpochPoints& current,
                                                      const DisplacementOptions& options) const;
  const EpochPoints* Reference() const;
  // The set_reference_epoch service: "" on success (*chosen set), else why not.
  std::string SetReference(bool use_latest, int epoch, int* chosen);
  int reference_epoch() const { return reference_epoch_; }
  int accepted() const { return static_cast<int>(epochs_.size()); }

  // What a later run of the same site needs (the site's history keeps it,
  // deformation/history.h): the reference epoch's points (positions, roles,
  // covariances), exact to the bit (core/common/state_text.h). Not the
  // cameras' last poses and calibrations: an epoch's start values then do
  // not depend on which runs came before, so a run again on the same
  // history (after kill -9) gives bit for bit the numbers of one that never
  // stopped.
  std::string Save() const;
  // Replaces the store's content with a saved one (the reference becomes
  // the saved reference; no poses, no calibrations); throws InvalidArgument
  // for text that is not one.
  void Load(const std::string& text);

 private:
  std::map<std::string, camera::CameraModel> calibrated_;
  std::map<std::string, camera::ExteriorOrientation> last_pose_;
  std::map<int, EpochPoints> epochs_;
  int reference_epoch_ = -1;
};

struct BuiltScene {
  Scene scene;
  std::vector<UnidentifiedObservation> unidentified;
  std::vector<std::string> cameras_without_model;
};

// The scene of a collected epoch: cameras with a model (the store's
// calibration when it has one), images (fixed cameras start from their last
// accepted pose; GNSS priors within position_prior_max_dt), points with their
// role and survey from the target list. Throws InvalidArgument when fewer than
// min_images images have a camera model (naming a camera without one).
BuiltScene BuildScene(const CollectedEpoch& epoch,
                      const std::map<std::string, camera::CameraModel>& models,
                      const EpochStore& store, const io::TargetList& targets,
                      const BuildSceneOptions& options);

// Every listed target with coordinates, for naming unidentified targets.
std::vector<ListedTarget> ListedTargets(const io::TargetList& targets);

// The role of a listed target (kTie for one not in the list).
PointRole RoleOf(const io::TargetSpec* spec);

}  // namespace adjustment
}  // namespace slope_monitor
