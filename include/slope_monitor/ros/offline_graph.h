// The processing graph of launch/replay.launch in one thread, fed with bag
// messages in bag-time order (process_bag, doc/process_bag.md): the same
// steps the nodelets run (ros/target_centroider_step.h, sequence_step.h,
// adjuster_step.h, radio_step.h, estimator_step.h, targetless_camera.h,
// offline_dense.h), each set up from the parameters replay.launch gives its
// node (config/defaults/<node>.yaml, then config/process_bag/<node>.yaml,
// then the options below), and what each step returns written to the output
// bag on the topic its nodelet publishes it on.
//
//   OfflineGraph graph(options, cameras, &output_bag, log);
//   if (options.uav_tie_points) graph.SetUpUavTiePoints(has_topic);
//   for (const rosbag::MessageInstance& m : view) graph.OnMessage(m);
//   graph.Finish();  // the epoch still open solved, the reports written
//
// Completion of an epoch is decided by the messages only (no time-outs), so
// the result does not depend on the CPU load. The set-up is
// offline_graph_setup.cpp, the message handling offline_graph.cpp.
#pragma once

#include <functional>
#include <future>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <rosbag/bag.h>
#include <rosbag/message_instance.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include "slope_monitor/ChangeAreaArray.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/adjuster_step.h"
#include "slope_monitor/ros/estimator_step.h"
#include "slope_monitor/ros/image_limits.h"
#include "slope_monitor/ros/offline_dense.h"
#include "slope_monitor/ros/radio_step.h"
#include "slope_monitor/ros/sequence_step.h"
#include "slope_monitor/ros/target_centroider_step.h"
#include "slope_monitor/ros/targetless_camera.h"
#include "slope_monitor/ros/uav_topics.h"

namespace slope_monitor {
namespace ros_adapters {

// What replay.launch's arguments give the nodes (process_bag's options).
struct OfflineGraphOptions {
  std::vector<std::string> bags;  // the first one's <stem>.truth.yaml: the radio's truth_file
  std::string site, site_config, target_list, radio_network, adjuster_config;
  bool uav_tie_points = false;
  // No target list (a site without targets): no target stage, each photo
  // gets an empty target list.
  bool no_targets = false;
  bool dense = true;     // the dense epoch step (replay.launch dense:=true)
  bool verbose = false;  // the bundle adjuster's INFO lines too
  std::string database, report_dir;
  std::string site_name;  // the site the history belongs to (ros/replay_defaults.h); "" = unchecked
  // Image messages above this many pixels, or whose header does not describe
  // their data, are skipped before conversion, named (ros/image_limits.h).
  ImageMessageLimits image_limits;
};

// The targets, as replay.launch finds them: the site file's when it lists
// them, else options->target_list, else <first bag>.targets.yaml (the
// simulator's). A site without targets and no such file: a site without
// targets (a UAV flight oriented by its tie points), no target stage
// (no_targets); its UAV cameras are tied by the sequence matcher
// (uav_tie_points set, said in `log`). Without a site a target list is
// required (InvalidArgument naming the file looked for).
void ResolveReplayTargets(OfflineGraphOptions* options,
                          const std::function<void(const std::string&)>& log);

// Cameras of a survey: every /<name>/camera/image_raw topic of the bags.
std::vector<std::string> BagCameras(rosbag::View& view);
bool BagHasTopic(rosbag::View& view, const std::string& topic);

class OfflineGraph {
 public:
  // Topics of the replay graph (launch/include/processing_graph.xml).
  static constexpr char kAdjusterDisplacements[] = "/bundle_adjuster/displacements";
  static constexpr char kRadioDisplacements[] = "/radio/radio_displacements";
  static constexpr char kTargetlessDisplacements[] = "/targetless_camera/displacements";

  // `cameras`: the bags' /<camera>/camera/image_raw names. `output`: the bag
  // the graph's outputs are written to, or null. `log`: a line for the user.
  // `history`: options.database already opened by the caller (its writer
  // lock held), taken over by the estimator; null: the estimator opens it.
  // ConfigError / InvalidArgument naming the node's key or file.
  OfflineGraph(const OfflineGraphOptions& options, const std::vector<std::string>& cameras,
               rosbag::Bag* output, std::function<void(const std::string&)> log,
               std::unique_ptr<deformation::History> history = nullptr);

  // --uav-tie-points: the graph's hex matcher (mode sequence) for every
  // camera of kind uav (the site file's, else io::DefaultCameras()'s `uav`)
  // on /<camera>/camera/image_raw and position_prior; its tie points go to
  // the collector as /<camera>/tie_points. has_topic: whether the bag has a
  // topic; with priors in the bag an image waits for its own, else every
  // image is matched when it comes.
  void SetUpUavTiePoints(const std::function<bool(const std::string&)>& has_topic);

  // The next message of the bags, in bag-time order.
  void OnMessage(const rosbag::MessageInstance& m);
  // End of the bags: an epoch still open is solved with what it has (the
  // live graph's time-out), then the reports are written.
  void Finish();

  int epochs_solved() const { return adjuster_->accepted() + static_cast<int>(radio_epochs()); }
  unsigned int radio_epochs() const { return radio_ ? radio_->epochs() : 0; }
  // Why no epoch was solved, in one line (epochs_solved() == 0).
  std::string WhyNothingSolved() const;
  bool has_points() const { return !estimator_->GetSnapshot().points.empty(); }
  const EstimatorStep& estimator() const { return *estimator_; }
  // The messages skipped (CheckedImage), one line each.
  const std::vector<std::string>& skipped() const { return skipped_; }

 private:
  // A camera with targets: its centroider step and the halves of its photos.
  struct Centroider {
    std::unique_ptr<TargetCentroiderStep> step;                    // the node's, shared
    std::map<ros::Time, sensor_msgs::Image::ConstPtr> images;      // waiting for their camera_info
    std::map<ros::Time, sensor_msgs::CameraInfo::ConstPtr> infos;  // waiting for their image
    // The latest centroided photo (its image kept: `mono` may share its pixels),
    // written as /<camera>/debug_image at the end of the input.
    sensor_msgs::Image::ConstPtr last_image;
    std::optional<CentroidedImage> last;
  };
  // The hex matcher (mode sequence) of a UAV camera.
  struct UavMatcher {
    std::unique_ptr<SequenceMatcherStep> step;  // parameters().camera: the UAV camera
    UavTopics topics;
  };
  // The photo being centroided on another thread (Pair, TakeCentroided).
  struct Centroiding {
    Centroider* c = nullptr;
    ros::Time bag_time;
    sensor_msgs::Image::ConstPtr image;
    std::future<CentroidedImage> result;
  };
  // Wall time per stage since the previous adjustment epoch [s] (LogStages).
  struct StageTimes {
    double targets = 0.0, matching = 0.0, dense = 0.0, estimator = 0.0;
    int pairs = 0, tie_points = 0;  // tie-point messages and their points
    double features_before = 0.0;   // FeatureSeconds() at the epoch's start
  };

  void Log(const std::string& line) const { log_(line); }

  // ---- set-up (offline_graph_setup.cpp): the parameters replay.launch gives every node.
  void SetUpCentroider(const std::string& cam);
  void SetUpAdjuster(const std::vector<std::string>& cameras);
  void SetUpRadio();
  void SetUpEstimator(std::unique_ptr<deformation::History> history);
  void SetUpTargetless();
  void SetUpDense();

  // ---- inputs (offline_graph.cpp).
  bool OnUavPrior(const rosbag::MessageInstance& m);
  void OnImageMessage(const std::string& topic, const sensor_msgs::Image::ConstPtr& image);
  void OnInfoMessage(const std::string& topic, const sensor_msgs::CameraInfo::ConstPtr& info);
  Centroider* CameraOf(const std::string& topic, const std::string& suffix);
  void OnTf(const tf2_msgs::TFMessage& tf, bool is_static);
  void OnCameraInfo(const std::string& cam, const sensor_msgs::CameraInfo& info);
  void Pair(Centroider* c, const ros::Time& stamp);
  void TakeCentroided();
  sensor_msgs::Image::ConstPtr CheckedImage(const rosbag::MessageInstance& m);
  void OnEpochEnd(const slope_monitor::EpochMarker& marker);
  void OnRadioBlock(const slope_monitor::RadioSampleBlock& block, const std::string& topic);
  bool OnTargetlessMessage(const rosbag::MessageInstance& m,
                           const sensor_msgs::Image::ConstPtr& image);
  void PublishTargetless(const TargetlessOutputs& out);
  bool IsPriorTopic(const std::string& topic) const;
  bool IsPicksTopic(const std::string& topic) const;

  // ---- the hex matcher (mode sequence), one per UAV camera.
  UavMatcher* UavMatcherOf(const std::string& topic, std::string UavTopics::*field);
  void OnUavImage(UavMatcher* uav, const sensor_msgs::Image::ConstPtr& image);
  std::optional<SequenceOutput> MatchUavPrior(
      UavMatcher* uav, const geometry_msgs::PoseWithCovarianceStamped& prior);
  void OnSequenceStep(const UavMatcher& uav, const SequenceOutput& out);
  double FeatureSeconds() const;

  // ---- the bundle adjuster's epochs.
  void Solve(const std::vector<SolvedEpoch>& epochs);
  void Solve(const SolvedEpoch& out);
  void LogStages(uint32_t epoch, const SolvedEpoch& out, double adjustment);
  void Publish(const SolvedEpoch& out);

  // ---- the deformation estimator (its inputs in one stamp order, no time-out).
  void Fuse(const slope_monitor::PointDisplacementArray& msg, const std::string& topic);
  void OnAreas(const slope_monitor::ChangeAreaArray& msg);
  void Publish(const EstimatorResult& result);
  void WriteReportFiles();

  template <typename M>
  void Write(const std::string& topic, const M& msg) {
    if (output_) output_->write(topic, now_, msg);
  }

  StageTimes stages_;
  std::optional<Centroiding> centroiding_;
  std::function<void(const std::string&)> log_;
  const OfflineGraphOptions options_;
  rosbag::Bag* output_;
  ros::Time now_;           // bag time of the message being processed
  CameraPoses poses_{1e6};  // the centroiders' (a bag's length of /tf)
  std::map<std::string, Centroider> centroiders_;
  std::unique_ptr<TargetlessCameras> targetless_;  // fixed_targetless cameras
  // bundle_adjuster
  std::unique_ptr<AdjusterStep> adjuster_;
  std::string last_failure_;          // the last epoch not accepted and why
  std::vector<std::string> skipped_;  // messages skipped, named (CheckedImage)
  std::optional<io::SiteFile> site_;  // --site
  // hex_matcher (mode sequence; --uav-tie-points): one per UAV camera
  std::vector<UavMatcher> uav_matchers_;
  std::unique_ptr<RadioStep> radio_;  // radio_phase_solver; null: not running
  // deformation_estimator
  std::unique_ptr<EstimatorStep> estimator_;
  std::unique_ptr<OfflineDense> dense_;  // dense_matcher
};

}  // namespace ros_adapters
}  // namespace slope_monitor
