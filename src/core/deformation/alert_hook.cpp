#include "slope_monitor/core/deformation/alert_hook.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/common/subprocess.h"
#include "slope_monitor/core/deformation/units.h"

namespace slope_monitor {
namespace deformation {
namespace {

constexpr size_t kMaxJson = 4096;  // RunProgram's input limit

std::string Escape(const std::string& s) {
  std::string out;
  for (const char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char u[8];
      std::snprintf(u, sizeof(u), "\\u%04x", c);
      out += u;
    } else {
      out += c;
    }
  }
  return out;
}

}  // namespace

std::string AlertJson(const std::string& site, const PointState& p, const AlertChange& c) {
  std::ostringstream o;
  o << "{\"site\": \"" << Escape(site) << "\", \"point\": \"" << Escape(p.id) << "\", \"from\": \""
    << AlertName(c.from) << "\", \"level\": \"" << AlertName(c.to)
    << "\", \"stamp\": " << Fixed(p.stamp, 3) << ", \"time_utc\": \"" << Utc(p.stamp)
    << "\", \"speed_mm_per_day\": " << Fixed(p.speed * kMmPerDay, 3)
    << ", \"sigma_speed_mm_per_day\": " << Fixed(p.speed_sigma * kMmPerDay, 3)
    << ", \"d_mm\": " << Fixed(p.displacement.norm() * 1e3, 3)
    << ", \"forecast_valid\": " << (p.forecast.valid ? "true" : "false")
    << ", \"forecast_failure_time_utc\": \""
    << (p.forecast.valid ? Utc(p.forecast.failure_time) : "") << "\", \"forecast_sigma_h\": "
    << (p.forecast.valid ? Fixed(p.forecast.sigma / 3600.0, 3) : "null")
    << ", \"forecast_reason\": \"" << Escape(p.forecast.valid ? "" : p.forecast.reason)
    << "\", \"text\": \"" << Escape(c.text) << "\"}";
  return o.str();
}

AlertHook::AlertHook(const io::NotificationOptions& options, Log log)
    : options_(options), log_(std::move(log)) {
  options_.Check();
  if (options_.hook.empty()) throw InvalidArgument("notification hook: no executable given");
  worker_ = std::thread([this] { Work(); });
}

AlertHook::~AlertHook() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  worker_.join();
}

void AlertHook::Notify(const std::string& json) {
  if (json.size() > kMaxJson)
    throw InvalidArgument(
        Message("notification hook: alert JSON of ", json.size(), " bytes exceeds ", kMaxJson));
  {
    std::lock_guard<std::mutex> lock(mutex_);
    queue_.push_back(json);
  }
  wake_.notify_all();
}

void AlertHook::Flush() {
  std::unique_lock<std::mutex> lock(mutex_);
  idle_.wait(lock, [this] { return queue_.empty() && !busy_; });
}

AlertHookSummary AlertHook::summary() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return summary_;
}

void AlertHook::Work() {
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (queue_.empty()) break;  // stopping, nothing left
    const std::string json = queue_.front();
    queue_.pop_front();
    busy_ = true;
    for (int attempt = 0;; ++attempt) {
      ++summary_.attempts;
      lock.unlock();
      const std::string failure = RunOnce(json);
      lock.lock();
      if (failure.empty()) {
        ++summary_.delivered;
        lock.unlock();
        if (log_)
          log_(false, Message("notification hook '", options_.hook, "' delivered the alert"));
        lock.lock();
        break;
      }
      ++summary_.failures;
      const bool last = attempt >= options_.retries || stop_;
      if (last) ++summary_.given_up;
      lock.unlock();
      if (log_)
        log_(true,
             Message("notification hook '", options_.hook, "' failed: ", failure,
                     last ? Message("; alert given up after ", attempt + 1, " attempt(s): ", json)
                          : Message("; retry ", attempt + 1, " of ", options_.retries, " in ",
                                    options_.retry_delay, " s")));
      lock.lock();
      if (last) break;
      wake_.wait_for(lock, std::chrono::duration<double>(options_.retry_delay),
                     [this] { return stop_; });
    }
    busy_ = false;
    idle_.notify_all();
  }
  busy_ = false;
  idle_.notify_all();
}

std::string AlertHook::RunOnce(const std::string& json) const {
  const RunResult r = RunProgram({options_.hook}, json, options_.timeout);
  if (r.failure == "exit status 127") return "exit status 127 (command not found?)";
  return r.failure;
}

std::vector<AlertChange> AnnounceAlertChanges(
    const Snapshot& snapshot, const std::string& site, AlertChangeTracker* tracker, AlertHook* hook,
    const std::function<void(LogLevel, const std::string&)>& log) {
  std::vector<AlertChange> changes = tracker->Update(snapshot);
  for (const AlertChange& c : changes) {
    if (hook) {
      for (const PointState& p : snapshot.points)
        if (p.id == c.point_id) hook->Notify(AlertJson(site, p, c));
    }
    const LogLevel level = c.to == AlertLevel::kAlarm  ? LogLevel::kError
                           : c.to == AlertLevel::kNone ? LogLevel::kInfo
                                                       : LogLevel::kWarn;
    log(level, c.text);
  }
  return changes;
}

}  // namespace deformation
}  // namespace slope_monitor
