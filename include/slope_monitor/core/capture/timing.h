// Capture timing: the schedule of a fixed camera and the epoch marking of a
// frame stream.
//
// Epochs (doc/design.md "Epochs"): a survey epoch is a set of images
// taken close together. EpochTracker emits "start" before the first frame of
// an epoch and "end" after its last, so downstream nodes know when an epoch is
// complete:
//   * photo folders / video: a gap in capture time larger than `gap` ends an
//     epoch (and an epoch longer than `max_duration`, when > 0, is split);
//     with look-ahead (the next stamp is known) the end is emitted right after
//     the last frame, otherwise when the next frame arrives or the stream ends;
//   * fixed cameras: each scheduled (or triggered) capture of
//     `frames_per_epoch` frames is one epoch (the caller ends it explicitly).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace slope_monitor {
namespace capture {

struct EpochEvent {
  bool end = false;    // false: epoch starts (before its first frame); true: epoch complete
  uint32_t epoch = 0;  // epoch number (consecutive from first_epoch)
  uint32_t count = 0;  // frames in the epoch (on end)
  double stamp = 0.0;  // [s] the first frame's stamp (start) / the last frame's stamp (end)
};

struct EpochOptions {
  double gap = 600.0;         // [s] a capture-time gap larger than this ends an epoch, > 0
  double max_duration = 0.0;  // [s] an epoch longer than this is split; 0: no limit
  uint32_t first_epoch = 0;   // number of the first epoch
  void Check() const;         // throws ConfigError naming the key
};

class EpochTracker {
 public:
  explicit EpochTracker(const EpochOptions& options);

  // Before publishing a frame stamped `stamp`: the end of the open epoch (if
  // the gap/duration closes it) and the start of a new one, in that order.
  std::vector<EpochEvent> BeforeFrame(double stamp);
  // After publishing it: the end of the epoch when the next stamp is known to
  // start a new one (or the stream has ended: next_known && !next).
  std::vector<EpochEvent> AfterFrame(std::optional<double> next_stamp, bool next_known);
  // Ends the open epoch, if any (end of stream, end of a scheduled burst).
  std::optional<EpochEvent> Close();

  bool open() const { return open_; }
  uint32_t current_epoch() const { return epoch_; }
  uint32_t count() const { return count_; }

 private:
  bool Splits(double first, double last, double next) const;
  EpochOptions options_;
  bool open_ = false;
  bool any_ = false;
  uint32_t epoch_ = 0;
  uint32_t count_ = 0;
  double first_stamp_ = 0.0;
  double last_stamp_ = 0.0;
};

struct ScheduleOptions {
  double interval =
      0.0;  // [s] periodic capture every `interval` s (aligned to multiples of it since
            // 1970-01-01 00:00 UTC); 0: no periodic capture (trigger only); else >= 1
  std::vector<std::string>
      windows;                    // daily "HH:MM-HH:MM" windows (may wrap midnight); empty: all day
  double utc_offset_hours = 0.0;  // [h] the windows' local time = UTC + offset, [-14, 14]
  int frames_per_epoch = 1;       // frames per capture (one epoch), [1, 1000]
  void Check() const;             // throws ConfigError naming the key/window
};

class CaptureSchedule {
 public:
  explicit CaptureSchedule(const ScheduleOptions& options);

  const ScheduleOptions& options() const { return options_; }
  // Whether a UTC time [s] is inside a daily window (always true without windows).
  bool InWindow(double t) const;
  // The first scheduled capture time strictly after t [s UTC]; nullopt when
  // interval is 0 (or no multiple of the interval falls in a window within 2 days).
  std::optional<double> NextCapture(double t) const;

 private:
  ScheduleOptions options_;
  std::vector<std::pair<int, int>> windows_;  // [begin, end) in seconds of the local day
};

}  // namespace capture
}  // namespace slope_monitor
