// radio_phase_solver: transmitter positions and displacements from radio
// phase (core/radio/phase_solver.h).
//
// Thin wrapper: parameters -> RadioSolverOptions; the network from
// `network_file` (config/radio/*.yaml) or, for simulated surveys, from the
// simulator's truth file (`truth_file`: receivers, transmitter frequencies,
// epoch-0 transmitter positions as the installation survey); each configured
// receiver's `<id>/samples` (RadioSampleBlock) -> SampleBlock -> epochs by
// stamp (EpochAssembler) -> RadioPhaseSolver::ProcessEpoch -> outputs: the
// work of ros_adapters::RadioStep (ros/radio_step.h), shared with process_bag.
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
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/radio_step.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class RadioPhaseSolverNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros_adapters::GraphReady ready(getPrivateNodeHandle());
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    ros_adapters::RadioParameters params;
    if (const auto error = ros_adapters::SetUpError([&] {
          ros_adapters::ParamReader p(pnh);
          params = ros_adapters::ReadRadioParameters(p);
          if (params.has_network) step_ = std::make_unique<ros_adapters::RadioStep>(params);
        })) {
      NODELET_ERROR("radio_phase_solver: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(
          nh, pnh, "radio_phase_solver", "parameters rejected: " + *error);
      return;
    }
    if (!step_) {  // radio is optional: a site without a radio network
      NODELET_INFO(
          "radio_phase_solver: no radio network (network_file, truth_file and the site file's "
          "radio_network are empty): idle");
      return;
    }
    const std::vector<std::string> ids = step_->receivers();
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
      // A recording before later ones already in the history: their radio
      // epochs are tracked again (the saved states follow), but the graph's
      // estimator keeps the displacements it holds; process_bag revises them.
      std::vector<ros_adapters::LogLine> log;
      const size_t revised = step_->Finish(&log).size();
      Log(log);
      if (revised > 0)
        NODELET_WARN(
            "radio_phase_solver: the history's displacements of those %zu epochs are "
            "not revised by the graph: process this recording with process_bag",
            revised);
    });
    obs_pub_ = nh.advertise<slope_monitor::RadioPhaseObservationArray>("phase_observations", 10);
    disp_pub_ =
        nh.advertise<slope_monitor::PointDisplacementArray>("radio_displacements", 10, true);
    for (const std::string& id : ids)
      subs_.push_back(nh.subscribe<slope_monitor::RadioSampleBlock>(
          id + "/samples", 20,
          [this, id](const slope_monitor::RadioSampleBlockConstPtr& m) { OnBlock(m, id); }));
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("radio_phase_solver");
    updater_->add("radio_phase_solver", [this](diagnostic_updater::DiagnosticStatusWrapper& stat) {
      std::lock_guard<std::mutex> lock(mutex_);
      step_->Diagnose(stat);
    });
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0),
                                     [this](const ros::WallTimerEvent&) { updater_->update(); });
    NODELET_INFO("radio_phase_solver: %zu receivers, %zu transmitters, lambda %.4f m",
                 params.network.receivers.size(), params.network.transmitters.size(),
                 params.network.wavelength);
  }

  void OnBlock(const slope_monitor::RadioSampleBlockConstPtr& msg, const std::string& receiver) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!step_->Accept(*msg, receiver, ros::WallTime::now().toSec())) {
      NODELET_WARN_THROTTLE(10.0, "radio_phase_solver: rejected %s", step_->last_problem().c_str());
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
    std::vector<ros_adapters::LogLine> dropped;  // and the state loaded from the history (kInfo)
    for (const ros_adapters::RadioEpochOutput& out : step_->Assemble(*msg, &dropped)) {
      Log(out.log);
      obs_pub_.publish(out.messages.observations);
      if (out.messages.displacements) disp_pub_.publish(*out.messages.displacements);
    }
    Log(dropped);
  }

  void Log(const std::vector<ros_adapters::LogLine>& lines) const {
    for (const ros_adapters::LogLine& line : lines) {
      if (line.level == ros_adapters::LogLine::kError)
        NODELET_ERROR_THROTTLE(5.0, "radio_phase_solver: %s", line.text.c_str());
      else if (line.level == ros_adapters::LogLine::kWarn)
        NODELET_WARN_THROTTLE(5.0, "radio_phase_solver: %s", line.text.c_str());
      else  // routine results (every ambiguity fixed, the state loaded): INFO
        NODELET_INFO("radio_phase_solver: %s", line.text.c_str());
    }
  }

  std::unique_ptr<ros_adapters::RadioStep> step_;  // null: no radio network, idle
  // [s] wall: how long the blocks of the other receivers wait for a silent one (live only).
  static constexpr double kSilentReceiverWait = 60.0;
  std::unique_ptr<InputOrder<slope_monitor::RadioSampleBlockConstPtr>> order_;
  ros::WallTimer order_timer_;
  ros::Subscriber end_sub_;  // replay only: the end of the input
  ros::Publisher obs_pub_, disp_pub_;
  std::vector<ros::Subscriber> subs_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diag_timer_;
  std::mutex mutex_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics>
      setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::RadioPhaseSolverNodelet, nodelet::Nodelet)
