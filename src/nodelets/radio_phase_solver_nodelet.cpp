// radio_phase_solver: transmitter positions and displacements from radio
// phase (core/radio/phase_solver.h).
//
// Thin wrapper: parameters -> RadioSolverOptions; the network from
// `network_file` (config/radio/*.yaml) or, for simulated surveys, from the
// simulator's truth file (`truth_file`: receivers, transmitter frequencies,
// epoch-0 transmitter positions as the installation survey); each configured
// receiver's `<id>/samples` (RadioSampleBlock) -> SampleBlock -> epochs by
// stamp (EpochAssembler) -> RadioPhaseSolver::ProcessEpoch -> outputs.
// Subscriptions are not lazy: phase continuity and the reference epoch need
// every block whether or not anyone listens.
#include <memory>
#include <mutex>

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RadioPhaseObservationArray.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/input_order.h"
#include "slope_monitor/core/radio/phase_solver.h"
#include "slope_monitor/core/sim/truth.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/radio_conversions.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/validation.h"

namespace slope_monitor {

class RadioPhaseSolverNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          if (ReadParameters(pnh))
            solver_ = std::make_unique<radio::RadioPhaseSolver>(network_, options_);
        })) {
      NODELET_ERROR("radio_phase_solver: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "radio_phase_solver", "parameters rejected: " + *error);
      return;
    }
    if (!solver_) {  // radio is optional: a site without a radio network
      NODELET_INFO(
          "radio_phase_solver: no radio network (network_file, truth_file and the site file's "
          "radio_network are empty): idle");
      return;
    }
    std::vector<std::string> ids;
    for (const auto& r : network_.receivers) ids.push_back(r.id);
    assembler_ = std::make_unique<radio::EpochAssembler>(ids, stamp_tolerance_, max_wait_);
    // The receivers' blocks in one stamp order (each receiver's topic is in
    // order; across topics a fast replay or a busy machine mixes them, and the
    // assembler's max_wait rule would then split epochs): as process_bag reads them.
    order_ = std::make_unique<InputOrder<slope_monitor::RadioSampleBlockConstPtr>>(ids);
    order_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                      [this](const ros::WallTimerEvent&) { OnOrderTimer(); });
    // The end of a replay (ros/setup.h): the blocks held for a silent receiver go on.
    end_sub_ = ros_adapters::SubscribeEndOfInput(nh, ros_adapters::kEndOfAdjustment, [this] {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto& r : order_->Flush()) Assemble(r.item);
    });
    obs_pub_ = nh.advertise<slope_monitor::RadioPhaseObservationArray>("phase_observations", 10);
    disp_pub_ =
        nh.advertise<slope_monitor::PointDisplacementArray>("radio_displacements", 10, true);
    for (const auto& r : network_.receivers)
      subs_.push_back(nh.subscribe<slope_monitor::RadioSampleBlock>(
          r.id + "/samples", 20,
          [this, id = r.id](const slope_monitor::RadioSampleBlockConstPtr& m) { OnBlock(m, id); }));
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("radio_phase_solver");
    updater_->add("radio_phase_solver", this, &RadioPhaseSolverNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
    NODELET_INFO("radio_phase_solver: %zu receivers, %zu transmitters, lambda %.4f m",
                 network_.receivers.size(), network_.transmitters.size(), network_.wavelength);
  }

  // False when no radio network is configured anywhere (the node stays idle).
  bool ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    ros_adapters::RadioParameters r = ros_adapters::ReadRadioParameters(p);
    network_ = std::move(r.network);
    options_ = r.options;
    stamp_tolerance_ = r.stamp_tolerance;
    max_wait_ = r.max_wait;
    frame_id_ = r.frame_id;
    return r.has_network;
  }

  void OnBlock(const slope_monitor::RadioSampleBlockConstPtr& msg, const std::string& receiver) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++blocks_received_;
    if (!validator_.Accept(*msg, receiver, ros::WallTime::now().toSec())) {
      last_error_ = validator_.last_problems().front();
      NODELET_WARN_THROTTLE(10.0, "radio_phase_solver: rejected %s", last_error_.c_str());
      return;
    }
    for (auto& r :
         order_->Add(receiver, msg->header.stamp.toSec(), msg, ros::WallTime::now().toSec()))
      Assemble(r.item);
  }

  // Live: a receiver silent for kSilentReceiverWait no longer holds the others' blocks.
  void OnOrderTimer() {
    if (!ros_adapters::LiveTimeouts()) return;  // replay: the blocks' order alone
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<std::string> given_up;
    for (auto& r : order_->Expire(ros::WallTime::now().toSec(), kSilentReceiverWait, &given_up))
      Assemble(r.item);
    for (const std::string& rx : given_up)
      NODELET_WARN_THROTTLE(
          60.0,
          "radio_phase_solver: no block of receiver '%s' for %.0f s: the others go on without it",
          rx.c_str(), kSilentReceiverWait);
  }

  // Caller holds mutex_.
  void Assemble(const slope_monitor::RadioSampleBlockConstPtr& msg) {
    try {
      for (auto& epoch : assembler_->Add(ros_adapters::FromMsg(*msg))) Process(epoch, msg->header);
    } catch (const std::exception& e) {
      ++errors_;
      last_error_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "radio_phase_solver: block of '%s' dropped: %s",
                             msg->receiver_id.c_str(), e.what());
    }
  }

  void Process(const radio::EpochAssembler::Epoch& epoch, const std_msgs::Header& input_header) {
    const radio::RadioEpochSummary s = solver_->ProcessEpoch(epoch.stamp, epoch.blocks);
    ++epochs_;
    for (const auto& p : s.problems) {
      NODELET_ERROR_THROTTLE(5.0, "radio_phase_solver: %s", p.c_str());
      last_error_ = p;
      ++errors_;
    }
    for (const auto& e : s.events) {
      NODELET_WARN_THROTTLE(5.0, "radio_phase_solver: %s", e.c_str());
      last_event_ = e;
    }
    last_ = s;
    std_msgs::Header header = input_header;
    header.stamp = ros::Time(epoch.stamp);
    header.frame_id = frame_id_;
    const ros_adapters::RadioOutputs out = ros_adapters::MakeRadioOutputs(s, header, epochs_);
    obs_pub_.publish(out.observations);
    if (out.displacements) disp_pub_.publish(*out.displacements);
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto& ref = solver_->reference();
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
    for (const auto& [reason, count] : validator_.rejected())
      stat.add("rejected: " + reason, count);
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

  radio::NetworkConfig network_;
  radio::RadioSolverOptions options_;
  std::unique_ptr<radio::RadioPhaseSolver> solver_;
  std::unique_ptr<radio::EpochAssembler> assembler_;
  // [s] wall: how long the blocks of the other receivers wait for a silent one (live only).
  static constexpr double kSilentReceiverWait = 60.0;
  std::unique_ptr<InputOrder<slope_monitor::RadioSampleBlockConstPtr>> order_;
  ros::WallTimer order_timer_;
  ros::Subscriber end_sub_;  // replay only: the end of the input
  ros_adapters::MessageValidator validator_;
  double stamp_tolerance_ = 1e-3, max_wait_ = 2.5;
  std::string frame_id_ = "site";
  ros::Publisher obs_pub_, disp_pub_;
  std::vector<ros::Subscriber> subs_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  std::mutex mutex_;
  radio::RadioEpochSummary last_;
  long blocks_received_ = 0, errors_ = 0;
  unsigned int epochs_ = 0;
  std::string last_error_, last_event_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::RadioPhaseSolverNodelet, nodelet::Nodelet)
