// The deformation estimator node's work, from ROS messages: each source's
// PointDisplacementArray is checked (MessageValidator), put in one stamp
// order over the inputs (core/common/input_order.h) and fused
// (deformation::Estimator with its SQLite history); the dense step's change
// areas likewise. After each input the snapshot's alert-level changes are
// announced (log lines, the site's notification hook) and the snapshot is
// returned to publish. The deformation_estimator nodelet (in its callbacks,
// with its live time-out) and process_bag (in bag-time order) use this same
// class. Not thread-safe: the caller serialises the calls (the hook's log
// callback runs on the hook's worker thread).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>
#include <std_msgs/Header.h>

#include "slope_monitor/ChangeAreaArray.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/core/common/input_order.h"
#include "slope_monitor/core/deformation/alert_hook.h"
#include "slope_monitor/core/deformation/alert_log.h"
#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/ros/epoch_solver.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/validation.h"

namespace slope_monitor {
namespace ros_adapters {

// A snapshot to publish: header (the input's stamp, frame_id), the alert
// changes it brought (already announced in `log`).
struct EstimatorPublication {
  deformation::Snapshot snapshot;
  std_msgs::Header header;
  std::vector<deformation::AlertChange> changes;
  std::vector<LogLine> log;  // the alert-level changes, never to be throttled
};

// What an input gave: snapshots to publish, and its problems (rejected
// entries, refused measurements, a dropped message: the nodelet throttles them).
struct EstimatorResult {
  std::vector<EstimatorPublication> publications;
  std::vector<LogLine> problems;
};

class EstimatorStep {
 public:
  // `ordered_inputs`: the displacement topics fused in one stamp order (a
  // batch waits until every other input has passed its stamp); empty:
  // arrival order. `hook_log`: the notification hook's lines (error or not),
  // from its worker thread. Throws ConfigError, or deformation::HistoryInUse
  // / IoError for a history that cannot be opened (nothing written to it).
  // `history`: the database already opened (with its writer lock) by the
  // caller (process_bag, which says what it holds before anything else);
  // null: opened here from parameters.database.
  EstimatorStep(const EstimatorParameters& parameters,
                const std::vector<std::string>& ordered_inputs,
                deformation::AlertHook::Log hook_log,
                std::unique_ptr<deformation::History> history = nullptr);

  const EstimatorParameters& parameters() const { return parameters_; }
  bool has_history() const { return history_ != nullptr; }
  bool has_hook() const { return hook_ != nullptr; }
  deformation::Snapshot GetSnapshot() const { return estimator_->GetSnapshot(); }

  // ---- inputs. `now` [s]: the caller's wall clock (0 for a recording: no
  // test of the stamps against it, no time-out).
  EstimatorResult AddDisplacements(const slope_monitor::PointDisplacementArray& msg,
                                   const std::string& topic, double now);
  EstimatorResult AddAreas(const slope_monitor::ChangeAreaArray& msg, const std::string& topic);
  // A source's revised displacements (RadioStep::Finish): they replace the
  // ones received for the same stamps (deformation::Estimator::ReviseBatch).
  EstimatorResult ReviseDisplacements(const slope_monitor::PointDisplacementArray& msg,
                                      const std::string& topic);
  // Live: batches that waited `timeout` for a silent input, fused without it.
  EstimatorResult Expire(double now, double timeout, std::vector<std::string>* given_up);
  // End of the inputs: what waits for a later stamp of another input is fused
  // (`publish` false: fused only, no snapshot returned).
  EstimatorResult Flush(bool publish = true);
  // The current state to publish (a resumed history), stamped `stamp`.
  EstimatorPublication Current(const ros::Time& stamp);
  // The set_reference_epoch service: the epoch chosen in `*chosen`; throws Error.
  EstimatorPublication SetReferenceEpoch(uint32_t epoch, bool use_latest, uint32_t* chosen);

  // Waits until the notification hook has delivered what it was given.
  void FlushHook() {
    if (hook_) hook_->Flush();
  }
  // The reports (deformation::WriteAllReports) under report_dir/subfolder. Throws.
  std::vector<std::string> WriteReports(const std::string& subfolder,
                                        const std::vector<std::string>& formats);

  // The reports once more at the end of the input (a replay's end,
  // shutdown): what still waits for the other inputs is fused first; with
  // report_on_shutdown and a report_dir the reports are written, but none
  // when no point was ever measured (empty files would look like a result).
  // The lines to log (INFO written, WARN nothing measured, ERROR failed).
  std::vector<LogLine> FinalReports();
  // The export_report service: the reports under report_dir/subfolder, the
  // files written. InvalidArgument when report_dir is empty (an export
  // writes only inside it); a failure is kept as the last problem, thrown.
  std::vector<std::string> ExportReports(const std::string& subfolder,
                                         const std::vector<std::string>& formats);

  // The node's diagnostics (counts, last problem).
  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const;
  const std::string& last_problem() const { return last_problem_; }
  // Measurements fused, and refused as already in the history (a recording processed again).
  uint64_t accepted() const { return accepted_; }
  uint64_t already_held() const { return already_held_; }

  void set_last_problem(const std::string& problem) { last_problem_ = problem; }

 private:
  // A message as it arrived, validated; `fuse` false when every entry was rejected.
  struct Incoming {
    slope_monitor::PointDisplacementArray valid;
    bool fuse = true;
  };
  void Fuse(const Incoming& in, const std::string& topic, bool publish, EstimatorResult* out);
  EstimatorPublication Publication(const std_msgs::Header& input);

  EstimatorParameters parameters_;
  std::unique_ptr<deformation::History> history_;  // null: parameter database empty
  std::unique_ptr<deformation::Estimator> estimator_;
  std::unique_ptr<InputOrder<Incoming>> order_;  // null: arrival order
  MessageValidator validator_;
  deformation::AlertChangeTracker alert_changes_;
  std::unique_ptr<deformation::AlertHook> hook_;  // the site's notification hook, if any
  uint64_t messages_ = 0, accepted_ = 0, refused_ = 0, errors_ = 0, already_held_ = 0, revised_ = 0;
  size_t num_points_ = 0;
  deformation::AlertLevel last_alert_ = deformation::AlertLevel::kNone;
  std::string last_problem_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
