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
#include "slope_monitor/core/deformation/history.h"
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
  // in `*dropped` (the epochs before it stand). With a database, the first
  // block loads the state saved before it (a kInfo line in `*dropped`) and
  // every solved epoch saves the state (parameters.database).
  std::vector<RadioEpochOutput> Assemble(const slope_monitor::RadioSampleBlock& block,
                                         std::vector<LogLine>* dropped);

  // End of a recording: when it preceded radio epochs already in the
  // history (a recording processed after a later one), those epochs are
  // tracked again from its end, in time order, from their saved phases, and
  // returned as revisions (one kWarn line in `*log`). Empty otherwise.
  std::vector<RadioEpochOutput> Finish(std::vector<LogLine>* log);

  unsigned int epochs() const { return epochs_; }
  const std::string& last_problem() const { return last_error_; }

  // The node's diagnostics: links, transmitters, counts, reference state.
  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const;

 private:
  RadioEpochOutput Solve(const radio::EpochAssembler::Epoch& epoch,
                         const std_msgs::Header& input_header);
  RadioEpochOutput Output(const radio::RadioEpochSummary& s, const std_msgs::Header& input_header);
  // The state saved in the history before `first_stamp`, if any.
  void Resume(double first_stamp, std::vector<LogLine>* log);
  static constexpr char kStatePrefix[] = "radio/";          // a run's state, by its first stamp
  static constexpr char kPhasesPrefix[] = "radio_phases/";  // each epoch's phases, by its stamp

  RadioParameters parameters_;
  radio::RadioPhaseSolver solver_;
  radio::EpochAssembler assembler_;
  MessageValidator validator_;
  radio::RadioEpochSummary last_;
  std::unique_ptr<deformation::SavedStates> states_;  // the site's history; null: none
  bool resumed_ = false;
  bool late_ = false;        // epochs of later recordings are in the history
  double last_stamp_ = 0.0;  // of this run's last epoch
  std::string run_key_;      // this run's state: radio/<first block's stamp>
  long blocks_received_ = 0, errors_ = 0;
  unsigned int epochs_ = 0;
  std::string last_error_, last_event_;
};

}  // namespace ros_adapters
}  // namespace slope_monitor
