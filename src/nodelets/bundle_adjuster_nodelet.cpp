// bundle_adjuster nodelet: collects the target observations (and tie points,
// camera infos, GNSS position priors) of a survey epoch, and when the epoch
// ends (EpochMarker end, a time gap, or the run_adjustment service) orients
// the images (resection / intersection), runs the collinearity bundle
// adjustment and publishes the solution, tf of every camera, the adjusted
// points with their sigma, and displacements of monitoring points against
// the reference epoch. All computing is in core/adjustment and core/geometry.
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/PointCloud2.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_ros/transform_broadcaster.h>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RunAdjustment.h"
#include "slope_monitor/SetReferenceEpoch.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/adjustment/initialization.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/setup.h"

namespace slope_monitor {

namespace {

struct CollectedImage {
  std::string camera;
  std::string frame_id;
  ros::Time stamp;
  std_msgs::Header header;
};

struct CollectedObservation {
  std::string image_key;
  std::string point_id;     // "" for an unidentified target (family in `family`)
  std::string family;
  adjustment::PointRole role = adjustment::PointRole::kTie;
  Eigen::Vector2d pixel;
  Eigen::Matrix2d covariance;
};

std::string ImageKey(const std::string& camera, const ros::Time& stamp) {
  return camera + "@" + std::to_string(stamp.sec) + "." + std::to_string(stamp.nsec);
}

uint8_t RoleToMsg(adjustment::PointRole r) {
  switch (r) {
    case adjustment::PointRole::kControl: return slope_monitor::PointEstimate::ROLE_CONTROL;
    case adjustment::PointRole::kMonitoring: return slope_monitor::PointEstimate::ROLE_MONITORING;
    case adjustment::PointRole::kCheck: return slope_monitor::PointEstimate::ROLE_CHECK;
    default: return slope_monitor::PointEstimate::ROLE_TIE;
  }
}

}  // namespace

class BundleAdjusterNodelet : public nodelet::Nodelet {
 public:
  void onInit() override {
    ros::NodeHandle& nh = getNodeHandle();
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    if (const auto error = ros_adapters::SetUpError([&] { ReadParameters(pnh); })) {
      NODELET_ERROR("bundle_adjuster: %s; not advertising anything", error->c_str());
      return;
    }
    solution_pub_ = nh.advertise<slope_monitor::AdjustmentSolution>("solution", 5, true);
    points_pub_ = nh.advertise<sensor_msgs::PointCloud2>("points", 5, true);
    displacements_pub_ = nh.advertise<slope_monitor::PointDisplacementArray>("displacements", 5, true);
    for (const std::string& topic : target_topics_)
      target_subs_.push_back(nh.subscribe(topic, 500, &BundleAdjusterNodelet::OnTargets, this));
    for (const std::string& cam : camera_names_) {
      info_subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
          cam + "/camera_info", 5, [this, cam](const sensor_msgs::CameraInfoConstPtr& m) { OnCameraInfo(cam, m); }));
    }
    // Large queues: a long solve holds the callbacks, and nothing may be lost.
    tie_sub_ = nh.subscribe("tie_points", 2000, &BundleAdjusterNodelet::OnTiePoints, this);
    prior_sub_ = nh.subscribe("position_prior", 500, &BundleAdjusterNodelet::OnPositionPrior, this);
    for (const std::string& topic : epoch_topics_)
      epoch_subs_.push_back(nh.subscribe(topic, 20, &BundleAdjusterNodelet::OnEpoch, this));
    run_srv_ = nh.advertiseService("run_adjustment", &BundleAdjusterNodelet::OnRun, this);
    reference_srv_ = nh.advertiseService("set_reference_epoch", &BundleAdjusterNodelet::OnSetReference, this);
    // Wall time: on a replay the clock stops with the bag, and the waits for
    // the last epoch's targets and tie points must still end.
    gap_timer_ = nh.createWallTimer(ros::WallDuration(1.0), &BundleAdjusterNodelet::OnTimer, this);
    updater_ = std::make_unique<diagnostic_updater::Updater>(nh, pnh);
    updater_->setHardwareID("bundle_adjuster");
    updater_->add("adjustment", this, &BundleAdjusterNodelet::Diagnose);
    NODELET_INFO("bundle_adjuster: %zu target topics, %zu cameras, %zu targets in '%s'", target_topics_.size(),
                 camera_names_.size(), targets_.targets().size(), target_list_path_.c_str());
  }

 private:
  void ReadParameters(ros::NodeHandle& pnh) {
    ros_adapters::ParamReader p(pnh);
    target_list_path_ = p.String("target_list", "");
    if (target_list_path_.empty()) throw ConfigError("parameter '" + p.FullKey("target_list") + "' is required");
    targets_ = io::TargetList::Load(target_list_path_);
    target_topics_ = p.StringList("target_topics", {"targets"});
    camera_names_ = p.StringList("cameras", {});
    epoch_topics_ = p.StringList("epoch_topics", {"epoch"});
    epoch_wait_ = p.Double("epoch_wait", 30.0, 0.0, 3600.0, "s");
    tie_point_cameras_ = p.StringList("tie_point_cameras", {});
    tie_point_wait_ = p.Double("tie_point_wait", 300.0, 0.0, 86400.0, "s");
    tie_pixel_sigma_floor_ = p.Double("tie_pixel_sigma_floor", 0.2, 0.0, 100.0, "px");
    min_tie_quality_ = p.Double("min_tie_quality", 0.25, 0.0, 1.0);
    frame_id_ = p.String("frame_id", "site");
    pixel_size_ = p.Double("pixel_size", 1.0, 1e-6, 1.0, "mm/px");
    default_pixel_sigma_ = p.Double("pixel_sigma", 0.3, 1e-4, 100.0, "px");
    pixel_sigma_floor_ = p.Double("pixel_sigma_floor", 0.05, 0.0, 100.0, "px");
    uav_pixel_sigma_floor_ = p.Double("uav_pixel_sigma_floor", 1.0, 0.0, 100.0, "px");
    epoch_gap_ = p.Double("epoch_gap", 600.0, 0.0, 1e7, "s");
    prior_max_dt_ = p.Double("position_prior_max_dt", 0.1, 0.0, 10.0, "s");
    gnss_sigma_floor_ = p.Double("position_prior_min_sigma", 0.01, 1e-4, 100.0, "m");
    min_images_ = p.Int("min_images", 2, 1, 10000);
    auto interior_list = [&p](const std::string& key) {
      std::vector<int> out;
      for (const std::string& name : p.StringList(key, {})) {
        int idx = -1;
        for (int i = 0; i < camera::kNumInterior; ++i)
          if (name == camera::InteriorNames()[i]) idx = i;
        if (idx < 0) throw ConfigError("parameter '" + p.FullKey(key) + "': unknown interior parameter '" + name + "'");
        out.push_back(idx);
      }
      return out;
    };
    free_interior_ = interior_list("free_interior");
    uav_free_interior_ = interior_list("uav_free_interior");
    options_.loss = p.String("loss", "huber", {"none", "huber", "cauchy"});
    options_.loss_scale = p.Double("loss_scale", 3.0, 1e-3, 1e3, "sigma");
    options_.outlier_threshold = p.Double("outlier_threshold", 5.0, 1e-3, 1e3, "sigma");
    options_.linear_solver = p.String("linear_solver", "auto", {"auto", "dense_schur", "sparse_schur", "iterative_schur"});
    options_.max_iterations = p.Int("max_iterations", 100, 1, 10000);
    options_.num_threads = p.Int("num_threads", 1, 1, 64);
    options_.minimizer_progress = p.Bool("minimizer_progress", false);
    options_.min_control_points = p.Int("min_control_points", 3, 0, 1000);
    options_.max_sigma0 = p.Double("max_sigma0", 5.0, 0.01, 1e6);
    options_.max_outlier_fraction = p.Double("max_outlier_fraction", 0.2, 0.0, 1.0);
    options_.min_observations_with_prior = p.Int("min_observations_with_prior", 3, 2, 1000);
    options_.min_variance_factor = p.Double("min_variance_factor", 1.0, 0.0, 100.0);
    options_.compute_datum_free_covariance = p.Bool("datum_free_displacements", true);
    options_.compute_covariance = true;
    options_.Check();
    epoch_options_.adjustment = options_;
    epoch_options_.free_interior = free_interior_;
    // A UAV camera self-calibrated in every flight: its own list (the fixed
    // cameras keep free_interior).
    if (!uav_free_interior_.empty())
      for (const std::string& c : camera_names_)
        if (!IsFixedCamera(c)) epoch_options_.free_interior_by_camera[c] = uav_free_interior_;
    epoch_options_.name_unidentified = p.Bool("name_unidentified", true);
    epoch_options_.orient_from_approximate = p.Bool("orient_from_approximate", true);
    epoch_options_.naming.gate_sigma = p.Double("naming_gate_sigma", 3.0, 0.1, 100.0, "sigma");
    epoch_options_.naming.gate_extra_px = p.Double("naming_gate_extra_px", 10.0, 0.0, 10000.0, "px");
    epoch_options_.naming.coarse_extra_px = p.Double("naming_coarse_extra_px", 100.0, 0.0, 10000.0, "px");
    epoch_options_.naming.ambiguity_factor = p.Double("naming_ambiguity_factor", 2.0, 1.0, 100.0);
    epoch_options_.Check();
    displacement_options_.stable_threshold = p.Double("stable_threshold", 0.02, 1e-6, 100.0, "m");
    displacement_options_.significance_threshold = p.Double("significance_threshold", 3.0, 0.1, 100.0);
    displacement_options_.estimate_scale = p.Bool("coregistration_scale", false);
    displacement_options_.Check();
    p.CheckNoUnknownKeys();
  }

  // ---------------------------------------------------------------- input
  void OnCameraInfo(const std::string& camera_name, const sensor_msgs::CameraInfoConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    try {
      models_[camera_name] = ros_adapters::CameraModelFromCameraInfo(*msg, pixel_size_);
    } catch (const Error& e) {
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: camera_info of '%s': %s", camera_name.c_str(), e.what());
    }
  }

  void OnTargets(const slope_monitor::TargetObservationArrayConstPtr& msg) {
    std::unique_lock<std::mutex> lock(mutex_);
    const std::string key = ImageKey(msg->camera_name, msg->header.stamp);
    CollectedImage& im = images_[key];
    im.camera = msg->camera_name;
    im.frame_id = msg->header.frame_id.empty() ? msg->camera_name + "_optical" : msg->header.frame_id;
    im.stamp = msg->header.stamp;
    im.header = msg->header;
    if (msg->epoch != 0 && !end_pending_) current_epoch_ = msg->epoch;
    // A UAV camera flies with its nominal interior (not calibrated on this
    // site, not self-calibrated from a few photos): its model error is far
    // above the centroid precision.
    const double floor = IsFixedCamera(msg->camera_name) ? pixel_sigma_floor_ : uav_pixel_sigma_floor_;
    for (const auto& o : msg->observations) {
      CollectedObservation c;
      c.image_key = key;
      c.family = o.family;
      if (o.id < 0) {  // unidentified (a circle the centroider could not name without a pose)
        ++unidentified_;
        c.pixel = Eigen::Vector2d(o.x, o.y);
        c.covariance = ros_adapters::FromRowMajor<2>(o.covariance);
        if (c.covariance.isZero()) c.covariance = Eigen::Matrix2d::Identity() * default_pixel_sigma_ * default_pixel_sigma_;
        c.covariance += Eigen::Matrix2d::Identity() * floor * floor;
        unidentified_observations_.push_back(c);
        continue;
      }
      c.point_id = o.family + "/" + std::to_string(o.id);
      const io::TargetSpec* spec = targets_.Find(o.family, o.id);
      c.role = spec == nullptr ? adjustment::PointRole::kTie
                               : (spec->role == io::TargetRole::kControl
                                      ? adjustment::PointRole::kControl
                                      : (spec->role == io::TargetRole::kCheck ? adjustment::PointRole::kCheck
                                                                              : adjustment::PointRole::kMonitoring));
      c.pixel = Eigen::Vector2d(o.x, o.y);
      c.covariance = ros_adapters::FromRowMajor<2>(o.covariance);
      if (c.covariance.isZero()) c.covariance = Eigen::Matrix2d::Identity() * default_pixel_sigma_ * default_pixel_sigma_;
      // The centroider's covariance is image noise only; calibration and model
      // errors of a real camera come on top (added in quadrature).
      c.covariance += Eigen::Matrix2d::Identity() * floor * floor;
      observations_.push_back(c);
    }
    last_input_ = ros::Time::now();
    if (!ReadyLocked(false)) return;
    lock.unlock();
    SolveEpoch();
  }

  void OnTiePoints(const slope_monitor::TiePointArrayConstPtr& msg) {
    std::unique_lock<std::mutex> lock(mutex_);
    const std::string kb = ImageKey(msg->camera_b, msg->header.stamp);
    const bool has_a = !msg->camera_a.empty();
    const std::string ka = has_a ? ImageKey(msg->camera_a, msg->header_a.stamp) : std::string();
    auto remember = [&](const std::string& key, const std::string& cam, const std_msgs::Header& header) {
      CollectedImage& im = images_[key];
      im.camera = cam;
      im.frame_id = header.frame_id.empty() ? cam + "_optical" : header.frame_id;
      im.stamp = header.stamp;
      im.header = header;
    };
    remember(kb, msg->camera_b, msg->header);
    if (has_a) remember(ka, msg->camera_a, msg->header_a);
    // A matcher in sequence mode says how many messages image b gets
    // (pairs_b): the epoch waits until they are all in (tie_point_cameras).
    if (msg->pairs_b > 0) {
      TieCount& count = tie_counts_[kb];
      ++count.received;
      count.expected = msg->pairs_b;
    }
    int used = 0, low = 0;
    for (const auto& t : msg->points) {
      if (t.id == 0 || !has_a) continue;  // a match without a track cannot tie more than this pair
      if (t.quality <= min_tie_quality_) {  // flagged by the matcher's quality control
        ++low;
        continue;
      }
      if (!(std::isfinite(t.xa) && std::isfinite(t.ya) && std::isfinite(t.xb) && std::isfinite(t.yb))) continue;
      const std::string id = "tie/" + std::to_string(t.id);
      // The matcher's covariance is that of xb given xa (image noise of the
      // correlation); xa carries the same. Model and calibration error come on top.
      Eigen::Matrix2d cov = ros_adapters::FromRowMajor<2>(t.covariance);
      if (cov.isZero() || !cov.allFinite())
        cov = Eigen::Matrix2d::Identity() * default_pixel_sigma_ * default_pixel_sigma_;
      cov += Eigen::Matrix2d::Identity() * tie_pixel_sigma_floor_ * tie_pixel_sigma_floor_;
      observations_.push_back({ka, id, "tie", adjustment::PointRole::kTie, Eigen::Vector2d(t.xa, t.ya), cov});
      observations_.push_back({kb, id, "tie", adjustment::PointRole::kTie, Eigen::Vector2d(t.xb, t.yb), cov});
      ++used;
    }
    tie_points_used_ += used;
    tie_points_low_quality_ += low;
    last_input_ = ros::Time::now();
    if (!ReadyLocked(false)) return;
    lock.unlock();
    SolveEpoch();
  }

  void OnPositionPrior(const geometry_msgs::PoseWithCovarianceStampedConstPtr& msg) {
    std::lock_guard<std::mutex> lock(mutex_);
    priors_.push_back(*msg);
  }

  void OnEpoch(const slope_monitor::EpochMarkerConstPtr& msg) {
    if (!msg->end) return;
    bool ready;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // The end of the NEXT epoch of a source while this one still waits (a
      // slow matcher on a fast replay): kept until this epoch is solved.
      auto ended = end_stamps_.find(msg->source);
      if (end_pending_ && ended != end_stamps_.end() && msg->header.stamp > ended->second) {
        deferred_ends_.push_back(*msg);
        return;
      }
      ApplyEndLocked(*msg);
      ready = ReadyLocked(false);
    }
    if (ready) SolveEpoch();
  }

  void ApplyEndLocked(const slope_monitor::EpochMarker& msg) {
    if (msg.epoch != 0) current_epoch_ = msg.epoch;
    ended_sources_.insert(msg.source);
    announced_images_[msg.source] = msg.count;
    end_stamps_[msg.source] = msg.header.stamp;
    ended_at_ = ros::WallTime::now();
    end_pending_ = true;
  }

  // Images of this epoch: those up to the latest end marker's stamp (the
  // next epoch's images may already be arriving); everything without markers.
  ros::Time CutoffLocked() const {
    ros::Time cutoff;
    for (const auto& [source, stamp] : end_stamps_) cutoff = std::max(cutoff, stamp);
    return cutoff;
  }
  bool InEpochLocked(const ros::Time& stamp) const {
    const ros::Time cutoff = CutoffLocked();
    return cutoff.isZero() || stamp <= cutoff;
  }

  // Every image of a camera in tie_point_cameras up to its end marker has all
  // the tie-point messages its matcher announced (TiePointArray.pairs_b).
  bool TiesCompleteLocked() const {
    // No matcher publishing (not started, or it failed on its parameters):
    // nothing to wait for.
    if (tie_point_cameras_.empty() || tie_sub_.getNumPublishers() == 0) return true;
    for (const std::string& c : tie_point_cameras_) {
      auto announced = announced_images_.find(c);
      auto end = end_stamps_.find(c);
      if (announced == announced_images_.end() || end == end_stamps_.end()) continue;
      uint32_t complete = 0;
      for (const auto& [key, count] : tie_counts_) {
        auto im = images_.find(key);
        if (im == images_.end() || im->second.camera != c || im->second.stamp > end->second) continue;
        if (count.received >= count.expected) ++complete;
      }
      if (complete < announced->second) return false;
    }
    return true;
  }

  // Every configured camera (or, with none configured, any source) has ended
  // its epoch and every image it announced has delivered its targets (or the
  // wait is over when `timed_out`).
  bool ReadyLocked(bool timed_out) const {
    if (!end_pending_) return false;
    if (camera_names_.empty()) return true;
    for (const std::string& c : camera_names_) {
      if (!ended_sources_.count(c)) return false;
    }
    const double waited = (ros::WallTime::now() - ended_at_).toSec();
    const bool ties = TiesCompleteLocked();
    if (!ties && waited <= std::max(epoch_wait_, tie_point_wait_)) return false;
    if (timed_out) return true;
    for (const auto& [source, count] : announced_images_) {
      auto end = end_stamps_.find(source);
      uint32_t have = 0;
      for (const auto& [key, im] : images_)
        have += im.camera == source && (end == end_stamps_.end() || im.stamp <= end->second) ? 1 : 0;
      if (have < count) return false;
    }
    return true;
  }

  void OnTimer(const ros::WallTimerEvent&) {
    bool gap;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // The gap ends epochs of sources without epoch markers; once a marker has
      // announced the epoch's end, wait for its images instead (on a fast
      // replay, a slow centroider's latency is a long gap in bag time).
      gap = epoch_gap_ > 0.0 && !end_pending_ && !observations_.empty() && !last_input_.isZero() &&
            (ros::Time::now() - last_input_).toSec() > epoch_gap_;
      gap = gap || (end_pending_ && (ros::WallTime::now() - ended_at_).toSec() > epoch_wait_ && ReadyLocked(true));
      // A deferred end marker (the next epoch) may have completed it already.
      gap = gap || ReadyLocked(false);
    }
    if (gap) SolveEpoch();
    if (updater_) updater_->update();
  }

  bool OnRun(slope_monitor::RunAdjustment::Request& req, slope_monitor::RunAdjustment::Response& res) {
    if (req.epoch != 0 && req.epoch != current_epoch_) {
      res.success = false;
      res.message = "only the epoch being collected (" + std::to_string(current_epoch_) + ") can be solved";
      return true;
    }
    res.solution = SolveEpoch();
    res.success = res.solution.usable;
    res.message = res.solution.message;
    return true;
  }

  bool OnSetReference(slope_monitor::SetReferenceEpoch::Request& req, slope_monitor::SetReferenceEpoch::Response& res) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (epochs_.empty()) {
      res.success = false;
      res.message = "no accepted epoch yet";
      return true;
    }
    const int wanted = req.use_latest ? epochs_.rbegin()->first : static_cast<int>(req.epoch);
    if (!epochs_.count(wanted)) {
      res.success = false;
      res.message = "epoch " + std::to_string(wanted) + " has no accepted solution";
      return true;
    }
    reference_epoch_ = wanted;
    res.success = true;
    res.reference_epoch = wanted;
    res.message = "reference epoch set to " + std::to_string(wanted);
    return true;
  }

  // ---------------------------------------------------------------- solve
  slope_monitor::AdjustmentSolution SolveEpoch() {
    std::lock_guard<std::mutex> lock(mutex_);
    slope_monitor::AdjustmentSolution out;
    out.header.frame_id = frame_id_;
    out.epoch = current_epoch_;
    out.usable = false;
    if (end_pending_ && !TiesCompleteLocked())
      NODELET_WARN("bundle_adjuster: epoch %u: solving without every photo's tie points (waited %.0f s; "
                   "tie_point_wait %.0f s)", current_epoch_, (ros::WallTime::now() - ended_at_).toSec(), tie_point_wait_);
    // This epoch's part of what was collected; later images (the next
    // epoch, arriving while a slow matcher finished this one) stay.
    std::map<std::string, CollectedImage> images;
    std::vector<CollectedObservation> observations, unidentified;
    std::vector<geometry_msgs::PoseWithCovarianceStamped> priors;
    {
      std::map<std::string, CollectedImage> later_images;
      for (auto& [key, im] : images_) (InEpochLocked(im.stamp) ? images : later_images)[key] = im;
      std::vector<CollectedObservation> later_obs, later_unidentified;
      for (auto& o : observations_) (images.count(o.image_key) ? observations : later_obs).push_back(o);
      for (auto& o : unidentified_observations_)
        (images.count(o.image_key) ? unidentified : later_unidentified).push_back(o);
      std::vector<geometry_msgs::PoseWithCovarianceStamped> later_priors;
      for (auto& p : priors_) (InEpochLocked(p.header.stamp) ? priors : later_priors).push_back(p);
      std::map<std::string, TieCount> later_ties;
      for (auto& [key, count] : tie_counts_)
        if (!images.count(key)) later_ties[key] = count;
      images_.swap(later_images);
      observations_.swap(later_obs);
      unidentified_observations_.swap(later_unidentified);
      priors_.swap(later_priors);
      tie_counts_.swap(later_ties);
    }
    ended_sources_.clear();
    announced_images_.clear();
    end_stamps_.clear();
    end_pending_ = false;
    last_input_ = observations_.empty() ? ros::Time() : ros::Time::now();
    // End markers of the next epoch that came while this one waited.
    std::vector<slope_monitor::EpochMarker> deferred;
    deferred.swap(deferred_ends_);
    for (const auto& m : deferred) ApplyEndLocked(m);
    if (observations.empty()) {
      out.message = "no observations collected";
      last_message_ = out.message;
      return out;
    }
    try {
      adjustment::Scene scene;
      std::map<std::string, int> camera_index, image_index, point_index;
      std::vector<std::string> skipped;
      for (const auto& [key, im] : images) {
        auto model = models_.find(im.camera);
        if (model == models_.end()) {
          skipped.push_back(im.camera);
          continue;
        }
        if (!camera_index.count(im.camera)) {
          camera_index[im.camera] = static_cast<int>(scene.cameras.size());
          adjustment::Camera c;
          c.name = im.camera;
          c.model = calibrated_.count(im.camera) ? calibrated_.at(im.camera) : model->second;
          scene.cameras.push_back(c);
        }
        adjustment::Image image;
        image.name = key;
        image.camera = camera_index[im.camera];
        image.stamp = im.stamp.toSec();
        auto last = last_pose_.find(im.camera);
        image.exterior_known = last != last_pose_.end() && epoch_gap_ >= 0.0 && IsFixedCamera(im.camera);
        if (image.exterior_known) image.exterior = last->second;
        for (const auto& prior : priors) {
          if (std::abs((prior.header.stamp - im.stamp).toSec()) > prior_max_dt_) continue;
          image.position_prior = Eigen::Vector3d(prior.pose.pose.position.x, prior.pose.pose.position.y,
                                                 prior.pose.pose.position.z);
          Eigen::Matrix3d c;
          for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) c(r, k) = prior.pose.covariance[6 * r + k];
          const double floor = gnss_sigma_floor_ * gnss_sigma_floor_;
          for (int r = 0; r < 3; ++r) c(r, r) = std::max(c(r, r), floor);
          image.position_prior_covariance = c;
        }
        image_index[key] = static_cast<int>(scene.images.size());
        scene.images.push_back(image);
      }
      if (static_cast<int>(scene.images.size()) < min_images_) {
        throw InvalidArgument(Message("only ", scene.images.size(), " images with camera_info (min_images = ",
                                      min_images_, ")", skipped.empty() ? "" : "; no camera_info for " + skipped[0]));
      }
      for (const CollectedObservation& c : observations) {
        auto ii = image_index.find(c.image_key);
        if (ii == image_index.end()) continue;
        if (!point_index.count(c.point_id)) {
          point_index[c.point_id] = static_cast<int>(scene.points.size());
          adjustment::ObjectPoint p;
          p.id = c.point_id;
          p.role = c.role;
          p.position_known = false;
          const size_t slash = c.point_id.find('/');
          const io::TargetSpec* spec =
              slash == std::string::npos || c.point_id.compare(0, 4, "tie/") == 0
                  ? nullptr
                  : targets_.Find(c.point_id.substr(0, slash), std::stoi(c.point_id.substr(slash + 1)));
          if (spec != nullptr && spec->position &&
              (spec->role == io::TargetRole::kControl || spec->role == io::TargetRole::kCheck)) {
            p.surveyed = *spec->position;
            p.surveyed_covariance = Eigen::Vector3d(spec->sigma(0) * spec->sigma(0), spec->sigma(0) * spec->sigma(0),
                                                    spec->sigma(1) * spec->sigma(1)).asDiagonal();
            if (spec->role == io::TargetRole::kCheck) {
              p.position = *spec->position;
              p.position_known = true;
            }
          }
          // A monitoring target's listed position is approximate (hand-held
          // GNSS): it may orient a UAV photo, never constrain the adjustment.
          if (spec != nullptr && spec->position && spec->role == io::TargetRole::kMonitoring)
            p.approximate = *spec->position;
          scene.points.push_back(p);
        }
        adjustment::Observation o;
        o.image = ii->second;
        o.point = point_index[c.point_id];
        o.pixel = c.pixel;
        o.covariance = c.covariance;
        scene.observations.push_back(o);
      }
      // Check points must not help orient the images: start them unknown too.
      for (auto& p : scene.points)
        if (p.role == adjustment::PointRole::kCheck) p.position_known = false;
      // Unidentified targets (circles in UAV photos) and the listed targets
      // that may name them.
      std::vector<adjustment::UnidentifiedObservation> unknown;
      for (const CollectedObservation& c : unidentified) {
        auto ii = image_index.find(c.image_key);
        if (ii == image_index.end()) continue;
        unknown.push_back({ii->second, c.family, c.pixel, c.covariance});
      }
      const adjustment::EpochAdjustmentResult result =
          adjustment::AdjustEpoch(scene, unknown, ListedTargets(), epoch_options_);
      if (!result.initialization.empty())
        NODELET_WARN_THROTTLE(10.0, "bundle_adjuster: initialisation: %s", result.initialization.c_str());
      if (!result.pruned.dropped_images.empty() || !result.pruned.dropped_cameras.empty())
        NODELET_WARN_THROTTLE(10.0, "bundle_adjuster: epoch %u: %s", out.epoch, result.pruned.Summary().c_str());
      for (const std::string& r : result.rejected_names)
        NODELET_WARN("bundle_adjuster: epoch %u: target name given by projection rejected: %s", out.epoch, r.c_str());
      for (size_t i = 0; i < result.naming.notes.size() && i < 5; ++i)
        NODELET_DEBUG("bundle_adjuster: epoch %u: %s", out.epoch, result.naming.notes[i].c_str());
      last_photos_ = result.photos;
      last_naming_ = result.naming;
      last_rejected_names_ = static_cast<int>(result.rejected_names.size());
      if (result.photos.total > 0 || !unknown.empty())
        NODELET_INFO("bundle_adjuster: epoch %u: %s; %s; %d oriented from approximate target coordinates; %zu names "
                     "rejected by the residual test",
                     out.epoch, result.photos.Brief().c_str(), result.naming.Brief().c_str(),
                     result.oriented_from_approximate, result.rejected_names.size());
      adjustment::Scene usable_scene = result.scene;
      const adjustment::Summary& s = result.summary;
      Fill(usable_scene, s, images, &out);
      last_message_ = s.reason;
      last_usable_ = s.IsSolutionUsable();
      if (!s.IsSolutionUsable()) {
        NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: epoch %u not usable: %s (previous solution kept)", out.epoch,
                               s.reason.c_str());
        solution_pub_.publish(out);
        return out;
      }
      // Accepted: remember poses and calibration, publish everything.
      for (const auto& im : usable_scene.images) last_pose_[usable_scene.cameras[im.camera].name] = im.exterior;
      for (const auto& c : usable_scene.cameras) calibrated_[c.name] = c.model;
      const adjustment::EpochPoints ep =
          adjustment::EpochPointsFromSolution(usable_scene, s, static_cast<int>(out.epoch), out.header.stamp.toSec(),
                                              options_.compute_datum_free_covariance);
      epochs_[static_cast<int>(out.epoch)] = ep;
      if (reference_epoch_ < 0) reference_epoch_ = static_cast<int>(out.epoch);
      solution_pub_.publish(out);
      PublishTf(usable_scene, images, out.header.stamp);
      PublishPoints(usable_scene, s, out.header);
      PublishDisplacements(ep, out.header);
      ++accepted_;
      NODELET_INFO("bundle_adjuster: epoch %u accepted: %zu images, %zu points, %d observations, sigma0 %.2f, rms %.3f px",
                   out.epoch, usable_scene.images.size(), usable_scene.points.size(), s.num_observations, s.sigma0,
                   s.rms_residual_px);
    } catch (const std::exception& e) {
      out.usable = false;
      out.message = std::string("adjustment failed: ") + e.what();
      last_message_ = out.message;
      last_usable_ = false;
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: %s (previous solution kept)", out.message.c_str());
      solution_pub_.publish(out);
    }
    return out;
  }

  bool IsFixedCamera(const std::string& name) const { return name.find("uav") == std::string::npos; }

  // Every listed target with coordinates: the survey of control / check
  // points, the approximate position of monitoring targets (its sigma from
  // the list), for naming unidentified targets by projection.
  std::vector<adjustment::ListedTarget> ListedTargets() const {
    std::vector<adjustment::ListedTarget> out;
    for (const io::TargetSpec& t : targets_.targets()) {
      if (!t.position) continue;
      adjustment::ListedTarget l;
      l.id = t.Key();
      l.family = t.family;
      l.role = t.role == io::TargetRole::kControl
                   ? adjustment::PointRole::kControl
                   : (t.role == io::TargetRole::kCheck ? adjustment::PointRole::kCheck : adjustment::PointRole::kMonitoring);
      l.position = *t.position;
      l.position_sigma = std::max({t.sigma(0), t.sigma(1), 1e-3});
      if (t.role != io::TargetRole::kMonitoring) {
        l.surveyed = *t.position;
        l.surveyed_covariance =
            Eigen::Vector3d(t.sigma(0) * t.sigma(0), t.sigma(0) * t.sigma(0), t.sigma(1) * t.sigma(1)).asDiagonal();
      }
      out.push_back(l);
    }
    return out;
  }

  void Fill(const adjustment::Scene& scene, const adjustment::Summary& s,
            const std::map<std::string, CollectedImage>& images, slope_monitor::AdjustmentSolution* out) {
    out->usable = s.IsSolutionUsable();
    out->message = s.reason;
    out->sigma0 = s.sigma0;
    out->rms_residual_px = s.rms_residual_px;
    out->initial_cost = s.initial_cost;
    out->final_cost = s.final_cost;
    out->iterations = static_cast<uint32_t>(std::max(0, s.iterations));
    out->num_observations = static_cast<uint32_t>(s.num_observations);
    out->num_outliers = static_cast<uint32_t>(s.num_outliers);
    out->solve_time = s.solve_time;
    ros::Time latest;
    for (const auto& [k, im] : images) latest = std::max(latest, im.stamp);
    out->header.stamp = latest;
    if (!s.IsSolutionUsable()) return;
    std::vector<int> obs_per_image(scene.images.size(), 0), obs_per_point(scene.points.size(), 0);
    for (const auto& o : scene.observations) {
      ++obs_per_image[o.image];
      ++obs_per_point[o.point];
    }
    for (size_t i = 0; i < scene.images.size(); ++i) {
      const adjustment::Image& im = scene.images[i];
      const adjustment::Camera& cam = scene.cameras[im.camera];
      slope_monitor::CameraEstimate c;
      c.camera_name = cam.name;
      auto it = images.find(im.name);
      if (it != images.end()) c.image_header = it->second.header;
      c.site_from_optical = ros_adapters::ToPose(im.exterior.SiteFromOptical());
      for (int r = 0; r < 6; ++r)
        for (int k = 0; k < 6; ++k) c.pose_covariance[6 * r + k] = s.precision.exterior_covariance[i](r, k);
      c.theta = im.exterior.angles.theta;
      c.phi = im.exterior.angles.phi;
      c.kappa = im.exterior.angles.kappa;
      const auto& in = cam.model.interior();
      c.principal_distance = in[camera::kC];
      c.x0 = in[camera::kX0];
      c.y0 = in[camera::kY0];
      c.distortion.assign(in.begin() + camera::kK1, in.end());
      const auto& sig = s.precision.interior_sigma[im.camera];
      c.interior_sigma.assign(sig.begin(), sig.end());
      c.num_observations = static_cast<uint32_t>(obs_per_image[i]);
      c.rms_residual_px = s.image_rms_px[i];
      out->cameras.push_back(c);
    }
    for (size_t j = 0; j < scene.points.size(); ++j) {
      slope_monitor::PointEstimate p;
      p.id = scene.points[j].id;
      p.role = RoleToMsg(scene.points[j].role);
      p.position.x = scene.points[j].position.x();
      p.position.y = scene.points[j].position.y();
      p.position.z = scene.points[j].position.z();
      const auto cov = ros_adapters::ToRowMajor<3>(Eigen::Matrix3d(s.precision.point_covariance[j]));
      std::copy(cov.begin(), cov.end(), p.covariance.begin());
      p.num_observations = static_cast<uint32_t>(obs_per_point[j]);
      out->points.push_back(p);
    }
  }

  void PublishTf(const adjustment::Scene& scene, const std::map<std::string, CollectedImage>& images,
                 const ros::Time& stamp) {
    std::vector<geometry_msgs::TransformStamped> tfs;
    std::set<std::string> done;
    // The latest image of each camera defines its frame.
    for (auto it = scene.images.rbegin(); it != scene.images.rend(); ++it) {
      auto ci = images.find(it->name);
      const std::string frame = ci != images.end() ? ci->second.frame_id : scene.cameras[it->camera].name + "_optical";
      if (!done.insert(frame).second) continue;
      geometry_msgs::TransformStamped t;
      t.header.stamp = stamp;
      t.header.frame_id = frame_id_;
      t.child_frame_id = frame;
      t.transform = ros_adapters::ToTransform(it->exterior.SiteFromOptical());
      tfs.push_back(t);
    }
    tf_broadcaster_.sendTransform(tfs);
  }

  void PublishPoints(const adjustment::Scene& scene, const adjustment::Summary& s, const std_msgs::Header& header) {
    sensor_msgs::PointCloud2 cloud;
    cloud.header = header;
    sensor_msgs::PointCloud2Modifier mod(cloud);
    mod.setPointCloud2Fields(6, "x", 1, sensor_msgs::PointField::FLOAT32, "y", 1, sensor_msgs::PointField::FLOAT32,
                             "z", 1, sensor_msgs::PointField::FLOAT32, "sigma_x", 1, sensor_msgs::PointField::FLOAT32,
                             "sigma_y", 1, sensor_msgs::PointField::FLOAT32, "sigma_z", 1,
                             sensor_msgs::PointField::FLOAT32);
    mod.resize(scene.points.size());
    sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z"), sx(cloud, "sigma_x"),
        sy(cloud, "sigma_y"), sz(cloud, "sigma_z");
    for (size_t j = 0; j < scene.points.size(); ++j, ++x, ++y, ++z, ++sx, ++sy, ++sz) {
      const Eigen::Matrix3d& c = s.precision.point_covariance[j];
      *x = static_cast<float>(scene.points[j].position.x());
      *y = static_cast<float>(scene.points[j].position.y());
      *z = static_cast<float>(scene.points[j].position.z());
      *sx = static_cast<float>(std::sqrt(std::max(0.0, c(0, 0))));
      *sy = static_cast<float>(std::sqrt(std::max(0.0, c(1, 1))));
      *sz = static_cast<float>(std::sqrt(std::max(0.0, c(2, 2))));
    }
    points_pub_.publish(cloud);
  }

  void PublishDisplacements(const adjustment::EpochPoints& current, const std_msgs::Header& header) {
    auto ref = epochs_.find(reference_epoch_);
    if (ref == epochs_.end() || ref->first == current.epoch) return;
    const adjustment::EpochComparison cmp = adjustment::CompareEpochs(ref->second, current, displacement_options_);
    if (!cmp.success) {
      NODELET_ERROR_THROTTLE(10.0, "bundle_adjuster: %s", cmp.message.c_str());
      return;
    }
    slope_monitor::PointDisplacementArray msg;
    msg.header = header;
    msg.epoch = static_cast<uint32_t>(current.epoch);
    for (const adjustment::Displacement& d : cmp.displacements) {
      slope_monitor::PointDisplacement p = ros_adapters::MakePointDisplacement(
          d.id, slope_monitor::PointDisplacement::SOURCE_TARGET, getName(), ref->second.stamp, header.stamp,
          d.reference_position, d.displacement, d.covariance);
      p.significance = d.significance;
      msg.displacements.push_back(p);
    }
    NODELET_INFO("bundle_adjuster: epoch %d vs reference %d: %zu monitoring displacements", current.epoch, ref->first,
                 msg.displacements.size());
    displacements_pub_.publish(msg);
  }

  void Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (last_message_.empty()) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "waiting for an epoch");
    } else if (last_usable_) {
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, last_message_);
    } else {
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "last epoch not usable: " + last_message_);
    }
    stat.add("collected observations", observations_.size());
    stat.add("collected images", images_.size());
    stat.add("accepted epochs", accepted_);
    stat.add("unidentified observations received", unidentified_);
    stat.add("UAV photos last epoch", last_photos_.total);
    stat.add("UAV photos kept", last_photos_.kept);
    stat.add("UAV photos dropped: not oriented", last_photos_.not_oriented);
    stat.add("UAV photos dropped: too few observations", last_photos_.too_few_observations);
    stat.add("targets named by projection", last_naming_.named);
    stat.add("targets left unnamed: ambiguous", last_naming_.ambiguous);
    stat.add("targets left unnamed: no listed target near", last_naming_.unmatched);
    stat.add("targets left unnamed: image not oriented", last_naming_.not_oriented);
    stat.add("names rejected by the residual test", last_rejected_names_);
    stat.add("tie-point observation pairs used", tie_points_used_);
    stat.add("tie points skipped: low quality", tie_points_low_quality_);
    stat.add("reference epoch", reference_epoch_);
  }

  // Parameters.
  std::string target_list_path_;
  io::TargetList targets_;
  std::vector<std::string> target_topics_, camera_names_;
  std::string frame_id_;
  uint64_t unidentified_ = 0;
  double pixel_size_ = 1.0, default_pixel_sigma_ = 0.3, pixel_sigma_floor_ = 0.05, uav_pixel_sigma_floor_ = 1.0, epoch_gap_ = 600.0, prior_max_dt_ = 0.1,
         gnss_sigma_floor_ = 0.01;
  int min_images_ = 2;
  std::vector<int> free_interior_, uav_free_interior_;
  adjustment::Options options_;
  adjustment::EpochAdjustmentOptions epoch_options_;
  adjustment::DisplacementOptions displacement_options_;

  // State.
  std::mutex mutex_;
  std::map<std::string, camera::CameraModel> models_, calibrated_;
  std::map<std::string, camera::ExteriorOrientation> last_pose_;
  std::map<std::string, CollectedImage> images_;
  std::vector<CollectedObservation> observations_, unidentified_observations_;
  adjustment::PhotoStats last_photos_;
  adjustment::NamingReport last_naming_;
  int last_rejected_names_ = 0;
  std::vector<geometry_msgs::PoseWithCovarianceStamped> priors_;
  std::set<std::string> ended_sources_;
  // Images each source announced in its epoch-end marker (EpochMarker.count),
  // and the wall time the last marker came: the epoch is solved once every
  // announced image's targets have arrived (the centroider lags the marker),
  // or epoch_wait seconds after the marker at the latest.
  std::map<std::string, uint32_t> announced_images_;
  ros::WallTime ended_at_;
  bool end_pending_ = false;
  // Stamp of each source's end marker: the epoch's images are those up to it.
  std::map<std::string, ros::Time> end_stamps_;
  std::vector<slope_monitor::EpochMarker> deferred_ends_;
  // Tie-point messages received / announced (pairs_b) per image b.
  struct TieCount {
    uint32_t received = 0, expected = 0;
  };
  std::map<std::string, TieCount> tie_counts_;
  std::vector<std::string> tie_point_cameras_;
  double tie_point_wait_ = 300.0, tie_pixel_sigma_floor_ = 0.2, min_tie_quality_ = 0.25;
  uint64_t tie_points_used_ = 0, tie_points_low_quality_ = 0;
  std::vector<std::string> epoch_topics_;
  double epoch_wait_ = 30.0;
  ros::Time last_input_;
  uint32_t current_epoch_ = 0;
  std::map<int, adjustment::EpochPoints> epochs_;
  int reference_epoch_ = -1;
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
  std::unique_ptr<diagnostic_updater::Updater> updater_;
};

}  // namespace slope_monitor

PLUGINLIB_EXPORT_CLASS(slope_monitor::BundleAdjusterNodelet, nodelet::Nodelet)
