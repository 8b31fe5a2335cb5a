#include "slope_monitor/core/capture/timing.h"

#include <cmath>
#include <cstdio>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {

void EpochOptions::Check() const {
  if (!std::isfinite(gap) || gap <= 0.0)
    throw ConfigError(Message("epoch_gap = ", gap, " s must be > 0"));
  if (!std::isfinite(max_duration) || max_duration < 0.0) {
    throw ConfigError(Message("epoch_max_duration = ", max_duration, " s must be >= 0"));
  }
}

EpochTracker::EpochTracker(const EpochOptions& options)
    : options_(options), epoch_(options.first_epoch) {
  options_.Check();
}

bool EpochTracker::Splits(double first, double last, double next) const {
  if (next - last > options_.gap) return true;
  return options_.max_duration > 0.0 && next - first > options_.max_duration;
}

std::vector<EpochEvent> EpochTracker::BeforeFrame(double stamp) {
  std::vector<EpochEvent> events;
  if (open_ && Splits(first_stamp_, last_stamp_, stamp)) events.push_back(*Close());
  if (!open_) {
    if (any_) ++epoch_;
    any_ = true;
    open_ = true;
    count_ = 0;
    first_stamp_ = stamp;
    events.push_back({false, epoch_, 0, stamp});
  }
  ++count_;
  last_stamp_ = stamp;
  return events;
}

std::vector<EpochEvent> EpochTracker::AfterFrame(std::optional<double> next_stamp,
                                                 bool next_known) {
  std::vector<EpochEvent> events;
  if (!open_ || !next_known) return events;
  if (!next_stamp || Splits(first_stamp_, last_stamp_, *next_stamp)) events.push_back(*Close());
  return events;
}

std::optional<EpochEvent> EpochTracker::Close() {
  if (!open_) return std::nullopt;
  open_ = false;
  return EpochEvent{true, epoch_, count_, last_stamp_};
}

// ---------------------------------------------------------------------------
void ScheduleOptions::Check() const {
  if (!std::isfinite(interval) || interval < 0.0 || (interval > 0.0 && interval < 1.0) ||
      interval > 7 * 86400.0) {
    throw ConfigError(
        Message("schedule/interval = ", interval, " s must be 0 (trigger only) or in [1, 604800]"));
  }
  if (!std::isfinite(utc_offset_hours) || std::abs(utc_offset_hours) > 14.0) {
    throw ConfigError(
        Message("schedule/utc_offset = ", utc_offset_hours, " h is outside [-14, 14]"));
  }
  if (frames_per_epoch < 1 || frames_per_epoch > 1000) {
    throw ConfigError(
        Message("schedule/frames_per_epoch = ", frames_per_epoch, " is outside [1, 1000]"));
  }
}

CaptureSchedule::CaptureSchedule(const ScheduleOptions& options) : options_(options) {
  options_.Check();
  for (const auto& w : options_.windows) {
    int h0, m0, h1, m1, n = 0;
    if (std::sscanf(w.c_str(), "%2d:%2d-%2d:%2d%n", &h0, &m0, &h1, &m1, &n) != 4 ||
        n != static_cast<int>(w.size()) || h0 < 0 || h0 > 24 || h1 < 0 || h1 > 24 || m0 < 0 ||
        m0 > 59 || m1 < 0 || m1 > 59 || (h0 == 24 && m0 > 0) || (h1 == 24 && m1 > 0)) {
      throw ConfigError(Message("schedule/windows: '", w, "' is not a daily window 'HH:MM-HH:MM'"));
    }
    const int begin = 3600 * h0 + 60 * m0, end = 3600 * h1 + 60 * m1;
    if (begin == end) throw ConfigError(Message("schedule/windows: '", w, "' is empty"));
    windows_.push_back({begin, end});
  }
}

bool CaptureSchedule::InWindow(double t) const {
  if (windows_.empty()) return true;
  double local = std::fmod(t + 3600.0 * options_.utc_offset_hours, 86400.0);
  if (local < 0) local += 86400.0;
  for (const auto& [b, e] : windows_) {
    if (b < e ? (local >= b && local < e) : (local >= b || local < e)) return true;
  }
  return false;
}

std::optional<double> CaptureSchedule::NextCapture(double t) const {
  const double dt = options_.interval;
  if (dt <= 0.0) return std::nullopt;
  double k = std::floor(t / dt) + 1.0;
  const double limit = t + 2.0 * 86400.0;
  for (double c = k * dt; c <= limit; k += 1.0, c = k * dt) {
    if (InWindow(c)) return c;
  }
  return std::nullopt;
}

}  // namespace capture
}  // namespace slope_monitor
