// The radio phase solver node's work, from ROS messages: a receiver's
// RadioSampleBlock is checked (MessageValidator), blocks are assembled into
// epochs by stamp (radio::EpochAssembler) and each complete epoch is solved
// (radio::RadioPhaseSolver) into the messages to publish. The
// radio_phase_solver nodelet (in its callbacks, behind its receivers' stamp
// order) and process_bag (in bag-time order) use this same class.
// Not thread-safe: the caller serialises the calls.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <diagnostic_updater/DiagnosticStatusWrapper.h>

#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/radio/phase_solver.h"
#include "slope_monitor/ros/epoch_solver.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/radio_conversions.h"
#include "slope_monitor/ros/validation.h"

namespace slope_monitor {
namespace ros_adapters {

// The receiver whose samples a topic carries: <id> of "/radio/<id>/samples"
// (the replay graph's radio namespace); "" for any other topic.
std::string RadioReceiverOfTopic(const std::string& topic);

struct RadioEpochOutput {
  RadioOutputs messages;  // phase_observations, and radio_displacements when usable
  // The solver's problems (kError), events (kWarn: faults handled) and notes
  // (kInfo: routine results), without the node's name.
  std::vector<LogLine> log;
};

class RadioStep {
 public:
  // `parameters.has_network` must be true (ConfigError otherwise).
  explicit RadioStep(const RadioParameters& parameters);

  // The receivers' ids, in the network's order.
  std::vector<std::string> receivers() const;

  // Whether a block of `receiver` passes the checks (ros/validation.h);
  // `now` [s]: the caller's wall clock, 0 for a recording (no test of the
  // stamps against it). A rejected block: last_problem() says why.
  bool Accept(const slope_monitor::RadioSampleBlock& block, const std::string& receiver,
              double now);

  // An accepted block into its epoch: the epochs it completes, solved. A
  // block the assembler or the solver refuses is dropped: one kError line
  // in `*dropped` (the epochs before it stand).
  std::vector<RadioEpochOutput> Assemble(const slope_monitor::RadioSampleBlock& block,
                                         std::vector<LogLine>* dropped);

  unsigned int epochs() const { return epochs_; }
  const std::string& last_problem() const { return last_error_; }

  // The node's diagnostics: links, transmitters, counts, reference state.
  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const;

 private:
  RadioEpochOutput Solve(const radio::EpochAssembler::Epoch& epoch,
                         const std_msgs::Header& input_header);

  RadioParameters parameters_;
  radio::RadioPhaseSolver solver_;
  radio::EpochAssembler assembler_;
  MessageValidator validator_;
  radio::RadioEpochSummary last_;
  long blocks_received_ = 0, errors_ = 0;
  unsigned int epochs_ = 0;
  std::string last_error_, last_event_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
