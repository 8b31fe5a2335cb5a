// The site's notification hook: an executable (site file key
// notification.hook) run with one alert as JSON on standard input at every
// alert-level change of a point, so alerts reach people who are not watching
// a topic (scripts/hooks/notify_email, scripts/hooks/notify_mqtt).
//
// Non-blocking: Notify() queues the alert; one worker thread starts the hook
// by posix_spawnp (a bare name is looked up in PATH), writes the JSON to its
// stdin, and waits at most options.timeout seconds (then SIGKILL). A hook
// that cannot be started, exits non-zero, dies of a signal or times out has
// failed: the failure is logged and the hook run again after retry_delay, at
// most `retries` more times; then the alert is given up (logged as an error).
// Alerts are sent one at a time in the order they were queued. At
// destruction the queued alerts get one attempt each (no retry waits).
//
// The JSON (one line, flat; speeds in mm/day, times ISO 8601 UTC):
//   {"site": "demo", "point": "tag36h11/10", "from": "watch", "level": "warning",
//    "stamp": 1700021600.000, "time_utc": "2023-11-15T04:13:20Z",
//    "speed_mm_per_day": 12.40, "sigma_speed_mm_per_day": 0.80, "d_mm": 31.20,
//    "forecast_valid": true, "forecast_failure_time_utc": "2023-11-16T10:00:00Z",
//    "forecast_sigma_h": 1.50, "forecast_reason": "",
//    "text": "point tag36h11/10: alert watch -> warning, speed 12.40 +- 0.80 mm/day, ..."}
// (without a valid forecast: "forecast_failure_time_utc": "", "forecast_sigma_h": null).
//
//   AlertHook hook(site.notification, [](bool error, const std::string& m) { log(m); });
//   for (const AlertChange& c : tracker.Update(s)) hook.Notify(AlertJson(site.name, *FindPoint(s,
//   c.point_id), c));
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "slope_monitor/core/deformation/alert_log.h"
#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/io/site_file.h"

namespace slope_monitor {
namespace deformation {

// The alert as one line of JSON (above); `site` is the site's name.
std::string AlertJson(const std::string& site, const PointState& point, const AlertChange& change);

class AlertHook;

// What the estimator nodelet and process_bag do at every snapshot: the
// alert-level changes (tracker.Update) are logged (`log`: level ERROR for
// alarm, INFO for back to none, else WARN) and each point's change goes to
// `hook` (may be null) as AlertJson. Returns the changes.
enum class LogLevel { kInfo, kWarn, kError };
std::vector<AlertChange> AnnounceAlertChanges(
    const Snapshot& snapshot, const std::string& site, AlertChangeTracker* tracker, AlertHook* hook,
    const std::function<void(LogLevel, const std::string&)>& log);

struct AlertHookSummary {
  int attempts = 0;   // hook runs started (or failed to start)
  int delivered = 0;  // alerts whose hook exited 0
  int failures = 0;   // failed attempts
  int given_up = 0;   // alerts dropped after the last retry
};

class AlertHook {
 public:
  // error: true for failures, false for deliveries. Called from the worker thread.
  using Log = std::function<void(bool error, const std::string& message)>;
  // Throws InvalidArgument (options.Check()) or when options.hook is empty.
  AlertHook(const io::NotificationOptions& options, Log log);
  ~AlertHook();
  AlertHook(const AlertHook&) = delete;
  AlertHook& operator=(const AlertHook&) = delete;

  // Queues one alert (JSON text, at most 4096 bytes); returns at once.
  void Notify(const std::string& json);
  // Blocks until every queued alert is delivered or given up (tests, shutdown).
  void Flush();
  AlertHookSummary summary() const;

 private:
  void Work();
  // One run of the hook; "" on success, else why it failed.
  std::string RunOnce(const std::string& json) const;

  const io::NotificationOptions options_;
  const Log log_;
  mutable std::mutex mutex_;
  std::condition_variable wake_, idle_;
  std::deque<std::string> queue_;
  bool busy_ = false, stop_ = false;
  AlertHookSummary summary_;
  std::thread worker_;
};

}  // namespace deformation
}  // namespace slope_monitor
