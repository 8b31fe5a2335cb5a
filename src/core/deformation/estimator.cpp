#include "slope_monitor/core/deformation/estimator.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include <Eigen/Cholesky>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/deformation/change_areas.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/deformation/units.h"

namespace slope_monitor {
namespace deformation {
namespace {

void SpeedOf(const Eigen::Vector3d& v, const Eigen::Matrix3d& P, double* speed, double* sigma) {
  *speed = v.norm();
  if (*speed > 0.0) {
    const Eigen::Vector3d u = v / *speed;
    *sigma = std::sqrt(std::max(0.0, u.dot(P * u)));
  } else {
    *sigma = std::sqrt(std::max(0.0, P.trace() / 3.0));
  }
}

}  // namespace

std::string SourceName(Source s) {
  switch (s) {
    case Source::kTarget:
      return "target";
    case Source::kFeature:
      return "feature";
    case Source::kRadio:
      return "radio";
    case Source::kSurface:
      return "surface";
    case Source::kFused:
      return "fused";
    case Source::kOther:
      return "other";
  }
  return "unknown";
}

Source SourceFromInt(int value) {
  switch (value) {
    case 1:
      return Source::kTarget;
    case 2:
      return Source::kFeature;
    case 3:
      return Source::kRadio;
    case 4:
      return Source::kSurface;
    case 5:
      return Source::kFused;
    case 9:
      return Source::kOther;
  }
  throw InvalidArgument(Message("unknown displacement source ", value, " (expected 1-5 or 9)"));
}

std::string AlertName(AlertLevel level) {
  switch (level) {
    case AlertLevel::kNone:
      return "none";
    case AlertLevel::kWatch:
      return "watch";
    case AlertLevel::kWarning:
      return "warning";
    case AlertLevel::kAlarm:
      return "alarm";
  }
  return "unknown";
}

double Thresholds::Of(AlertLevel level) const {
  switch (level) {
    case AlertLevel::kWatch:
      return watch;
    case AlertLevel::kWarning:
      return warning;
    case AlertLevel::kAlarm:
      return alarm;
    default:
      return 0.0;
  }
}

double Thresholds::DisplacementOf(AlertLevel level) const {
  switch (level) {
    case AlertLevel::kWatch:
      return displacement_watch;
    case AlertLevel::kWarning:
      return displacement_warning;
    case AlertLevel::kAlarm:
      return displacement_alarm;
    default:
      return 0.0;
  }
}

void Thresholds::Check(const std::string& context) const {
  if (!(watch > 0.0 && warning > watch && alarm > warning) || !std::isfinite(alarm))
    throw ConfigError(Message(
        context, ": velocity thresholds must satisfy 0 < watch < warning < alarm, got ",
        watch * kMmPerDay, " / ", warning * kMmPerDay, " / ", alarm * kMmPerDay, " mm/day"));
  if (!(displacement_watch > 0.0 && displacement_warning > displacement_watch &&
        displacement_alarm > displacement_warning) ||
      !std::isfinite(displacement_alarm))
    throw ConfigError(Message(context,
                              ": displacement thresholds must satisfy 0 < watch < warning < "
                              "alarm, got ",
                              displacement_watch * 1e3, " / ", displacement_warning * 1e3, " / ",
                              displacement_alarm * 1e3, " mm"));
}

void AlertOptions::Check() const {
  thresholds.Check("alerts.thresholds");
  for (const auto& [id, t] : point_thresholds) t.Check("alerts.point_thresholds." + id);
  if (!(significance >= 0.0))
    throw ConfigError(Message("alerts.significance = ", significance, " must be >= 0"));
  if (confirm_points < 1)
    throw ConfigError(Message("alerts.confirm_points = ", confirm_points, " must be >= 1"));
  if (confirm_sources < 1)
    throw ConfigError(Message("alerts.confirm_sources = ", confirm_sources, " must be >= 1"));
  if (!(hysteresis > 0.0 && hysteresis <= 1.0))
    throw ConfigError(Message("alerts.hysteresis = ", hysteresis, " must be in (0, 1]"));
}

void EstimatorOptions::Check() const {
  filter.Check();
  alerts.Check();
  areas.Check();
  forecast.Check();
  if (!(reorder_window >= 0.0))
    throw ConfigError(Message("reorder_window = ", reorder_window, " s must be >= 0"));
  if (!(reference_tolerance >= 0.0))
    throw ConfigError(Message("reference_tolerance = ", reference_tolerance, " s must be >= 0"));
  if (!(disagreement_threshold > 0.0))
    throw ConfigError(Message("disagreement_threshold = ", disagreement_threshold, " must be > 0"));
  if (!(comparison_max_gap > 0.0))
    throw ConfigError(Message("comparison_max_gap = ", comparison_max_gap, " s must be > 0"));
  if (!(innovation_gate >= 0.0))
    throw ConfigError(Message("innovation_gate = ", innovation_gate, " must be >= 0"));
  if (!(velocity_sample_interval > 0.0))
    throw ConfigError(
        Message("velocity_sample_interval = ", velocity_sample_interval, " s must be > 0"));
  for (const auto& [from, to] : aliases) {
    if (from.empty() || to.empty()) throw ConfigError("aliases: empty point id");
    if (aliases.count(to))
      throw ConfigError(Message("aliases: '", from, "' -> '", to, "' chains to another alias"));
  }
}

struct Estimator::SourceTrack {
  SourceTrack(const EstimatorOptions& o) : filter(o.filter, o.reorder_window) {}
  OrderedFilter filter;
  double last_stamp = 0.0;
};

struct Estimator::Point {
  Point(const EstimatorOptions& o) : fused(o.filter, o.reorder_window) {}
  std::string id;
  Eigen::Vector3d reference_position = Eigen::Vector3d::Zero();
  bool reference_from_target = false;
  OrderedFilter fused;
  std::map<Source, SourceTrack> sources;
  std::map<std::pair<Source, Source>, SourceComparison> comparisons;
  AlertLevel alert = AlertLevel::kNone;
  std::string alert_reason;
  Forecast forecast;
  std::vector<SeriesSample> series;  // relative to the datum
  uint64_t rejected = 0;
  struct Raw {
    double stamp;
    Eigen::Vector3d z;
    Eigen::Matrix3d R;
  };
  std::vector<Raw> raw;  // fused measurements in the forecast window, by stamp
};

Estimator::Estimator(const EstimatorOptions& options, History* history)
    : options_(options), history_(history) {
  options_.Check();
  if (!history_) return;
  if (auto d = history_->Meta("datum_stamp")) {
    datum_pending_ = d->empty();
    has_history_datum_ = !d->empty();
    if (has_history_datum_) history_datum_ = std::stod(*d);
  }
  for (History::StoredBatch& sb : history_->LoadBatches())
    held_.push_back({std::move(sb.batch), std::move(sb.sequences)});
  Rerun();
  reruns_ = 0;
  if (auto e = history_->Meta("reference_epoch"))
    reference_epoch_ = static_cast<uint32_t>(std::stoul(*e));
  if (auto s = history_->Meta("reference_stamp")) reference_stamp_ = std::stod(*s);
  reference_offsets_ = history_->LoadReferenceOffsets();
  StoreAllEstimates();
}

void Estimator::StoreAllEstimates() {
  if (!history_) return;
  std::vector<PointState> states;
  for (const auto& [id, p] : points_) states.push_back(StateOf(*p));
  history_->StoreEstimates(states, newest_epoch_);
}

Estimator::~Estimator() = default;

std::string Estimator::ResolveAlias(const std::string& id) const {
  auto it = options_.aliases.find(id);
  return it == options_.aliases.end() ? id : it->second;
}

Thresholds Estimator::ThresholdsOf(const std::string& point_id) const {
  auto it = options_.alerts.point_thresholds.find(point_id);
  return it == options_.alerts.point_thresholds.end() ? options_.alerts.thresholds : it->second;
}

void Estimator::Validate(const Measurement& m) const {
  const std::string who =
      Message("point '", m.point_id, "' from ", SourceName(m.source), " '", m.source_name, "'");
  if (m.point_id.empty())
    throw InvalidArgument(Message("measurement from '", m.source_name, "' has an empty point_id"));
  if (!std::isfinite(m.stamp) || !std::isfinite(m.reference_stamp) || m.stamp < m.reference_stamp)
    throw InvalidArgument(Message(who, ": stamp ", m.stamp,
                                  " must be finite and not before its reference stamp ",
                                  m.reference_stamp));
  if (!m.displacement.allFinite() || !m.reference_position.allFinite())
    throw InvalidArgument(Message(who, ": displacement or reference position is not finite"));
  if (!m.covariance.allFinite() || (m.covariance - m.covariance.transpose()).cwiseAbs().maxCoeff() >
                                       1e-9 * m.covariance.cwiseAbs().maxCoeff() + 1e-30)
    throw InvalidArgument(Message(who, ": covariance is not finite and symmetric"));
  Eigen::LLT<Eigen::Matrix3d> llt(m.covariance);
  if (llt.info() != Eigen::Success || m.covariance.diagonal().minCoeff() <= 0.0)
    throw InvalidArgument(Message(who, ": covariance is not positive definite"));
}

namespace {

// Identity of a measurement: what it measures (point, source, source name,
// stamp, and the reference it is measured from), not its values: the same
// recording processed again (whatever the settings) or a latched topic
// re-delivered is received once; measured again from a new reference
// (process_bag --new-reference) it is another measurement.
std::string MeasurementKey(const Measurement& m) {
  std::ostringstream k;
  k << std::setprecision(17) << m.point_id << '|' << static_cast<int>(m.source) << '|'
    << m.source_name << '|' << m.stamp << '|' << m.reference_stamp;
  return k.str();
}

// Stamp order of the batches held: by stamp, then by arrival (first observation id).
bool StampOrder(const Batch& a, uint64_t sa, const Batch& b, uint64_t sb) {
  return a.stamp < b.stamp || (a.stamp == b.stamp && sa < sb);
}

}  // namespace

BatchSummary Estimator::AddBatch(const Batch& batch_in) {
  BatchSummary summary;
  Batch batch = batch_in;
  batch.measurements.clear();
  for (const Measurement& m : batch_in.measurements) {
    if (received_.count(MeasurementKey(m))) {  // counted, not a problem: said once by the caller
      ++summary.refused;
      ++summary.already_held;
      continue;
    }
    try {
      Validate(m);
      batch.measurements.push_back(m);
    } catch (const InvalidArgument& e) {
      ++summary.refused;
      summary.messages.push_back(e.what());
    }
  }
  if (batch.measurements.empty()) return summary;
  std::vector<uint64_t> sequences;
  if (history_) {
    sequences = history_->AppendBatch(batch);  // committed before use
  } else {
    for (size_t i = 0; i < batch.measurements.size(); ++i) sequences.push_back(next_sequence_++);
  }
  const uint64_t first = sequences.empty() ? 0 : sequences.front();
  const bool late = !held_.empty() &&
                    StampOrder(batch, first, held_.back().batch,
                               held_.back().sequences.empty() ? 0 : held_.back().sequences.front());
  held_.push_back({batch, sequences});
  BatchSummary s;
  if (late) {
    // Older than a batch already processed: every point again in stamp order.
    Rerun();
    s.accepted = static_cast<int>(batch.measurements.size());
    StoreAllEstimates();
  } else {
    s = Process(batch, sequences, false);
  }
  s.refused += summary.refused;
  s.already_held += summary.already_held;
  s.messages.insert(s.messages.begin(), summary.messages.begin(), summary.messages.end());
  return s;
}

BatchSummary Estimator::ReviseBatch(const Batch& batch) {
  BatchSummary summary;
  Batch fresh = batch;
  fresh.measurements.clear();
  for (const Measurement& m : batch.measurements) {
    if (!received_.count(MeasurementKey(m))) {
      fresh.measurements.push_back(m);
      continue;
    }
    Validate(m);
    for (Held& h : held_)
      for (Measurement& held : h.batch.measurements)
        if (held.stamp == m.stamp && MeasurementKey(held) == MeasurementKey(m)) {
          const uint32_t epoch = held.epoch;  // as stored: the values are revised, not the epoch
          held = m;
          held.epoch = epoch;
        }
    if (history_) history_->ReviseObservation(m);
    ++summary.revised;
  }
  if (summary.revised > 0) {
    Rerun();
    StoreAllEstimates();
  }
  if (!fresh.measurements.empty()) {
    const BatchSummary added = AddBatch(fresh);
    summary.accepted += added.accepted;
    summary.refused += added.refused;
    summary.messages = added.messages;
  }
  return summary;
}

void Estimator::ResetState() {
  points_.clear();
  epochs_.clear();
  has_datum_ = has_history_datum_;
  datum_stamp_ = history_datum_;
  newest_stamp_ = 0.0;
  newest_epoch_ = 0;
  received_.clear();
  areas_.clear();
  has_areas_ = false;
  last_area_epoch_ = 0;
}

void Estimator::Rerun() {
  std::stable_sort(held_.begin(), held_.end(), [](const Held& a, const Held& b) {
    return StampOrder(a.batch, a.sequences.empty() ? 0 : a.sequences.front(), b.batch,
                      b.sequences.empty() ? 0 : b.sequences.front());
  });
  const uint32_t reference_epoch = reference_epoch_;
  const double reference_stamp = reference_stamp_;
  const bool had_datum = has_datum_;
  ResetState();
  for (const Held& h : held_) Process(h.batch, h.sequences, true);
  if (had_datum) {  // the reference (set by meta or SetReferenceEpoch) stands
    reference_epoch_ = reference_epoch;
    reference_stamp_ = reference_stamp;
  }
  ++reruns_;
}

// The first measurement (of a new reference) sets the datum; false while a
// new reference is awaited and `m` is a held one of the old.
bool Estimator::TakeDatum(const Measurement& m, bool replay) {
  // A new reference was asked for (meta datum_stamp ""): the held batches
  // of the old one wait out; the first new measurement sets the datum.
  if (datum_pending_ && replay) return false;
  has_datum_ = true;
  datum_pending_ = false;
  has_history_datum_ = true;  // kept through a re-run
  datum_stamp_ = history_datum_ = m.reference_stamp;
  reference_stamp_ = datum_stamp_;
  reference_epoch_ = 0;
  for (const auto& [e, t] : epochs_)
    if (std::abs(t - datum_stamp_) <= options_.reference_tolerance) {
      reference_epoch_ = e;
      break;
    }
  if (history_ && !replay) {
    history_->SetMeta("datum_stamp", Fixed(datum_stamp_, 6));
    history_->SetMeta("reference_epoch", std::to_string(reference_epoch_));
    history_->SetMeta("reference_stamp", Fixed(reference_stamp_, 6));
    if (!recording_.empty()) history_->SetMeta("reference_recording", recording_);
  }
  return true;
}

BatchSummary Estimator::Process(const Batch& batch, const std::vector<uint64_t>& sequences,
                                bool replay) {
  BatchSummary summary;
  if (!epochs_.count(batch.epoch)) epochs_[batch.epoch] = batch.stamp;
  newest_epoch_ = std::max(newest_epoch_, batch.epoch);
  std::set<std::string> touched;
  for (size_t i = 0; i < batch.measurements.size(); ++i) {
    const Measurement& m = batch.measurements[i];
    const uint64_t seq = i < sequences.size() ? sequences[i] : next_sequence_;
    next_sequence_ = std::max(next_sequence_, seq + 1);
    received_.insert(MeasurementKey(m));
    if (replay) {  // rows of older schemas or edited files: refuse, never delete
      try {
        Validate(m);
      } catch (const InvalidArgument& e) {
        ++summary.refused;
        summary.messages.push_back(e.what());
        continue;
      }
    }
    if (!epochs_.count(m.epoch)) epochs_[m.epoch] = m.stamp;
    if (!has_datum_ && !TakeDatum(m, replay)) continue;
    if (std::abs(m.reference_stamp - datum_stamp_) > options_.reference_tolerance) {
      ++summary.refused;
      summary.messages.push_back(
          Message("point '", m.point_id, "' from '", m.source_name, "': reference stamp ",
                  Fixed(m.reference_stamp, 3), " differs from the datum ", Fixed(datum_stamp_, 3),
                  " by more than ", options_.reference_tolerance, " s (another reference epoch)"));
      continue;
    }
    const std::string id = ResolveAlias(m.point_id);
    auto& slot = points_[id];
    if (!slot) {
      slot = std::make_unique<Point>(options_);
      slot->id = id;
      slot->reference_position = m.reference_position;
      slot->reference_from_target = m.source == Source::kTarget;
      // The origin: zero displacement at the reference epoch (point_filter.h).
      if (m.stamp > datum_stamp_) slot->fused.AddOrigin(datum_stamp_);
    } else if (m.source == Source::kTarget && !slot->reference_from_target) {
      slot->reference_position = m.reference_position;
      slot->reference_from_target = true;
    }
    Point& p = *slot;
    bool fuse = true;
    if (options_.innovation_gate > 0.0 && p.fused.initialized()) {
      const UpdateResult t =
          p.fused.filter().Test(p.fused.latest(), m.stamp, m.displacement, m.covariance);
      if (m.stamp >= p.fused.latest().stamp && t.nis > options_.innovation_gate) {
        fuse = false;
        ++p.rejected;
        summary.messages.push_back(Message("point '", id, "' from '", m.source_name,
                                           "': innovation ", Fixed(t.nis, 1), " > gate ",
                                           options_.innovation_gate, ", not fused"));
      }
    }
    if (fuse && !p.fused.Add(m.stamp, seq, m.displacement, m.covariance)) {
      ++summary.refused;
      summary.messages.push_back(Message("point '", id, "' from '", m.source_name, "': stamp ",
                                         Fixed(m.stamp, 3), " is older than the reorder window (",
                                         options_.reorder_window, " s)"));
      continue;
    }
    if (fuse) {
      Point::Raw r{m.stamp, m.displacement, m.covariance};
      auto pos = std::upper_bound(
          p.raw.begin(), p.raw.end(), r,
          [](const Point::Raw& x, const Point::Raw& y) { return x.stamp < y.stamp; });
      p.raw.insert(pos, r);
      const double keep_from = p.raw.back().stamp - options_.forecast.window;
      size_t drop = 0;
      while (drop < p.raw.size() && p.raw[drop].stamp < keep_from) ++drop;
      p.raw.erase(p.raw.begin(), p.raw.begin() + drop);
    }
    auto it = p.sources.find(m.source);
    if (it == p.sources.end()) {
      it = p.sources.emplace(m.source, SourceTrack(options_)).first;
      if (m.stamp > m.reference_stamp) it->second.filter.AddOrigin(m.reference_stamp);
    }
    it->second.filter.Add(m.stamp, seq, m.displacement, m.covariance);
    it->second.last_stamp = std::max(it->second.last_stamp, m.stamp);
    ++summary.accepted;
    touched.insert(id);

    // Compare this source with every other source of the point at m.stamp.
    const std::optional<FilterState> mine = it->second.filter.StateAt(m.stamp);
    for (auto& [other_source, other] : p.sources) {
      if (other_source == m.source || !mine) continue;
      if (std::abs(other.last_stamp - m.stamp) > options_.comparison_max_gap) continue;
      const std::optional<FilterState> theirs = other.filter.StateAt(m.stamp);
      if (!theirs) continue;
      SourceComparison c;
      c.a = std::min(m.source, other_source);
      c.b = std::max(m.source, other_source);
      const FilterState& sa = c.a == m.source ? *mine : *theirs;
      const FilterState& sb = c.a == m.source ? *theirs : *mine;
      c.stamp = m.stamp;
      c.difference = sa.Displacement() - sb.Displacement();
      const Eigen::Matrix3d C = sa.DisplacementCovariance() + sb.DisplacementCovariance();
      c.statistic = c.difference.dot(C.ldlt().solve(c.difference));
      c.disagree = c.statistic > options_.disagreement_threshold;
      p.comparisons[{c.a, c.b}] = c;
    }
  }
  // Series and velocity samples, forecasts.
  for (const std::string& id : touched) {
    Point& p = *points_[id];
    const FilterState& s = p.fused.latest();
    newest_stamp_ = std::max(newest_stamp_, s.stamp);
    if (p.series.empty() || s.stamp >= p.series.back().stamp + options_.velocity_sample_interval) {
      SeriesSample sample;
      sample.stamp = s.stamp;
      sample.displacement = s.Displacement();
      sample.sigma = std::sqrt(std::max(0.0, s.DisplacementCovariance().trace() / 3.0));
      SpeedOf(s.Velocity(), s.VelocityCovariance(), &sample.speed, &sample.speed_sigma);
      p.series.push_back(sample);
      // Inverse-velocity forecast, refitted at each series sample, on the
      // raw displacements along the direction of motion (forecast.h).
      if (sample.speed - options_.alerts.significance * sample.speed_sigma >
          options_.forecast.min_velocity) {
        const Eigen::Vector3d u = s.Velocity().normalized();
        std::vector<DisplacementSample> d;
        for (const Point::Raw& r : p.raw)
          d.push_back({r.stamp, u.dot(r.z), std::sqrt(u.dot(r.R * u))});
        p.forecast = ForecastFromDisplacements(d, options_.forecast);
      } else {
        p.forecast = Forecast();
        p.forecast.reason = "speed not significantly above forecast min_velocity";
      }
    }
  }
  UpdateAlerts();
  if (history_ && !replay) {
    std::vector<PointState> states;
    states.reserve(touched.size());
    for (const std::string& id : touched) states.push_back(StateOf(*points_[id]));
    history_->StoreEstimates(states, batch.epoch);
  }
  return summary;
}

namespace {

// The highest level whose speed or displacement threshold the state exceeds
// by k sigma (0: none); *by_displacement: the displacement decided it.
int ExceededLevel(const FilterState& s, const Eigen::Vector3d& offset,
                  const Eigen::Matrix3d& offset_cov, const Thresholds& th, double k,
                  bool* by_displacement = nullptr) {
  double speed, speed_sigma, d, d_sigma;
  SpeedOf(s.Velocity(), s.VelocityCovariance(), &speed, &speed_sigma);
  SpeedOf(s.Displacement() - offset, s.DisplacementCovariance() + offset_cov, &d, &d_sigma);
  int level = 0;
  if (by_displacement) *by_displacement = false;
  for (int l = 1; l <= 3; ++l) {
    const AlertLevel al = static_cast<AlertLevel>(l);
    const bool by_speed = speed - k * speed_sigma > th.Of(al);
    const bool by_d = d - k * d_sigma > th.DisplacementOf(al);
    if (by_speed || by_d) {
      level = l;
      if (by_displacement) *by_displacement = !by_speed;
    }
  }
  return level;
}

}  // namespace

void Estimator::UpdateAlerts() {
  const AlertOptions& a = options_.alerts;
  const double k = a.significance;
  std::map<std::string, int> candidate;
  std::map<std::string, bool> by_displacement;
  int count[4] = {0, 0, 0, 0};  // points that are candidates for >= level
  for (const auto& [id, p] : points_) {
    Eigen::Matrix3d offset_cov;
    const Eigen::Vector3d offset = ReferenceOffset(*p, &offset_cov);
    bool by_d = false;
    const int c = ExceededLevel(p->fused.latest(), offset, offset_cov, ThresholdsOf(id), k, &by_d);
    candidate[id] = c;
    by_displacement[id] = by_d;
    for (int l = 1; l <= c; ++l) ++count[l];
  }
  for (auto& [id, p] : points_) {
    const FilterState& s = p->fused.latest();
    Eigen::Matrix3d offset_cov;
    const Eigen::Vector3d offset = ReferenceOffset(*p, &offset_cov);
    double speed, sigma, d, d_sigma;
    SpeedOf(s.Velocity(), s.VelocityCovariance(), &speed, &sigma);
    SpeedOf(s.Displacement() - offset, s.DisplacementCovariance() + offset_cov, &d, &d_sigma);
    const Thresholds th = ThresholdsOf(id);
    int confirmed = 0, by_sources = 0;
    for (int l = candidate[id]; l >= 1; --l) {
      int n_sources = 0;
      for (const auto& [src, track] : p->sources) {
        if (!track.filter.has_velocity()) continue;
        if (ExceededLevel(track.filter.latest(), offset, offset_cov, th, k) >= l) ++n_sources;
      }
      if (count[l] >= a.confirm_points || n_sources >= a.confirm_sources) {
        confirmed = l;
        by_sources = n_sources;
        break;
      }
    }
    int level = confirmed;
    const int current = static_cast<int>(p->alert);
    if (current > level) {
      level = current;
      while (level > confirmed) {
        const AlertLevel l = static_cast<AlertLevel>(level);
        if (speed >= a.hysteresis * th.Of(l) || d >= a.hysteresis * th.DisplacementOf(l)) break;
        --level;
      }
    }
    p->alert = static_cast<AlertLevel>(level);
    if (level == 0) {
      p->alert_reason =
          candidate[id] > 0
              ? Message(by_displacement[id] ? "displacement " : "speed ",
                        by_displacement[id] ? Fixed(d * 1e3, 1) + " mm"
                                            : Fixed(speed * kMmPerDay, 2) + " mm/day",
                        " exceeds ", AlertName(static_cast<AlertLevel>(candidate[id])),
                        " but is not confirmed (", count[candidate[id]], " of ", a.confirm_points,
                        " points)")
              : "";
    } else if (level > confirmed) {
      p->alert_reason =
          Message("held by hysteresis: speed ", Fixed(speed * kMmPerDay, 2),
                  " mm/day, displacement ", Fixed(d * 1e3, 1), " mm > ", a.hysteresis, " x ",
                  AlertName(p->alert), " threshold ", Fixed(th.Of(p->alert) * kMmPerDay, 2),
                  " mm/day or ", Fixed(th.DisplacementOf(p->alert) * 1e3, 1), " mm");
    } else if (by_displacement[id] && candidate[id] == level) {
      p->alert_reason =
          Message("displacement ", Fixed(d * 1e3, 1), " +- ", Fixed(d_sigma * 1e3, 1), " mm > ",
                  AlertName(p->alert), " threshold ", Fixed(th.DisplacementOf(p->alert) * 1e3, 1),
                  " mm by ", k, " sigma; confirmed by ", count[level], " point(s), ", by_sources,
                  " source(s)");
    } else {
      p->alert_reason = Message(
          "speed ", Fixed(speed * kMmPerDay, 2), " +- ", Fixed(sigma * kMmPerDay, 2), " mm/day > ",
          AlertName(p->alert), " threshold ", Fixed(th.Of(p->alert) * kMmPerDay, 2), " mm/day by ",
          k, " sigma; confirmed by ", count[level], " point(s), ", by_sources, " source(s)");
    }
  }
}

Eigen::Vector3d Estimator::ReferenceOffset(const Point& p, Eigen::Matrix3d* cov) const {
  auto it = reference_offsets_.find(p.id);
  if (it == reference_offsets_.end()) {
    cov->setZero();
    return Eigen::Vector3d::Zero();
  }
  *cov = it->second.second;
  return it->second.first;
}

PointState Estimator::StateOf(const Point& p) const {
  PointState s;
  const FilterState& f = p.fused.latest();
  s.id = p.id;
  s.reference_position = p.reference_position;
  s.stamp = f.stamp;
  Eigen::Matrix3d offset_cov;
  const Eigen::Vector3d offset = ReferenceOffset(p, &offset_cov);
  s.displacement = f.Displacement() - offset;
  s.displacement_covariance = f.DisplacementCovariance() + offset_cov;
  s.velocity = f.Velocity();
  s.velocity_covariance = f.VelocityCovariance();
  s.acceleration = f.Acceleration();
  SpeedOf(s.velocity, s.velocity_covariance, &s.speed, &s.speed_sigma);
  s.alert = p.alert;
  s.alert_reason = p.alert_reason;
  s.forecast = p.forecast;
  for (const auto& [src, track] : p.sources) {
    s.sources.push_back(src);
    SourceEstimate e;
    e.source = src;
    const FilterState& t = track.filter.latest();
    e.displacement = t.Displacement() - offset;
    e.displacement_covariance = t.DisplacementCovariance() + offset_cov;
    e.velocity = t.Velocity();
    e.last_stamp = t.stamp;
    e.count = track.filter.count();
    s.per_source.push_back(e);
  }
  for (const auto& [pair, c] : p.comparisons) {
    s.comparisons.push_back(c);
    if (c.disagree) {
      s.sources_disagree = true;
      s.alert_reason +=
          Message(s.alert_reason.empty() ? "" : "; ", SourceName(c.a), " and ", SourceName(c.b),
                  " disagree by ", Fixed(c.difference.norm() * 1e3, 1), " mm (chi2 ",
                  Fixed(c.statistic, 1), ")");
    }
  }
  s.num_measurements = p.fused.count();
  s.num_rejected = p.rejected;
  return s;
}

uint32_t Estimator::SetReferenceEpoch(uint32_t epoch, bool use_latest) {
  if (epochs_.empty())
    throw InvalidArgument("no epoch has been received yet; cannot set the reference epoch");
  if (use_latest) epoch = epochs_.rbegin()->first;
  auto it = epochs_.find(epoch);
  if (it == epochs_.end())
    throw InvalidArgument(Message("reference epoch ", epoch, " has not been received (latest is ",
                                  epochs_.rbegin()->first, ")"));
  const double t = it->second;
  std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>> offsets;
  for (const auto& [id, p] : points_) {
    if (std::abs(t - datum_stamp_) <= options_.reference_tolerance)
      continue;  // the datum itself: no offset
    const std::optional<FilterState> s = p->fused.StateAt(t);
    if (!s)
      continue;  // first measured after the epoch: its datum displacement is taken as zero there
    offsets[id] = {s->Displacement(), s->DisplacementCovariance()};
  }
  reference_offsets_ = offsets;
  reference_epoch_ = epoch;
  reference_stamp_ = t;
  if (history_) {
    history_->StoreReferenceOffsets(offsets);
    history_->SetMeta("reference_epoch", std::to_string(epoch));
    history_->SetMeta("reference_stamp", Fixed(t, 6));
  }
  return epoch;
}

bool Estimator::AddAreas(const AreaBatch& batch) {
  if (has_areas_ && batch.epoch <= last_area_epoch_) return false;  // old, or re-delivered
  areas_ =
      AssessAreas(areas_, has_areas_ ? std::optional<uint32_t>(last_area_epoch_) : std::nullopt,
                  batch, options_.areas);
  has_areas_ = true;
  last_area_epoch_ = batch.epoch;
  return true;
}

Snapshot Estimator::GetSnapshot() const {
  Snapshot s;
  s.stamp = newest_stamp_;
  s.epoch = newest_epoch_;
  s.has_reference = has_datum_;
  s.reference_epoch = reference_epoch_;
  s.reference_stamp = reference_stamp_;
  double max_d = 0.0;
  std::string max_id;
  int disagree = 0;
  for (const auto& [id, p] : points_) {
    s.points.push_back(StateOf(*p));
    const PointState& ps = s.points.back();
    s.alert = std::max(s.alert, ps.alert);
    if (ps.displacement.norm() >= max_d) {
      max_d = ps.displacement.norm();
      max_id = id;
    }
    disagree += ps.sources_disagree ? 1 : 0;
  }
  s.areas = areas_;
  s.area_alert = AreasAlert(areas_);
  s.alert = std::max(s.alert, s.area_alert);
  s.summary = Message(s.points.size(), " points, largest displacement ", Fixed(max_d * 1e3, 1),
                      " mm at '", max_id, "', slope alert ", AlertName(s.alert), ", ", disagree,
                      " point(s) with disagreeing sources");
  if (!areas_.empty())
    s.summary += Message(", ", areas_.size(), " area(s) of significant surface change (alert ",
                         AlertName(s.area_alert), ")");
  return s;
}

std::map<std::string, std::vector<SeriesSample>> Estimator::Series() const {
  std::map<std::string, std::vector<SeriesSample>> out;
  for (const auto& [id, p] : points_) {
    Eigen::Matrix3d cov;
    const Eigen::Vector3d offset = ReferenceOffset(*p, &cov);
    std::vector<SeriesSample> series = p->series;
    for (SeriesSample& s : series) s.displacement -= offset;
    out[id] = series;
  }
  return out;
}

}  // namespace deformation
}  // namespace slope_monitor
