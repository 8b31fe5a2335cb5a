// bundle_adjuster nodelet: converts the target observations, tie points,
// camera infos, GNSS position priors and epoch markers of the graph into the
// core's EpochCollector (which decides when an epoch is complete, see
// core/adjustment/epoch_collector.h), and publishes what the core computes for
// each complete epoch: the solution, tf of every camera, the adjusted points
// with their sigma, and displacements of monitoring points against the
// reference epoch. The process_bag tool drives the same core the same way.
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <nodelet/nodelet.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/static_transform_broadcaster.h>
#include <tf2_ros/transform_broadcaster.h>
#include <pluginlib/class_list_macros.hpp>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RunAdjustment.h"
#include "slope_monitor/SetReferenceEpoch.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/adjustment/site_options.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

class BundleAdjusterNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh); })) {
      NODELET_ERROR("bundle_adjuster: %s; not advertising anything", error->c_str());
      setup_failure_ = std::make_unique<ros_adapters::SetUpFailureDiagnostics>(nh, pnh, "bundle_adjuster",
                                                                               "parameters rejected: " + *error);
      return;
    }
    solution_pub_ = nh.advertise<slope_monitor::AdjustmentSolution>("solution", 5, true);
    points_pub_ = nh.advertise<sensor_msgs::PointCloud2>("points", 5, true);
    displacements_pub_ =
        nh.advertise<slope_monitor::PointDisplacementArray>("displacements", 5, true);
    for (const std::string& topic : target_topics_)
      target_subs_.push_back(nh.subscribe(topic, 500, &BundleAdjusterNodelet::OnTargets, this));
    for (const std::string& cam : collector_options_.cameras) {
      info_subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          cam + "/camera_info", 5,
          [this, cam](const sensor_msgs::CameraInfoConstPtr& m) { OnCameraInfo(cam, m); }));
    }
    // Large queues: a long solve holds the callbacks, and nothing may be lost.
    tie_sub_ = nh.subscribe("tie_points", 2000, &BundleAdjusterNodelet::OnTiePoints, this);
    prior_sub_ = nh.subscribe("position_prior", 500, &BundleAdjusterNodelet::OnPositionPrior, this);
    for (const std::string& topic : epoch_topics_)
      epoch_subs_.push_back(nh.subscribe(topic, 20, &BundleAdjusterNodelet::OnEpoch, this));
    // A live installation may switch off the services that change state (ROS 1
    // has no authentication; doc/security.md).
    if (enable_run_adjustment_)
      run_srv_ = nh.advertiseService("run_adjustment", &BundleAdjusterNodelet::OnRun, this);
    if (enable_set_reference_epoch_)
      reference_srv_ =
          nh.advertiseService("set_reference_epoch", &BundleAdjusterNodelet::OnSetReference, this);
    // The collector's time-outs are for live sensors only (a complete epoch is
    // decided by the messages); wall time, so that they also end on a replay
    // whose clock stopped with the bag.
    gap_timer_ = nh.createWallTimer(ros::WallDuration(1.0), &BundleAdjusterNodelet::OnTimer, this);
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("bundle_adjuster");
    updater_->add("adjustment", this, &BundleAdjusterNodelet::Diagnose);
    NODELET_INFO("bundle_adjuster: %zu target topics, %zu cameras, %zu targets in '%s'",
                 target_topics_.size(), collector_options_.cameras.size(),
                 targets_.targets().size(), target_list_path_.c_str());
  }

 private:
  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    // The site file (io::LoadSiteFile) gives the targets when it lists them
    // (target_list is then not read: replay.launch defaults it to the bag's),
    // and each camera's pixel size and kind.
    const std::string site_file = p.String("site_file", "");
    std::optional<io::SiteFile> site;
    if (!site_file.empty()) site = io::LoadSiteFile(site_file);
    target_list_path_ = p.String("target_list", "");
    if (site && site->targets) {
      if (!target_list_path_.empty())
        NODELET_INFO("bundle_adjuster: the targets come from the site file %s; parameter '%s' (%s) is not used",
                     site_file.c_str(), p.FullKey("target_list").c_str(), target_list_path_.c_str());
      targets_ = *site->targets;
      target_list_path_ = site->targets_file.empty() ? site_file + " (inline targets)" : site->targets_file;
    } else if (!target_list_path_.empty()) {
      targets_ = io::TargetList::Load(target_list_path_);
    } else {
      throw ConfigError("parameter '" + p.FullKey("target_list") + "' is required (or '" + p.FullKey("site_file") +
                        "' naming a site file with targets)");
    }
    // The camera kind is the site file's field, not the name.
    if (site) pixel_size_by_camera_ = adjustment::ApplySite(*site, &collector_options_, &scene_options_);
    target_topics_ = p.StringList("target_topics", {"targets"});
    adjustment::EpochCollectorOptions& c = collector_options_;
    c.cameras = p.StringList("cameras", {});
    epoch_topics_ = p.StringList("epoch_topics", {"epoch"});
    c.epoch_wait = p.Double("epoch_wait", 30.0, 0.0, 3600.0, "s");
    c.tie_point_cameras = p.StringList("tie_point_cameras", {});
    c.tie_point_wait = p.Double("tie_point_wait", 300.0, 0.0, 86400.0, "s");
    c.tie_pixel_sigma_floor = p.Double("tie_pixel_sigma_floor", 0.2, 0.0, 100.0, "px");
    c.min_tie_quality = p.Double("min_tie_quality", 0.25, 0.0, 1.0);
    frame_id_ = p.String("frame_id", "site");
    enable_run_adjustment_ = p.Bool("enable_run_adjustment", true);
    enable_set_reference_epoch_ = p.Bool("enable_set_reference_epoch", true);
    pixel_size_ = p.Double("pixel_size", 1.0, 1e-6, 1.0, "mm/px");
    c.pixel_sigma = p.Double("pixel_sigma", 0.3, 1e-4, 100.0, "px");
    c.pixel_sigma_floor = p.Double("pixel_sigma_floor", 0.05, 0.0, 100.0, "px");
    c.uav_pixel_sigma_floor = p.Double("uav_pixel_sigma_floor", 1.0, 0.0, 100.0, "px");
    c.epoch_gap = p.Double("epoch_gap", 600.0, 0.0, 1e7, "s");
    c.Check();
    scene_options_.position_prior_max_dt = p.Double("position_prior_max_dt", 0.1, 0.0, 10.0, "s");
    scene_options_.position_prior_min_sigma =
        p.Double("position_prior_min_sigma", 0.01, 1e-4, 100.0, "m");
    scene_options_.min_images = p.Int("min_images", 2, 1, 10000);
    scene_options_.Check();
    auto interior_list = [&p](const std::string& key) {
      std::vector<int> out;
      for (const std::string& name : p.StringList(key, {})) {
        int idx = -1;
        for (int i = 0; i < camera::kNumInterior; ++i)
          if (name == camera::InteriorNames()[i]) idx = i;
        if (idx < 0)
          throw ConfigError("parameter '" + p.FullKey(key) + "': unknown interior parameter '" +
                            name + "'");
        out.push_back(idx);
      }
      return out;
    };
    adjustment::EpochAdjustmentOptions& e = epoch_options_;
    e.free_interior = interior_list("free_interior");
    const std::vector<int> uav_free_interior = interior_list("uav_free_interior");
    adjustment::Options& o = e.adjustment;
    o.loss = p.String("loss", "huber", {"none", "huber", "cauchy"});
    o.loss_scale = p.Double("loss_scale", 3.0, 1e-3, 1e3, "sigma");
    o.outlier_threshold = p.Double("outlier_threshold", 5.0, 1e-3, 1e3, "sigma");
    o.linear_solver = p.String("linear_solver", "auto",
                               {"auto", "dense_schur", "sparse_schur", "iterative_schur"});
    o.max_iterations = p.Int("max_iterations", 100, 1, 10000);
    const int threads = p.Int("num_threads", 1, 0, 64);
    o.num_threads = threads > 0 ? threads : adjustment::Options::HardwareThreads();
    o.minimizer_progress = p.Bool("minimizer_progress", false);
    o.min_control_points = p.Int("min_control_points", 3, 0, 1000);
    o.max_sigma0 = p.Double("max_sigma0", 5.0, 0.01, 1e6);
    o.max_outlier_fraction = p.Double("max_outlier_fraction", 0.2, 0.0, 1.0);
    o.min_observations_with_prior = p.Int("min_observations_with_prior", 3, 2, 1000);
    o.min_variance_factor = p.Double("min_variance_factor", 1.0, 0.0, 100.0);
    o.compute_datum_free_covariance = p.Bool("datum_free_displacements", true);
    o.compute_covariance = true;
    o.Check();
    // A UAV camera self-calibrated in every flight: its own list (the fixed
    // cameras keep free_interior).
    if (!uav_free_interior.empty())
      for (const std::string& cam : c.cameras)
        if (adjustment::IsUavCamera(cam, c.uav_cameras)) e.free_interior_by_camera[cam] = uav_free_interior;
    e.name_unidentified = p.Bool("name_unidentified", true);
    e.orient_from_approximate = p.Bool("orient_from_approximate", true);
    e.naming.gate_sigma = p.Double("naming_gate_sigma", 3.0, 0.1, 100.0, "sigma");
    e.naming.gate_extra_px = p.Double("naming_gate_extra_px", 10.0, 0.0, 10000.0, "px");
    e.naming.coarse_extra_px = p.Double("naming_coarse_extra_px", 100.0, 0.0, 10000.0, "px");
    e.naming.ambiguity_factor = p.Double("naming_ambiguity_factor", 2.0, 1.0, 100.0);
    e.Check();
    displacement_options_.stable_threshold = p.Double("stable_threshold", 0.02, 1e-6, 100.0, "m");
    displacement_options_.significance_threshold =
        p.Double("significance_threshold", 3.0, 0.1, 100.0);
    displacement_options_.estimate_scale = p.Bool("coregistration_scale", false);
    displacement_options_.Check();
    p.CheckNoUnknownKeys();
    collector_ = std::make_unique<adjustment::EpochCollector>(collector_options_, &targets_);
  }

  // Cameras whose every photo has its own pose: the site file's kind uav;
  // without a site file, the collector's rule (adjustment::IsUavCamera).
  std::set<std::string> MovingCameras(const adjustment::Scene& scene) const {
    std::set<std::string> moving;
    for (const auto& camera : scene.cameras)
      if (adjustment::IsUavCamera(camera.name, collector_options_.uav_cameras)) moving.insert(camera.name);
    return moving;
  }

  // ---------------------------------------------------------------- input
  static double Now() { return ros::WallTime::now().toSec(); }

  void OnCameraInfo(const std::string& camera_name, const sensor_msgs::CameraInfoConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      const auto size = pixel_size_by_camera_.find(camera_name);
      models_[camera_name] = ros_adapters::CameraModelFromCameraInfo(
          *msg, size == pixel_size_by_camera_.end() ? pixel_size_ : size->second);
    } catch (const Error& e) {
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: camera_info of '%s': %s", camera_name.c_str(),
                             e.what());
    }
  }

  void OnTargets(const slope_monitor::TargetObservationArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    collector_->SetTiePointsExpected(tie_sub_.getNumPublishers() > 0);
    Solve(collector_->AddTargets(ros_adapters::FromMsg(*msg), Now()));
  }

  void OnTiePoints(const slope_monitor::TiePointArrayConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    // No matcher publishing (not started, or failed on its parameters):
    // nothing to wait for.
    collector_->SetTiePointsExpected(tie_sub_.getNumPublishers() > 0);
    Solve(collector_->AddTies(ros_adapters::FromMsg(*msg), Now()));
  }

  void OnPositionPrior(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    collector_->AddPrior(ros_adapters::FromMsg(*msg));
  }

  void OnEpoch(const slope_monitor::EpochMarkerConstPtr& msg) {
    if (!msg->end) return;
    std::lock_guard<std::mutex> lock(mutex_);
    collector_->SetTiePointsExpected(tie_sub_.getNumPublishers() > 0);
    Solve(collector_->AddEnd(ros_adapters::FromMsg(*msg), Now()));
    for (; reported_ignored_ < collector_->ignored().size(); ++reported_ignored_)
      NODELET_WARN("bundle_adjuster: %s", collector_->ignored()[reported_ignored_].c_str());
  }

  void OnTimer(const ros::WallTimerEvent&) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      collector_->SetTiePointsExpected(tie_sub_.getNumPublishers() > 0);
      Solve(collector_->Poll(Now()));
    }
    if (updater_) updater_->update();
  }

  bool OnRun(slope_monitor::RunAdjustment::Request& req,
             slope_monitor::RunAdjustment::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (req.epoch != 0 && req.epoch != collector_->current_epoch()) {
      res.success = false;
      res.message = "only the epoch being collected (" +
                    std::to_string(collector_->current_epoch()) + ") can be solved";
      return true;
    }
    res.solution = SolveOne(collector_->TakeNow());
    res.success = res.solution.usable;
    res.message = res.solution.message;
    return true;
  }

  bool OnSetReference(slope_monitor::SetReferenceEpoch::Request& req,
                      slope_monitor::SetReferenceEpoch::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    int chosen = -1;
    const std::string error =
        store_.SetReference(req.use_latest, static_cast<int>(req.epoch), &chosen);
    res.success = error.empty();
    res.message = error.empty() ? "reference epoch set to " + std::to_string(chosen) : error;
    if (res.success) res.reference_epoch = chosen;
    return true;
  }

  // ---------------------------------------------------------------- solve
  void Solve(const std::vector<adjustment::CollectedEpoch>& epochs) {
    for (const adjustment::CollectedEpoch& e : epochs) SolveOne(e);
  }

  slope_monitor::AdjustmentSolution SolveOne(const adjustment::CollectedEpoch& epoch) {
    const uint32_t n = epoch.epoch;
    for (const std::string& line : epoch.incomplete)
      NODELET_WARN("bundle_adjuster: epoch %u (%s): incomplete: %s", n, epoch.reason.c_str(),
                   line.c_str());
    for (const std::string& line : epoch.dropped)
      NODELET_WARN("bundle_adjuster: epoch %u: %s", n, line.c_str());
    slope_monitor::AdjustmentSolution out;
    out.header.frame_id = frame_id_;
    out.epoch = n;
    out.usable = false;
    if (epoch.observations.empty()) {
      out.message = "no observations collected";
      last_message_ = out.message;
      return out;
    }
    try {
      const adjustment::BuiltScene built =
          adjustment::BuildScene(epoch, models_, store_, targets_, scene_options_);
      const adjustment::EpochAdjustmentResult result = adjustment::AdjustEpoch(
          built.scene, built.unidentified, adjustment::ListedTargets(targets_), epoch_options_);
      LogResult(n, result, built.unidentified.empty());
      const adjustment::Summary& s = result.summary;
      out = ros_adapters::MakeSolution(epoch, result.scene, s, frame_id_);
      last_message_ = s.reason;
      last_usable_ = s.IsSolutionUsable();
      if (!s.IsSolutionUsable()) {
        NODELET_ERROR_THROTTLE(10.0,
                               "bundle_adjuster: epoch %u not usable: %s (previous solution kept)",
                               n, s.reason.c_str());
        solution_pub_.publish(out);
        return out;
      }
      // Accepted: the store keeps poses and calibration; publish everything.
      const adjustment::EpochPoints ep =
          store_.Accept(result.scene, s, static_cast<int>(n), out.header.stamp.toSec(),
                        epoch_options_.adjustment.compute_datum_free_covariance);
      solution_pub_.publish(out);
      // Fixed cameras on /tf_static (latched), each UAV photo as its own stamped transform on /tf.
      const ros_adapters::CameraTransforms tfs =
          ros_adapters::MakeTransforms(result.scene, epoch, frame_id_, out.header.stamp, MovingCameras(result.scene));
      if (!tfs.fixed.empty()) static_broadcaster_.sendTransform(tfs.fixed);
      if (!tfs.moving.empty()) tf_broadcaster_.sendTransform(tfs.moving);
      points_pub_.publish(ros_adapters::MakePointCloud(result.scene, s, out.header));
      PublishDisplacements(ep, out.header);
      ++accepted_;
      NODELET_INFO(
          "bundle_adjuster: epoch %u accepted: %zu images, %zu points, %d observations, sigma0 "
          "%.2f, rms %.3f px",
          n, result.scene.images.size(), result.scene.points.size(), s.num_observations, s.sigma0,
          s.rms_residual_px);
    } catch (const std::exception& e) {
      out.usable = false;
      out.message = std::string("adjustment failed: ") + e.what();
      last_message_ = out.message;
      last_usable_ = false;
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: %s (previous solution kept)",
                             out.message.c_str());
      solution_pub_.publish(out);
    }
    return out;
  }

  void LogResult(uint32_t n, const adjustment::EpochAdjustmentResult& result,
                 bool no_unidentified) {
    if (!result.initialization.empty())
      NODELET_WARN_THROTTLE(10.0, "bundle_adjuster: initialisation: %s",
                            result.initialization.c_str());
    if (!result.pruned.dropped_images.empty() || !result.pruned.dropped_cameras.empty())
      NODELET_WARN_THROTTLE(10.0, "bundle_adjuster: epoch %u: %s", n,
                            result.pruned.Summary().c_str());
    for (const std::string& r : result.rejected_names)
      NODELET_WARN("bundle_adjuster: epoch %u: target name given by projection rejected: %s", n,
                   r.c_str());
    for (size_t i = 0; i < result.naming.notes.size() && i < 5; ++i)
      NODELET_DEBUG("bundle_adjuster: epoch %u: %s", n, result.naming.notes[i].c_str());
    last_photos_ = result.photos;
    last_naming_ = result.naming;
    last_rejected_names_ = static_cast<int>(result.rejected_names.size());
    if (result.photos.total > 0 || !no_unidentified)
      NODELET_INFO(
          "bundle_adjuster: epoch %u: %s; %s; %d oriented from approximate target coordinates; %zu "
          "names "
          "rejected by the residual test",
          n, result.photos.Brief().c_str(), result.naming.Brief().c_str(),
          result.oriented_from_approximate, result.rejected_names.size());
  }

  void PublishDisplacements(const adjustment::EpochPoints& current,
                            const std_msgs::Header& header) {
    const std::optional<adjustment::EpochComparison> cmp =
        store_.CompareWithReference(current, displacement_options_);
    if (!cmp) return;
    if (!cmp->success) {
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: %s", cmp->message.c_str());
      return;
    }
    const adjustment::EpochPoints& ref = *store_.Reference();
    NODELET_INFO("bundle_adjuster: epoch %d vs reference %d: %zu monitoring displacements",
                 current.epoch, ref.epoch, cmp->displacements.size());
    displacements_pub_.publish(
        ros_adapters::MakeDisplacements(*cmp, ref, current.epoch, getName(), header));
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (last_message_.empty()) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "waiting for an epoch");
    } else if (last_usable_) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, last_message_);
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN,
                   "last epoch not usable: " + last_message_);
    }
    stat.add("collected observations", collector_->num_observations());
    stat.add("collected images", collector_->num_images());
    stat.add("accepted epochs", accepted_);
    stat.add("unidentified observations received", collector_->unidentified_received());
    stat.add("observations dropped: bad pixel or covariance", collector_->observations_dropped());
    stat.add("UAV photos last epoch", last_photos_.total);
    stat.add("UAV photos kept", last_photos_.kept);
    stat.add("UAV photos dropped: not oriented", last_photos_.not_oriented);
    stat.add("UAV photos dropped: too few observations", last_photos_.too_few_observations);
    stat.add("targets named by projection", last_naming_.named);
    stat.add("targets left unnamed: ambiguous", last_naming_.ambiguous);
    stat.add("targets left unnamed: no listed target near", last_naming_.unmatched);
    stat.add("targets left unnamed: image not oriented", last_naming_.not_oriented);
    stat.add("names rejected by the residual test", last_rejected_names_);
    stat.add("tie-point observation pairs used", collector_->tie_points_used());
    stat.add("tie points skipped: low quality", collector_->tie_points_low_quality());
    stat.add("reference epoch", store_.reference_epoch());
  }

  // Parameters.
  std::string target_list_path_;
  io::TargetList targets_;
  std::vector<std::string> target_topics_, epoch_topics_;
  std::string frame_id_;
  bool enable_run_adjustment_ = true, enable_set_reference_epoch_ = true;
  double pixel_size_ = 1.0;
  std::map<std::string, double> pixel_size_by_camera_;  // [mm/px] from the site file
  adjustment::EpochCollectorOptions collector_options_;
  adjustment::BuildSceneOptions scene_options_;
  adjustment::EpochAdjustmentOptions epoch_options_;
  adjustment::DisplacementOptions displacement_options_;

  // State (guarded by mutex_; a solve holds it, as the callbacks wait anyway).
  std::mutex mutex_;
  std::unique_ptr<adjustment::EpochCollector> collector_;
  adjustment::EpochStore store_;
  std::map<std::string, camera::CameraModel> models_;
  size_t reported_ignored_ = 0;
  adjustment::PhotoStats last_photos_;
  adjustment::NamingReport last_naming_;
  int last_rejected_names_ = 0;
  std::string last_message_;
  bool last_usable_ = false;
  int accepted_ = 0;

  // ROS.
  ros::Publisher solution_pub_, points_pub_, displacements_pub_;
  std::vector<ros::Subscriber> target_subs_, info_subs_;
  ros::Subscriber tie_sub_, prior_sub_;
  std::vector<ros::Subscriber> epoch_subs_;
  ros::ServiceServer run_srv_, reference_srv_;
  ros::WallTimer gap_timer_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  tf2_ros::StaticTransformBroadcaster static_broadcaster_;
  std::unique_ptr<diagnostic_updater::Updater> updater_;
  std::unique_ptr<ros_adapters::SetUpFailureDiagnostics> setup_failure_;  // onInit failed: ERROR diagnostics
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::BundleAdjusterNodelet, nodelet::Nodelet)
