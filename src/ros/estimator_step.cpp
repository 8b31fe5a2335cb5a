#include "slope_monitor/ros/estimator_step.h"

#include <exception>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/plot_report.h"
#include "slope_monitor/ros/change_area_conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

LogLine::Level LineLevel(deformation::LogLevel level) {
  switch (level) {
    case deformation::LogLevel::kError:
      return LogLine::kError;
    case deformation::LogLevel::kWarn:
      return LogLine::kWarn;
    case deformation::LogLevel::kInfo:
      break;
  }
  return LogLine::kInfo;
}

}  // namespace

EstimatorStep::EstimatorStep(const EstimatorParameters& parameters,
                             const std::vector<std::string>& ordered_inputs,
                             deformation::AlertHook::Log hook_log,
                             std::unique_ptr<deformation::History> history)
    : parameters_(parameters), history_(std::move(history)) {
  if (history_ || !parameters_.database.empty()) {
    if (!history_) history_ = std::make_unique<deformation::History>(parameters_.database);
    history_->CheckReference();
    history_->CheckSite(parameters_.site ? parameters_.site->name : parameters_.site_name);
  }
  estimator_ = std::make_unique<deformation::Estimator>(parameters_.options, history_.get());
  estimator_->SetRecording(parameters_.recording);
  // A history continued: the levels it ends at were announced by the run
  // that reached them; this run announces only what changes from there.
  alert_changes_.Update(estimator_->GetSnapshot());
  if (!ordered_inputs.empty()) order_ = std::make_unique<InputOrder<Incoming>>(ordered_inputs);
  if (parameters_.site && !parameters_.site->notification.hook.empty())
    hook_ = std::make_unique<deformation::AlertHook>(parameters_.site->notification,
                                                     std::move(hook_log));
}

EstimatorResult EstimatorStep::AddDisplacements(const slope_monitor::PointDisplacementArray& msg,
                                                const std::string& topic, double now) {
  EstimatorResult out;
  ++messages_;
  Incoming in;
  in.valid = validator_.Filter(msg, topic, now);
  for (const std::string& problem : validator_.last_problems()) {
    out.problems.push_back({LogLine::kWarn, "rejected " + problem});
    last_problem_ = problem;
  }
  in.fuse = !(in.valid.displacements.empty() && !msg.displacements.empty());
  if (!order_) {
    Fuse(in, topic, true, &out);
    return out;
  }
  // In stamp order across the inputs (core/common/input_order.h).
  for (auto& r : order_->Add(topic, msg.header.stamp.toSec(), std::move(in), now))
    Fuse(r.item, r.input, true, &out);
  return out;
}

EstimatorResult EstimatorStep::Expire(double now, double timeout,
                                      std::vector<std::string>* given_up) {
  EstimatorResult out;
  if (order_)
    for (auto& r : order_->Expire(now, timeout, given_up)) Fuse(r.item, r.input, true, &out);
  return out;
}

EstimatorResult EstimatorStep::Flush(bool publish) {
  EstimatorResult out;
  if (order_)
    for (auto& r : order_->Flush()) Fuse(r.item, r.input, publish, &out);
  return out;
}

void EstimatorStep::Fuse(const Incoming& in, const std::string& topic, bool publish,
                         EstimatorResult* out) {
  if (!in.fuse) return;
  try {
    const deformation::BatchSummary s = estimator_->AddBatch(FromMsg(in.valid, topic));
    accepted_ += s.accepted;
    refused_ += s.refused;
    if (already_held_ == 0 && s.already_held > 0)  // said once, then counted
      out->problems.push_back(
          {LogLine::kInfo, Message("topic '", topic,
                                   "': measurements already in the history are not stored or "
                                   "fused again (a recording processed again, or a latched topic "
                                   "re-delivered after a restart); counted in diagnostics")});
    already_held_ += s.already_held;
    for (const std::string& m : s.messages) {
      out->problems.push_back({LogLine::kWarn, Message("topic '", topic, "': ", m)});
      last_problem_ = m;
    }
  } catch (const Error& e) {
    ++errors_;
    last_problem_ = e.what();
    out->problems.push_back(
        {LogLine::kError, "topic '" + topic + "': " + e.what() + "; message dropped"});
    return;
  }
  if (publish) out->publications.push_back(Publication(in.valid.header));
}

EstimatorResult EstimatorStep::ReviseDisplacements(const slope_monitor::PointDisplacementArray& msg,
                                                   const std::string& topic) {
  EstimatorResult out;
  ++messages_;
  const slope_monitor::PointDisplacementArray valid = validator_.Filter(msg, topic, 0.0);
  try {
    const deformation::BatchSummary s = estimator_->ReviseBatch(FromMsg(valid, topic));
    accepted_ += s.accepted;
    revised_ += s.revised;
    for (const std::string& m : s.messages) out.problems.push_back({LogLine::kWarn, m});
  } catch (const Error& e) {
    ++errors_;
    last_problem_ = e.what();
    out.problems.push_back(
        {LogLine::kError, "topic '" + topic + "': " + e.what() + "; revision dropped"});
    return out;
  }
  out.publications.push_back(Publication(valid.header));
  return out;
}

EstimatorResult EstimatorStep::AddAreas(const slope_monitor::ChangeAreaArray& msg,
                                        const std::string& topic) {
  EstimatorResult out;
  ++messages_;
  try {
    if (!estimator_->AddAreas(AreaBatchFromMsg(msg, topic))) {
      out.problems.push_back({LogLine::kWarn, "topic '" + topic + "': areas of epoch " +
                                                  std::to_string(msg.epoch) +
                                                  " are not newer than the last; ignored"});
      return out;
    }
  } catch (const Error& e) {
    ++errors_;
    last_problem_ = e.what();
    out.problems.push_back(
        {LogLine::kError, "topic '" + topic + "': " + e.what() + "; message dropped"});
    return out;
  }
  out.publications.push_back(Publication(msg.header));
  return out;
}

EstimatorPublication EstimatorStep::SetReferenceEpoch(uint32_t epoch, bool use_latest,
                                                      uint32_t* chosen) {
  *chosen = estimator_->SetReferenceEpoch(epoch, use_latest);
  return Current(ros::Time(estimator_->GetSnapshot().stamp));
}

EstimatorPublication EstimatorStep::Current(const ros::Time& stamp) {
  std_msgs::Header h;
  h.stamp = stamp;
  return Publication(h);
}

// The snapshot after an input: its alert changes announced (log, hook).
EstimatorPublication EstimatorStep::Publication(const std_msgs::Header& input) {
  EstimatorPublication p;
  p.snapshot = estimator_->GetSnapshot();
  p.header = input;
  p.header.frame_id = parameters_.frame_id;
  p.changes = deformation::AnnounceAlertChanges(
      p.snapshot, parameters_.site ? parameters_.site->name : "", &alert_changes_, hook_.get(),
      [&p](deformation::LogLevel level, const std::string& text) {
        p.log.push_back({LineLevel(level), text});
      });
  last_alert_ = p.snapshot.alert;
  num_points_ = p.snapshot.points.size();
  return p;
}

std::vector<std::string> EstimatorStep::WriteReports(const std::string& subfolder,
                                                     const std::vector<std::string>& formats) {
  return deformation::WriteAllReports(*estimator_, history_ ? parameters_.database : "",
                                      parameters_.plot, parameters_.report_dir, subfolder, formats,
                                      parameters_.report);
}

std::vector<LogLine> EstimatorStep::FinalReports() {
  Flush(false);
  const EstimatorParameters& p = parameters_;
  if (!p.report_on_shutdown || p.report_dir.empty()) return {};
  if (GetSnapshot().points.empty()) {
    // An empty, unreadable or truncated bag, or one without the input topics.
    std::string topics;
    for (const std::string& x : p.input_topics) topics += (topics.empty() ? "" : ", ") + x;
    return {{LogLine::kWarn,
             Message("no point was ever measured (history '", p.database,
                     "'); no reports written to ", p.report_dir,
                     " (was the bag empty, unreadable, or without the topics ", topics, "?)")}};
  }
  try {
    const auto files = WriteReports("", p.report_formats);
    return {{LogLine::kInfo,
             Message("wrote ", files.size(), " report file(s) to ", p.report_dir, " at shutdown")}};
  } catch (const std::exception& e) {
    return {{LogLine::kError, std::string("reports at shutdown failed: ") + e.what()}};
  }
}

std::vector<std::string> EstimatorStep::ExportReports(const std::string& subfolder,
                                                      const std::vector<std::string>& formats) {
  try {
    if (parameters_.report_dir.empty())
      throw InvalidArgument("parameter 'report_dir' is empty: export_report writes only inside it");
    return WriteReports(subfolder, formats);
  } catch (const std::exception& e) {
    last_problem_ = e.what();
    throw;
  }
}

void EstimatorStep::Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const {
  if (errors_ > 0 && !last_problem_.empty()) {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "dropped messages: " + last_problem_);
  } else {
    stat.summary(
        diagnostic_msgs::DiagnosticStatus::OK,
        Message(num_points_, " points, slope alert ", deformation::AlertName(last_alert_)));
  }
  stat.add("messages", messages_);
  stat.add("measurements accepted", accepted_);
  stat.add("measurements refused", refused_);
  stat.add("measurements already held (not stored again)", already_held_);
  stat.add("measurements revised (radio epochs tracked again)", revised_);
  stat.add("messages dropped", errors_);
  for (const auto& [reason, count] : validator_.rejected()) stat.add("rejected: " + reason, count);
  stat.add("database", parameters_.database.empty() ? "(none)" : parameters_.database);
  stat.add("last problem", last_problem_);
}

}  // namespace ros_adapters
}  // namespace slope_monitor
