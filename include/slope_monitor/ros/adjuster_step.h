// The bundle adjuster node's work, from ROS messages: target observations,
// tie points, GNSS position priors, epoch end markers and camera_info go to
// the core's EpochCollector (which decides when an epoch is complete); each
// complete epoch is solved (SolveCollectedEpoch) into the messages to
// publish. The bundle_adjuster nodelet (in its callbacks, behind its cameras'
// marker order and its live time-outs) and process_bag (in bag-time order)
// use this same class; which cameras a replay's epochs wait for is decided
// by ReplayCameras for both.
// Not thread-safe: the caller serialises the calls.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <visualization_msgs/MarkerArray.h>

#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/common/input_order.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/ros/epoch_solver.h"
#include "slope_monitor/ros/node_parameters.h"

namespace slope_monitor {
namespace ros_adapters {

// The cameras a replay's epochs wait for: without live time-outs, a camera
// of the site file that never sends (the UAV did not fly) would hold every
// epoch to the end, so a site file's cameras (or the graph's default ones,
// graph_cameras) are kept only where `present(camera)` (the replay has its
// input); all of them when none or every one is present, and the
// parameters' cameras when they are neither. One kInfo line in `*log` per
// camera left out.
std::vector<std::string> ReplayCameras(const AdjusterParameters& parameters,
                                       const std::function<bool(const std::string&)>& present,
                                       std::vector<LogLine>* log);

// The configured cameras' epoch markers in epoch order (the live node; a
// bag is read in order): each camera's topic is in order, but on a fast
// replay or a busy machine one camera's next epoch can overtake another's
// end marker, which would cut that one short. A camera's marker of epoch k
// waits until every camera has begun epoch k; unnumbered markers (epoch 0)
// and those of other sources pass at once, as every marker without cameras.
class EpochMarkerOrder {
 public:
  using Marker = slope_monitor::EpochMarkerConstPtr;
  explicit EpochMarkerOrder(const std::vector<std::string>& cameras);

  // The markers that may go on now (`msg` among them or not), in order.
  std::vector<Marker> Add(const Marker& msg, double now);
  // Live: a camera silent for `wait` [s] no longer holds the others' markers
  // (named in `*given_up`).
  std::vector<Marker> Expire(double now, double wait, std::vector<std::string>* given_up);
  std::vector<Marker> Flush();  // end of input: every marker held

 private:
  std::vector<Marker> Items(const std::vector<InputOrder<Marker>::Released>& released) const;

  std::vector<std::string> cameras_;
  std::unique_ptr<InputOrder<Marker>> order_;  // null without cameras
};

class AdjusterStep {
 public:
  // The key of the epoch store (its reference epoch) in the site's history
  // (deformation::SavedStates).
  static constexpr char kStoreKey[] = "adjuster";

  // `source_name`: the displacement messages' source (the node's name).
  // Throws ConfigError from the collector's options.
  AdjusterStep(const AdjusterParameters& parameters, const std::string& source_name);

  const AdjusterParameters& parameters() const { return parameters_; }
  // Epochs wait only for `cameras` from now on (ReplayCameras; at the first
  // input, before anything is collected).
  void KeepCameras(const std::vector<std::string>& cameras);
  // False while nothing publishes tie points (nothing to wait for).
  void SetTiePointsExpected(bool expected) { collector_->SetTiePointsExpected(expected); }

  // ---- inputs; `now` [s]: the caller's clock (wall or bag time). Each
  // returns the epochs it completed, solved (published by the caller).
  // A camera_info that cannot be read: its reason (the camera's model stays).
  std::optional<std::string> OnCameraInfo(const std::string& camera,
                                          const sensor_msgs::CameraInfo& info);
  std::vector<SolvedEpoch> AddTargets(const slope_monitor::TargetObservationArray& msg, double now);
  std::vector<SolvedEpoch> AddTies(const slope_monitor::TiePointArray& msg, double now);
  void AddPrior(const geometry_msgs::PoseWithCovarianceStamped& msg);
  // An end marker; a duplicate or stale one is ignored with a kWarn line in `*ignored`.
  std::vector<SolvedEpoch> AddEnd(const slope_monitor::EpochMarker& msg, double now,
                                  std::vector<LogLine>* ignored);
  std::vector<SolvedEpoch> Poll(double now);  // live time-outs
  std::optional<SolvedEpoch> Finish();        // end of input: the epoch still open
  SolvedEpoch SolveNow();                     // the epoch being collected (run_adjustment)
  uint32_t current_epoch() const { return collector_->current_epoch(); }

  // The camera frustums of a solved epoch (rviz).
  visualization_msgs::MarkerArray Frustums(const SolvedEpoch& epoch) const;
  adjustment::EpochStore& store() { return store_; }
  int accepted() const { return accepted_; }
  // The store into the site's history (parameters().database), e.g. after
  // the set_reference_epoch service; nothing without a database.
  void SaveStore();
  // How the run started (a line for the log): the reference epoch loaded
  // from the site's history, or "" when it starts without one.
  const std::string& resumed() const { return resumed_; }

  // The node's diagnostics: the last epoch, the collector's counts.
  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const;

 private:
  std::vector<SolvedEpoch> Solve(const std::vector<adjustment::CollectedEpoch>& epochs);
  SolvedEpoch Solve(const adjustment::CollectedEpoch& epoch);

  AdjusterParameters parameters_;
  std::string source_name_;
  std::unique_ptr<adjustment::EpochCollector> collector_;  // reads parameters_.targets
  adjustment::EpochStore store_;
  std::unique_ptr<deformation::SavedStates> states_;  // the site's history; null: none
  std::string resumed_;
  int saved_reference_ = -1;  // the reference epoch the history holds (-1: none)
  std::map<std::string, camera::CameraModel> models_;
  size_t reported_ignored_ = 0;
  // The last epoch, for the diagnostics.
  adjustment::PhotoStats last_photos_;
  adjustment::NamingReport last_naming_;
  int last_rejected_names_ = 0;
  std::string last_message_;
  bool last_usable_ = false;
  int accepted_ = 0;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
