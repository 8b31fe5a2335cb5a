// One deformation estimate of the slope from every source that measures it.
//
//   deformation::EstimatorOptions options;               // defaults documented below
//   deformation::History history("slope.db");           // optional persistent store
//   deformation::Estimator estimator(options, &history); // resumes what history holds
//   estimator.AddBatch(batch);                           // one source, one epoch
//   deformation::Snapshot s = estimator.GetSnapshot();   // points, alerts, forecasts
//
// Per monitoring point (after alias resolution), a constant-acceleration
// Kalman filter (point_filter.h) is fed by every source's displacements with
// their 3x3 covariances, in stamp order whatever the arrival order. Beside
// the fused filter, each (point, source) pair runs its own filter on that
// source alone: two sources measuring the same point are compared through
// their independent estimates at the time of each new measurement,
//   delta = d_a(t) - d_b(t),  C = P_a(t) + P_b(t),  T = delta' C^-1 delta ~ chi2(3),
// and T > disagreement_threshold is reported (PointState::sources_disagree
// and the reason), never silently averaged: both still enter the fused
// filter, and the flag stays until a later comparison passes.
//
// Alerts (per point): level L in {watch, warning, alarm} is a candidate when
// the speed or the displacement since the reference exceeds the level's
// threshold significantly:
//   |v| - k sigma_v > threshold_L,  sigma_v = sqrt(u' P_v u), u = v / |v|,
//   |d| - k sigma_d > displacement_threshold_L (sigma_d along d likewise).
// A candidate is confirmed when at least `confirm_sources` sources' own
// filters also exceed the threshold significantly, or at least
// `confirm_points` points are candidates for L (or higher). A confirmed level
// is lowered only when both |v| and |d| fall below hysteresis * their threshold_L.
// The slope's level is the highest confirmed point level.
//
// The origin: each point's fused filter and each (point, source) filter
// start at their reference epoch with a zero displacement (PointFilter::
// Origin, an exact zero), so the first displacement after the reference
// already gives a speed d / dt and can raise an alert.
//
// Identity and order: a measurement is what it measures (point, source,
// source name, stamp, reference stamp); one already received is refused,
// whatever its values
// (a recording processed again, a latched topic re-delivered). The state is
// always that of the batches processed in stamp order: a batch older than
// the newest one processed (a recording processed after a later one, weeks
// apart, beyond the filters' reorder window) re-runs every point from the
// batches held (the history's), in stamp order.
//
// Reference: displacements are relative to the reference epoch. The
// history's datum (meta datum_stamp), else the first batch's reference_stamp, is the datum;
// measurements whose reference_stamp differs from it by more than reference_tolerance are refused
// (their source uses another datum) and counted. SetReferenceEpoch re-bases the reported
// displacements on a later epoch: the fused displacement at that epoch's stamp is subtracted (its
// covariance added, ignoring the correlation: conservative).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/deformation/forecast.h"
#include "slope_monitor/core/deformation/point_filter.h"

namespace slope_monitor {
namespace deformation {

class History;

// Values equal to slope_monitor/PointDisplacement SOURCE_*.
enum class Source : uint8_t {
  kTarget = 1,
  kFeature = 2,
  kRadio = 3,
  kSurface = 4,
  kFused = 5,
  kOther = 9
};
std::string SourceName(Source s);
Source SourceFromInt(int value);  // throws InvalidArgument naming the value

// Values equal to slope_monitor/DeformationPoint ALERT_*.
enum class AlertLevel : uint8_t { kNone = 0, kWatch = 1, kWarning = 2, kAlarm = 3 };
std::string AlertName(AlertLevel level);

// One displacement measurement of one point by one source.
struct Measurement {
  std::string point_id;
  Source source = Source::kOther;
  std::string source_name;  // node or sensor
  uint32_t epoch = 0;
  double stamp = 0.0;            // [s] time of the measurement
  double reference_stamp = 0.0;  // [s] time of the source's reference epoch
  Eigen::Vector3d reference_position = Eigen::Vector3d::Zero();  // [m] site
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();        // [m] site
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Identity();      // [m^2]
};

// Measurements of one source at one epoch (one PointDisplacementArray).
struct Batch {
  uint32_t epoch = 0;
  double stamp = 0.0;  // [s] header stamp
  std::vector<Measurement> measurements;
};

// One area of significant surface change (change_areas.h): a polygon of a
// DoD's significant cells (source `surface`).
struct ChangeArea {
  int sign = 0;                                     // +1 gain (fill), -1 loss (cut)
  double area = 0.0;                                // [m^2]
  double volume = 0.0;                              // [m^3] signed
  double mean_change = 0.0;                         // [m]
  double max_change = 0.0;                          // [m] signed
  std::vector<Eigen::Vector2d> outline;             // site x, y, closed implicitly
  std::vector<std::vector<Eigen::Vector2d>> holes;  // interior rings
};

// Every polygon of one epoch's DoD (one ChangeAreaArray message).
struct AreaBatch {
  uint32_t epoch = 0;
  uint32_t reference_epoch = 0;
  double stamp = 0.0;  // [s] the epoch's stamp
  std::string source_name;
  std::vector<ChangeArea> areas;
};

// Thresholds of the three levels (watch < warning < alarm): on the speed
// [m/s], and on the cumulative displacement since the reference epoch [m]
// (monitoring systems offer both: a slope creeping a few mm a month between
// flights weeks apart crosses a displacement threshold long before a speed one).
struct Thresholds {
  double watch = 1.0 / 86400.0 * 1e-3 * 2.0;      // [m/s] 2 mm/day
  double warning = 1.0 / 86400.0 * 1e-3 * 10.0;   // [m/s] 10 mm/day
  double alarm = 1.0 / 86400.0 * 1e-3 * 50.0;     // [m/s] 50 mm/day
  double displacement_watch = 0.010;              // [m] 10 mm since the reference
  double displacement_warning = 0.030;            // [m] 30 mm
  double displacement_alarm = 0.100;              // [m] 100 mm
  double Of(AlertLevel level) const;              // speed threshold [m/s]
  double DisplacementOf(AlertLevel level) const;  // displacement threshold [m]
  void Check(const std::string& context) const;   // throws ConfigError
};

struct AlertOptions {
  Thresholds thresholds;
  std::map<std::string, Thresholds> point_thresholds;  // per point overrides (by point_id)
  double significance = 3.0;  // [-] k: the speed must exceed the threshold by k sigma
  int confirm_points = 2;     // [-] points that must be candidates for a level (>= 1)
  int confirm_sources = 2;    // [-] or sources of the same point that exceed it (>= 1)
  double hysteresis = 0.8;    // [-] lower a level only below hysteresis * threshold, (0, 1]
  void Check() const;
};

// Growth of areas of significant surface change that raises an alert (change_areas.h).
struct AreaOptions {
  double growth_watch = 25.0;     // [m^2] a polygon grown by more than this: watch; > 0
  double growth_warning = 100.0;  // [m^2] ... warning; > growth_watch
  void Check() const;             // throws ConfigError naming the field
};

struct EstimatorOptions {
  FilterOptions filter;
  double reorder_window = 3.0 * 86400.0;  // [s] how late a measurement may arrive and still be used
  double reference_tolerance = 3600.0;    // [s] sources' reference stamps must agree within this
  double disagreement_threshold = 16.27;  // [-] chi2(3) at 99.9 %: sources disagree above it
  double comparison_max_gap = 86400.0;  // [s] compare two sources only if both measured within this
  double innovation_gate = 0.0;         // [-] chi2(3) gate of the fused filter; 0: no gating
  double velocity_sample_interval =
      3600.0;  // [s] spacing of the velocity / displacement series kept per point
  std::map<std::string, std::string>
      aliases;  // measured id -> monitoring point id (e.g. "radio/tx1" -> "tag36h11/5")
  AlertOptions alerts;
  AreaOptions areas;
  ForecastOptions forecast;
  void Check() const;  // throws ConfigError naming the field
};

struct SeriesSample {
  double stamp = 0.0;                                      // [s]
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  // [m] relative to the reference epoch
  double sigma = 0.0;                                      // [m] sqrt(trace(P_d)/3)
  double speed = 0.0;                                      // [m/s]
  double speed_sigma = 0.0;                                // [m/s]
};

struct SourceComparison {
  Source a = Source::kOther, b = Source::kOther;
  double stamp = 0.0;
  double statistic = 0.0;                                // chi2(3)
  Eigen::Vector3d difference = Eigen::Vector3d::Zero();  // [m] d_a - d_b
  bool disagree = false;
};

struct SourceEstimate {
  Source source = Source::kOther;
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  // [m]
  Eigen::Matrix3d displacement_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // [m/s]
  double last_stamp = 0.0;
  uint64_t count = 0;
};

struct PointState {
  std::string id;
  Eigen::Vector3d reference_position = Eigen::Vector3d::Zero();  // [m] site
  double stamp = 0.0;                                            // [s] of the estimate
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();        // [m]
  Eigen::Matrix3d displacement_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();  // [m/s]
  Eigen::Matrix3d velocity_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d acceleration = Eigen::Vector3d::Zero();  // [m/s^2]
  double speed = 0.0, speed_sigma = 0.0;                   // [m/s]
  AlertLevel alert = AlertLevel::kNone;
  std::string alert_reason;
  Forecast forecast;
  std::vector<Source> sources;
  std::vector<SourceEstimate> per_source;
  bool sources_disagree = false;
  std::vector<SourceComparison> comparisons;  // latest comparison per source pair
  uint64_t num_measurements = 0;
  uint64_t num_rejected = 0;  // gated by the innovation test
};

struct AreaState {
  std::string id;  // "e03/1": epoch and rank (largest first)
  ChangeArea area;
  uint32_t epoch = 0;
  double stamp = 0.0;
  double growth = 0.0;  // [m^2] against the previous area epoch (change_areas.h)
  AlertLevel alert = AlertLevel::kNone;
  std::string reason;
};

struct Snapshot {
  double stamp = 0.0;  // [s] newest measurement
  uint32_t epoch = 0;  // newest epoch
  uint32_t reference_epoch = 0;
  double reference_stamp = 0.0;  // [s]
  bool has_reference = false;
  std::vector<PointState> points;             // sorted by id
  std::vector<AreaState> areas;               // the latest area epoch's polygons, largest first
  AlertLevel area_alert = AlertLevel::kNone;  // the highest of `areas`
  AlertLevel alert = AlertLevel::kNone;       // the slope's: points and areas
  std::string summary;
};

struct BatchSummary {
  int accepted = 0;
  int refused = 0;                    // other datum, too late, bad covariance, already held
  int already_held = 0;               // of `refused`: measurements already received (AddBatch)
  int revised = 0;                    // measurements replaced (ReviseBatch)
  std::vector<std::string> messages;  // one per refused measurement
};

class Estimator {
 public:
  // With a history, everything it holds is replayed (the reference epoch,
  // the observations in their arrival order), so a restarted estimator is
  // in the same state as one that never stopped. Throws ConfigError.
  explicit Estimator(const EstimatorOptions& options, History* history = nullptr);
  ~Estimator();

  // Commits the batch's observations to the history (one transaction)
  // before using them, then updates the filters, the alerts and the
  // forecasts, and commits the new estimates (one transaction).
  // Throws InvalidArgument for a batch that cannot be used at all (NaN,
  // non-positive-definite covariance: naming the point); refusals of single
  // measurements (other datum, too late) are reported in the summary.
  // A measurement already received (same point, source, source name, stamp
  // and reference stamp) is refused and counted in BatchSummary::already_held (no message:
  // the caller says it once), not stored or fused twice: a re-delivery (a
  // latched topic's last message when a restarted node subscribes again) or
  // a recording processed again.
  BatchSummary AddBatch(const Batch& batch);
  // A source's revised measurements (the radio's epochs tracked again after
  // an earlier recording was processed): each one already received is
  // replaced, in the history too, and every point re-run in stamp order;
  // one not received yet is added as AddBatch adds it. Counted in
  // BatchSummary::revised.
  BatchSummary ReviseBatch(const Batch& batch);

  // Areas of significant surface change of one epoch (source `surface`):
  // replaces the previous area epoch's, their growth against it sets the
  // areas' alert (change_areas.h). An epoch not newer than the latest area
  // epoch (late, or re-delivered by a latched topic) is refused (returns false). Throws
  // InvalidArgument naming a bad polygon. Not kept in the history: a restarted estimator starts a
  // new baseline.
  bool AddAreas(const AreaBatch& batch);

  // Re-bases displacements on epoch `epoch` (which must have been seen), or
  // on the latest epoch. Throws InvalidArgument naming the epoch.
  uint32_t SetReferenceEpoch(uint32_t epoch, bool use_latest);

  Snapshot GetSnapshot() const;
  // Per point displacement / speed series (spaced velocity_sample_interval).
  std::map<std::string, std::vector<SeriesSample>> Series() const;
  const EstimatorOptions& options() const { return options_; }
  const std::map<uint32_t, double>& epochs() const { return epochs_; }
  std::string ResolveAlias(const std::string& id) const;
  Thresholds ThresholdsOf(const std::string& point_id) const;
  // The recording being processed: kept in the history (meta
  // reference_recording) when its measurements set the datum.
  void SetRecording(const std::string& name) { recording_ = name; }

 private:
  struct SourceTrack;
  struct Point;
  struct Held {  // a batch processed, with its observation ids
    Batch batch;
    std::vector<uint64_t> sequences;
  };
  BatchSummary Process(const Batch& batch, const std::vector<uint64_t>& sequences, bool replay);
  // Every point again from the batches held, in stamp order (a late batch).
  void Rerun();
  void ResetState();
  void StoreAllEstimates();  // every point's estimate into the history (one transaction)
  // The first measurement (of a new reference) sets the datum; false while a
  // new reference is awaited and `m` is a held one of the old.
  bool TakeDatum(const Measurement& m, bool replay);
  void Validate(const Measurement& m) const;
  void UpdateAlerts();
  PointState StateOf(const Point& p) const;
  Eigen::Vector3d ReferenceOffset(const Point& p, Eigen::Matrix3d* cov) const;

  EstimatorOptions options_;
  History* history_ = nullptr;
  std::map<std::string, std::unique_ptr<Point>> points_;
  std::map<uint32_t, double> epochs_;  // epoch -> stamp (earliest seen)
  bool has_datum_ = false;
  double datum_stamp_ = 0.0;
  uint32_t reference_epoch_ = 0;
  double reference_stamp_ = 0.0;
  std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>> reference_offsets_;
  double newest_stamp_ = 0.0;
  uint32_t newest_epoch_ = 0;
  uint64_t next_sequence_ = 1;
  std::vector<AreaState> areas_;  // the latest area epoch's
  bool has_areas_ = false;
  uint32_t last_area_epoch_ = 0;
  std::set<std::string> received_;  // keys of every measurement received (duplicate check)
  std::vector<Held> held_;          // every batch processed, in stamp order
  bool has_history_datum_ =
      false;  // the datum once fixed (or the history's), kept through a re-run
  double history_datum_ = 0.0;
  bool datum_pending_ = false;  // a new reference asked for: the next new measurement sets it
  uint64_t reruns_ = 0;
  std::string recording_;

 public:
  // Times a late batch made every point re-run in stamp order.
  uint64_t reruns() const { return reruns_; }
};

}  // namespace deformation
}  // namespace slope_monitor
