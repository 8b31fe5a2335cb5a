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
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>

#include <diagnostic_updater/diagnostic_updater.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>

#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RadioPhaseObservationArray.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/radio/phase_solver.h"
#include "slope_monitor/core/sim/truth.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"
#include "slope_monitor/ros/validation.h"

namespace slope_monitor {

class RadioPhaseSolverNodelet : public nodelet::Nodelet {
 private:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] {
          if (ReadParameters(pnh)) solver_ = std::make_unique<radio::RadioPhaseSolver>(network_, options_);
        })) {
      NODELET_ERROR("radio_phase_solver: %s; not advertising", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(nh, pnh, "radio_phase_solver",
                                                                               "parameters rejected: " + *error);
      return;
    }
    if (!solver_) {  // radio is optional: a site without a radio network
      NODELET_INFO("radio_phase_solver: no radio network (network_file, truth_file and the site file's "
                   "radio_network are empty): idle");
      return;
    }
    std::vector<std::string> ids;
    for (const auto& r : network_.receivers) ids.push_back(r.id);
    assembler_ = std::make_unique<radio::EpochAssembler>(ids, stamp_tolerance_, max_wait_);
    obs_pub_ = nh.advertise<slope_monitor::RadioPhaseObservationArray>("phase_observations", 10);
    disp_pub_ = nh.advertise<slope_monitor::PointDisplacementArray>("radio_displacements", 10, true);
    for (const auto& r : network_.receivers)
      subs_.push_back(nh.subscribe<slope_monitor::RadioSampleBlock>(
          r.id + "/samples", 20,
          [this, id = r.id](const slope_monitor::RadioSampleBlockConstPtr& m) { OnBlock(m, id); }));
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("radio_phase_solver");
    updater_->add("radio_phase_solver", this, &RadioPhaseSolverNodelet::Diagnose);
    diag_timer_ = nh.createWallTimer(ros::WallDuration(1.0), [this](const ros::WallTimerEvent&) { updater_->update(); });
    NODELET_INFO("radio_phase_solver: %zu receivers, %zu transmitters, lambda %.4f m", network_.receivers.size(),
                 network_.transmitters.size(), network_.wavelength);
  }

  // False when no radio network is configured anywhere (the node stays idle).
  bool ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    const std::string network_file = p.String("network_file", "");
    const std::string site_file = p.String("site_file", "");  // its radio_network, when it names one
    const std::string truth_file = p.String("truth_file", "");
    const double truth_sigma = p.Double("truth_initial_sigma", 0.005, 1e-5, 10.0, "m");
    const double truth_rate = p.Double("truth_sample_rate", 20000.0, 1.0, 1e10, "Hz");
    radio::RadioSolverOptions& o = options_;
    o.extraction.min_snr = p.Double("min_snr", 100.0, 1e-3, 1e9);
    o.extraction.max_saturated_fraction = p.Double("max_saturated_fraction", 1e-3, 0.0, 1.0);
    o.extraction.fit_dc = p.Bool("fit_dc", true);
    o.init_epochs = p.Int("init_epochs", 5, 1, 1000, "epochs");
    o.ratio_threshold = p.Double("ratio_threshold", 3.0, 1.0, 100.0);
    o.process_noise = p.Double("process_noise", 1e-9, 0.0, 1.0, "m^2/s");
    o.outlier_sigma = p.Double("outlier_sigma", 5.0, 2.0, 100.0);
    o.refix_after = p.Int("refix_after", 5, 1, 1000, "epochs");
    o.min_phase_sigma = p.Double("min_phase_sigma", 0.01, 0.0, 1.0, "rad");
    o.min_receivers = p.Int("min_receivers", 3, 3, 100);
    o.max_refix_sigma = p.Double("max_refix_sigma", 0.01, 1e-6, 1.0, "m");
    stamp_tolerance_ = p.Double("stamp_tolerance", 1e-3, 0.0, 10.0, "s");
    max_wait_ = p.Double("max_wait", 2.5, 0.0, 86400.0, "s");
    frame_id_ = p.String("frame_id", "site");
    p.CheckNoUnknownKeys();
    // A site file's radio network wins over network_file / truth_file (replay.launch defaults
    // truth_file to the bag's); a site without one leaves them in charge.
    const std::string site_network = site_file.empty() ? "" : io::LoadSiteFile(site_file).radio_network;
    if (!site_network.empty()) {
      if (!network_file.empty() || !truth_file.empty())
        NODELET_INFO("radio_phase_solver: the radio network comes from the site file %s; network_file / "
                     "truth_file are not used", site_file.c_str());
      network_ = radio::NetworkConfig::Load(site_network);
      return true;
    }
    if (network_file.empty() && truth_file.empty()) return false;
    if (network_file.empty() == truth_file.empty())
      throw ConfigError(p.FullKey("network_file") + " / " + p.FullKey("truth_file") + ": set exactly one of them");
    if (!network_file.empty()) {
      network_ = radio::NetworkConfig::Load(network_file);
    } else {
      network_ = NetworkFromTruth(sim::SurveyTruth::Load(truth_file), truth_sigma, truth_rate, truth_file);
    }
    return true;
  }

  // The simulator's truth as a network file: receivers as surveyed, the
  // transmitters' epoch-0 positions as the installation survey.
  static radio::NetworkConfig NetworkFromTruth(const sim::SurveyTruth& truth, double sigma, double sample_rate,
                                               const std::string& path) {
    radio::NetworkConfig n;
    if (truth.radio.Empty()) throw ConfigError(path + ": radio: the truth has no radio network");
    n.wavelength = truth.radio.wavelength;
    n.center_frequency = truth.radio.center_frequency;
    n.sample_rate = sample_rate;  // the truth does not hold it: parameter truth_sample_rate
    for (const auto& r : truth.radio.receivers) n.receivers.push_back({r.id, r.position});
    for (const auto& t : truth.radio.transmitters) {
      if (t.positions.empty()) throw ConfigError(path + ": radio.transmitters '" + t.id + "' has no positions");
      radio::TransmitterConfig c;
      c.id = t.id;
      c.frequency_offset = t.frequency - n.center_frequency;
      c.initial_position = t.positions.front();
      c.initial_sigma = sigma;
      n.transmitters.push_back(c);
    }
    n.Check(path);
    return n;
  }

  static radio::SampleBlock FromMsg(const slope_monitor::RadioSampleBlock& m) {
    radio::SampleBlock b;
    b.receiver_id = m.receiver_id;
    b.frame_id = m.header.frame_id;
    b.stamp = m.header.stamp.toSec();
    b.sequence = m.sequence;
    b.sample_rate = m.sample_rate;
    b.center_frequency = m.center_frequency;
    b.full_scale = m.full_scale;
    b.i = m.i;
    b.q = m.q;
    return b;
  }

  void OnBlock(const slope_monitor::RadioSampleBlockConstPtr& msg, const std::string& receiver) {
    std::lock_guard<std::mutex> lock(mutex_);
    ++blocks_received_;
    if (!validator_.Accept(*msg, receiver, ros::WallTime::now().toSec())) {
      last_error_ = validator_.last_problems().front();
      NODELET_WARN_THROTTLE(10.0, "radio_phase_solver: rejected %s", last_error_.c_str());
      return;
    }
    try {
      for (auto& epoch : assembler_->Add(FromMsg(*msg))) Process(epoch, msg->header);
    } catch (const std::exception& e) {
      ++errors_;
      last_error_ = e.what();
      NODELET_ERROR_THROTTLE(5.0, "radio_phase_solver: block of '%s' dropped: %s", msg->receiver_id.c_str(), e.what());
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

    slope_monitor::RadioPhaseObservationArray obs;
    obs.header = header;
    for (const auto& o : s.observations) {
      slope_monitor::RadioPhaseObservation m;
      m.receiver_id = o.receiver_id;
      m.transmitter_id = o.transmitter_id;
      m.frequency = o.frequency;
      m.phase = o.phase;
      m.phase_variance = o.phase_variance;
      m.amplitude = o.amplitude;
      m.snr = o.snr;
      obs.observations.push_back(m);
    }
    obs_pub_.publish(obs);

    if (!s.IsSolutionUsable()) return;
    slope_monitor::PointDisplacementArray out;
    out.header = header;
    out.epoch = epochs_;
    for (const auto& t : s.transmitters) {
      if (!t.initialized) continue;
      // The reference block itself: its displacement is zero by definition with
      // a singular covariance; it is the datum, not a measurement of motion.
      if (t.displacement_covariance.diagonal().minCoeff() <= 0.0 ||
          Eigen::LLT<Eigen::Matrix3d>(t.displacement_covariance).info() != Eigen::Success)
        continue;
      slope_monitor::PointDisplacement d = ros_adapters::MakePointDisplacement(
          t.id, slope_monitor::PointDisplacement::SOURCE_RADIO, "radio_phase_solver", t.reference_stamp, header.stamp,
          t.reference_position, t.displacement, t.displacement_covariance);
      const double n = t.displacement.norm();
      if (n > 0.0) {
        const Eigen::Vector3d u = t.displacement / n;
        const double sigma = std::sqrt(std::max(0.0, u.dot(t.displacement_covariance * u)));
        d.significance = sigma > 0.0 ? n / sigma : 0.0;
      }
      out.displacements.push_back(d);
    }
    disp_pub_.publish(out);
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto& ref = solver_->reference();
    int ok_links = 0, links = 0;
    for (const auto& l : last_.links) {
      ++links;
      if (l.used) ++ok_links;
      stat.add("link " + l.transmitter_id + "->" + l.receiver_id,
               l.status + " (snr " + std::to_string(l.snr) + ", refixes " + std::to_string(l.refixes) + ")");
    }
    for (const auto& t : last_.transmitters)
      stat.add("transmitter " + t.id, t.status + ", reference " + radio::FixStateName(t.fix_state) + " ratio " +
                                          std::to_string(t.ratio) + ", epoch " + radio::FixStateName(t.epoch_fix_state) +
                                          ", links " + std::to_string(t.links_used));
    stat.add("blocks received", blocks_received_);
    for (const auto& [reason, count] : validator_.rejected()) stat.add("rejected: " + reason, count);
    stat.add("epochs", epochs_);
    stat.add("errors", errors_);
    stat.add("last error", last_error_);
    stat.add("last event", last_event_);
    stat.add("reference", ref.solved ? radio::FixStateName(ref.fix_state) + " " + std::to_string(ref.num_fixed) +
                                           "/" + std::to_string(ref.num_ambiguities) + " ratio " +
                                           std::to_string(ref.ratio)
                                     : std::string("initialising"));
    if (!ref.solved)
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for the reference epochs");
    else if (links > 0 && ok_links < links)
      stat.summaryf(diagnostic_msgs::DiagnosticStatus::WARN, "%d of %d links in use", ok_links, links);
    else
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "all links in use");
  }

  radio::NetworkConfig network_;
  radio::RadioSolverOptions options_;
  std::unique_ptr<radio::RadioPhaseSolver> solver_;
  std::unique_ptr<radio::EpochAssembler> assembler_;
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
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics> setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::RadioPhaseSolverNodelet, nodelet::Nodelet)
