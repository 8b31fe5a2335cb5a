#include "slope_monitor/ros/radio_step.h"

#include <algorithm>
#include <exception>
#include <map>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

std::vector<std::string> ReceiverIds(const radio::NetworkConfig& network) {
  std::vector<std::string> ids;
  for (const auto& r : network.receivers) ids.push_back(r.id);
  return ids;
}

const RadioParameters& WithNetwork(const RadioParameters& parameters) {
  if (!parameters.has_network) throw ConfigError("radio step: no radio network configured");
  return parameters;
}

}  // namespace

std::string RadioReceiverOfTopic(const std::string& topic) {
  const std::string prefix = "/radio/", suffix = "/samples";
  if (topic.size() <= prefix.size() + suffix.size() ||
      topic.compare(0, prefix.size(), prefix) != 0 ||
      topic.compare(topic.size() - suffix.size(), suffix.size(), suffix) != 0)
    return "";
  return topic.substr(prefix.size(), topic.size() - prefix.size() - suffix.size());
}

RadioStep::RadioStep(const RadioParameters& parameters)
    : parameters_(WithNetwork(parameters)),
      solver_(parameters_.network, parameters_.options),
      assembler_(ReceiverIds(parameters_.network), parameters_.stamp_tolerance,
                 parameters_.max_wait) {}

std::vector<std::string> RadioStep::receivers() const { return ReceiverIds(parameters_.network); }

bool RadioStep::Accept(const slope_monitor::RadioSampleBlock& block, const std::string& receiver,
                       double now) {
  ++blocks_received_;
  if (validator_.Accept(block, receiver, now)) return true;
  last_error_ = validator_.last_problems().front();
  return false;
}

void RadioStep::Resume(double first_stamp, std::vector<LogLine>* log) {
  resumed_ = true;
  if (parameters_.database.empty()) return;
  states_ = std::make_unique<deformation::SavedStates>(parameters_.database);
  run_key_ = Message(kStatePrefix, Fixed(first_stamp, 3));
  // Epochs of a later recording already in the history: tracked again after this one (Finish).
  late_ = !states_->After(kPhasesPrefix, first_stamp).empty();
  const auto saved = states_->LatestBefore(kStatePrefix, first_stamp);
  if (!saved) return;
  solver_.Load(saved->value);
  log->push_back({LogLine::kInfo,
                  Message("radio reference solution of stamp ", Fixed(solver_.reference().stamp, 3),
                          " and tracking state of stamp ", Fixed(saved->stamp, 3),
                          " loaded from the history '", parameters_.database, "'")});
}

std::vector<RadioEpochOutput> RadioStep::Assemble(const slope_monitor::RadioSampleBlock& block,
                                                  std::vector<LogLine>* dropped) {
  std::vector<RadioEpochOutput> out;
  try {
    if (!resumed_) Resume(block.header.stamp.toSec(), dropped);
    for (const radio::EpochAssembler::Epoch& epoch : assembler_.Add(FromMsg(block)))
      out.push_back(Solve(epoch, block.header));
  } catch (const std::exception& e) {
    ++errors_;
    last_error_ = e.what();
    dropped->push_back(
        {LogLine::kError, "block of '" + block.receiver_id + "' dropped: " + e.what()});
  }
  return out;
}

std::vector<RadioEpochOutput> RadioStep::Finish(std::vector<LogLine>* log) {
  std::vector<RadioEpochOutput> out;
  if (!late_ || !states_) return out;
  late_ = false;
  std::map<double, std::string> state_keys;  // the later runs' states, by their last stamp
  for (const auto& s : states_->After(kStatePrefix, last_stamp_)) state_keys[s.stamp] = s.key;
  const auto later = states_->After(kPhasesPrefix, last_stamp_);
  if (later.empty()) return out;
  log->push_back(
      {LogLine::kWarn, Message("this recording precedes ", later.size(),
                               " radio epoch(s) already in the history: tracked again after it, in "
                               "time order; their displacements revised")});
  std_msgs::Header header;
  for (const auto& phases : later) {
    const radio::RadioEpochSummary s = solver_.ProcessPhases(phases.value);
    header.stamp = ros::Time(s.stamp);
    out.push_back(Output(s, header));
    auto key = state_keys.find(phases.stamp);
    if (key != state_keys.end()) states_->Put(key->second, phases.stamp, solver_.Save());
  }
  return out;
}

RadioEpochOutput RadioStep::Solve(const radio::EpochAssembler::Epoch& epoch,
                                  const std_msgs::Header& input_header) {
  const radio::RadioEpochSummary s = solver_.ProcessEpoch(epoch.stamp, epoch.blocks);
  if (states_) {
    states_->Put(Message(kPhasesPrefix, Fixed(epoch.stamp, 6)), epoch.stamp, solver_.LastPhases());
    states_->Put(run_key_, epoch.stamp, solver_.Save());
  }
  last_stamp_ = std::max(last_stamp_, epoch.stamp);
  return Output(s, input_header);
}

RadioEpochOutput RadioStep::Output(const radio::RadioEpochSummary& s,
                                   const std_msgs::Header& input_header) {
  ++epochs_;
  RadioEpochOutput out;
  for (const std::string& p : s.problems) {
    out.log.push_back({LogLine::kError, p});
    last_error_ = p;
    ++errors_;
  }
  for (const std::string& e : s.events) {
    out.log.push_back({LogLine::kWarn, e});
    last_event_ = e;
  }
  for (const std::string& n : s.notes) out.log.push_back({LogLine::kInfo, n});
  last_ = s;
  std_msgs::Header header = input_header;
  header.stamp = ros::Time(s.stamp);
  header.frame_id = parameters_.frame_id;
  out.messages = MakeRadioOutputs(s, header, epochs_);
  return out;
}

void RadioStep::Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const {
  const auto& ref = solver_.reference();
  int ok_links = 0, links = 0;
  for (const auto& l : last_.links) {
    ++links;
    if (l.used) ++ok_links;
    stat.add("link " + l.transmitter_id + "->" + l.receiver_id,
             l.status + " (snr " + std::to_string(l.snr) + ", refixes " +
                 std::to_string(l.refixes) + ")");
  }
  for (const auto& t : last_.transmitters)
    stat.add("transmitter " + t.id, t.status + ", reference " + radio::FixStateName(t.fix_state) +
                                        " ratio " + std::to_string(t.ratio) + ", epoch " +
                                        radio::FixStateName(t.epoch_fix_state) + ", links " +
                                        std::to_string(t.links_used));
  stat.add("blocks received", blocks_received_);
  for (const auto& [reason, count] : validator_.rejected()) stat.add("rejected: " + reason, count);
  stat.add("epochs", epochs_);
  stat.add("errors", errors_);
  stat.add("last error", last_error_);
  stat.add("last event", last_event_);
  stat.add("reference",
           ref.solved
               ? radio::FixStateName(ref.fix_state) + " " + std::to_string(ref.num_fixed) + "/" +
                     std::to_string(ref.num_ambiguities) + " ratio " + std::to_string(ref.ratio)
               : std::string("initialising"));
  if (!ref.solved)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for the reference epochs");
  else if (links > 0 && ok_links < links)
    stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%d of %d links in use", ok_links,
                  links);
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "all links in use");
}

}  // namespace ros_adapters
}  // namespace slope_monitor
