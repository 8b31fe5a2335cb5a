// The offline graph's message handling (ros/offline_graph.h): each bag
// message to the steps that take it, in bag order, and what they return
// written as the nodelets publish it.
#include "slope_monitor/ros/offline_graph.h"

#include <chrono>
#include <cstdio>
#include <set>

#include <diagnostic_msgs/DiagnosticArray.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/peak_memory.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/change_area_conversions.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/sequence_conversions.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

// f() with its wall time added to *seconds; returns what f returns.
template <typename F>
auto WallTimed(double* seconds, F&& f) {
  struct Add {
    double* seconds;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    ~Add() {
      *seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
  } add{seconds};
  return f();
}

// Message types the graph takes input from (OnMessage's branches).
bool GraphInputType(const std::string& type) {
  static const std::set<std::string> types = {
      ros::message_traits::datatype<tf2_msgs::TFMessage>(),
      ros::message_traits::datatype<sensor_msgs::Image>(),
      ros::message_traits::datatype<sensor_msgs::CameraInfo>(),
      ros::message_traits::datatype<slope_monitor::EpochMarker>(),
      ros::message_traits::datatype<geometry_msgs::PoseWithCovarianceStamped>(),
      ros::message_traits::datatype<slope_monitor::RadioSampleBlock>(),
      ros::message_traits::datatype<slope_monitor::TargetObservationArray>()};
  return types.count(type) > 0;
}

}  // namespace

// ------------------------------------------------------------------ inputs

void OfflineGraph::OnMessage(const rosbag::MessageInstance& m) {
  if (OnUavPrior(m)) return;
  // A message the graph takes no input from (e.g. /uav/gnss/fix) leaves a
  // photo being centroided running.
  if (!GraphInputType(m.getDataType())) return;
  // An image is read once, and only when its record and its header are
  // within the pixel budget; else it is skipped, named.
  sensor_msgs::Image::ConstPtr image;
  if (m.getDataType() == ros::message_traits::datatype<sensor_msgs::Image>()) {
    image = CheckedImage(m);
    if (!image) return;
  }
  TakeCentroided();
  now_ = m.getTime();
  const std::string& topic = m.getTopic();
  if (topic == "/tf" || topic == "/tf_static") {
    if (const auto tf = m.instantiate<tf2_msgs::TFMessage>()) OnTf(*tf, topic == "/tf_static");
  } else if (OnTargetlessMessage(m, image)) {
  } else if (image) {
    OnImageMessage(topic, image);
  } else if (const auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
    OnInfoMessage(topic, info);
  } else if (const auto marker = m.instantiate<slope_monitor::EpochMarker>()) {
    if (marker->end) OnEpochEnd(*marker);
  } else if (const auto prior = m.instantiate<geometry_msgs::PoseWithCovarianceStamped>()) {
    if (IsPriorTopic(topic)) adjuster_->AddPrior(*prior);
  } else if (const auto block = m.instantiate<slope_monitor::RadioSampleBlock>()) {
    OnRadioBlock(*block, topic);
  } else if (const auto picks = m.instantiate<slope_monitor::TargetObservationArray>()) {
    // Points picked in a photo (camera_capture with a site's gcp list).
    if (IsPicksTopic(topic)) Solve(adjuster_->AddTargets(*picks, now_.toSec()));
  }
}

// A UAV matcher's position prior: the sequence matcher's work for it
// (features and pairs of the photo that waited for it) runs while the
// photo's targets are still being centroided (Pair); both are taken in bag
// order after. False for any other message.
bool OfflineGraph::OnUavPrior(const rosbag::MessageInstance& m) {
  UavMatcher* uav = UavMatcherOf(m.getTopic(), &UavTopics::prior);
  if (!uav) return false;
  const auto prior = m.instantiate<geometry_msgs::PoseWithCovarianceStamped>();
  if (!prior) return false;
  const std::optional<SequenceOutput> step = MatchUavPrior(uav, *prior);
  TakeCentroided();
  now_ = m.getTime();
  adjuster_->AddPrior(*prior);
  if (step) OnSequenceStep(*uav, *step);
  return true;
}

// An image (checked) of a UAV camera (its matcher) or of a camera with targets.
void OfflineGraph::OnImageMessage(const std::string& topic,
                                  const sensor_msgs::Image::ConstPtr& image) {
  if (UavMatcher* uav = UavMatcherOf(topic, &UavTopics::image)) OnUavImage(uav, image);
  if (Centroider* c = CameraOf(topic, "/camera/image_raw")) {
    c->images[image->header.stamp] = image;
    if (dense_)
      WallTimed(&stages_.dense, [&] { dense_->OnImage(c->step->camera(), *image, now_.toSec()); });
    Pair(c, image->header.stamp);
  }
}

// The camera_info of a camera with targets.
void OfflineGraph::OnInfoMessage(const std::string& topic,
                                 const sensor_msgs::CameraInfo::ConstPtr& info) {
  if (Centroider* c = CameraOf(topic, "/camera/camera_info")) {
    OnCameraInfo(c->step->camera(), *info);
    if (dense_) dense_->OnCameraInfo(c->step->camera(), *info);
    c->infos[info->header.stamp] = info;
    Pair(c, info->header.stamp);
  }
}

OfflineGraph::Centroider* OfflineGraph::CameraOf(const std::string& topic,
                                                 const std::string& suffix) {
  if (topic.size() <= suffix.size() + 1) return nullptr;
  const std::string cam = topic.substr(1, topic.size() - suffix.size() - 1);
  const auto it = centroiders_.find(cam);
  return it != centroiders_.end() && "/" + cam + suffix == topic ? &it->second : nullptr;
}

void OfflineGraph::OnTf(const tf2_msgs::TFMessage& tf, bool is_static) {
  std::vector<std::string> problems;
  poses_.Add(tf, is_static, &problems);
  for (const std::string& line : problems) Log("target_centroider: " + line);
  Write(is_static ? "/tf_static" : "/tf", tf);
}

void OfflineGraph::OnCameraInfo(const std::string& cam, const sensor_msgs::CameraInfo& info) {
  if (const auto error = adjuster_->OnCameraInfo(cam, info))
    Log("bundle_adjuster: camera_info of '" + cam + "': " + *error);
}

// The image of `m`, or null when its record is larger than an image within
// the limits can be (not read) or its header claims more pixels than the
// limit or does not describe its data; a skipped message is named with its
// topic and bag time (skipped()).
sensor_msgs::Image::ConstPtr OfflineGraph::CheckedImage(const rosbag::MessageInstance& m) {
  const ImageMessageLimits& limits = options_.image_limits;
  std::string why;
  sensor_msgs::Image::ConstPtr image;
  if (m.size() > MaxImageMessageBytes(limits)) {
    why = Message("a record of ", m.size(), " bytes, more than an image of max_megapixels ",
                  limits.max_megapixels, " can hold (", MaxImageMessageBytes(limits),
                  " bytes); not read");
  } else {
    image = m.instantiate<sensor_msgs::Image>();
    try {
      if (image) CheckImageMessage(*image, limits);
    } catch (const InvalidArgument& e) {
      why = e.what();
      image.reset();
    }
  }
  if (image) return image;
  char at[32];
  std::snprintf(at, sizeof at, "%.3f", m.getTime().toSec());
  skipped_.push_back(Message("image message on ", m.getTopic(), " at ", at, " s: ", why));
  Log("skipped " + skipped_.back());
  return nullptr;
}

// ------------------------------------------------------ target centroiders

// An image and its camera_info (same stamp, in either order) are both in:
// its targets are centroided on another thread (the photo and its pose are
// the task's own) and taken (written, given to the collector) by
// TakeCentroided before the next message's effects, i.e. in bag order.
void OfflineGraph::Pair(Centroider* c, const ros::Time& stamp) {
  TakeCentroided();
  const auto image = c->images.find(stamp);
  const auto info = c->infos.find(stamp);
  if (image == c->images.end() || info == c->infos.end()) return;
  Centroiding task;
  task.c = c;
  task.bag_time = now_;
  task.image = image->second;
  const TargetCentroiderStep* step = c->step.get();
  const auto pose = step->Pose(poses_.buffer(), *image->second, *info->second);
  if (!step->has_targets()) {
    // No targets to look for: the photo's empty target list at once.
    std::promise<CentroidedImage> ready;
    ready.set_value(step->Centroid(*image->second, *info->second, pose));
    task.result = ready.get_future();
  } else {
    task.result = std::async(
        std::launch::async, [this, step, image = image->second, info = info->second, pose] {
          return WallTimed(&stages_.targets, [&] { return step->Centroid(*image, *info, pose); });
        });
  }
  centroiding_ = std::move(task);
  c->images.erase(c->images.begin(), std::next(image));
  c->infos.erase(c->infos.begin(), std::next(info));
}

void OfflineGraph::TakeCentroided() {
  if (!centroiding_) return;
  Centroiding task = std::move(*centroiding_);
  centroiding_.reset();
  const ros::Time now = now_;
  now_ = task.bag_time;  // written and collected at the photo's place in the bag
  try {
    const CentroidedImage out = task.result.get();
    Centroider* c = task.c;
    Write("/" + c->step->camera() + "/targets", out.targets);
    c->step->Count(out);
    if (c->step->has_targets()) {
      c->last_image = task.image;
      c->last = out;
    }
    Solve(adjuster_->AddTargets(out.targets, now_.toSec()));
  } catch (const std::exception& e) {
    Log("target_centroider: " + task.c->step->Dropped(task.image->header, e.what()));
  }
  now_ = now;
}

// ------------------------------------------------- radio, targetless, markers

void OfflineGraph::OnEpochEnd(const slope_monitor::EpochMarker& marker) {
  std::vector<LogLine> ignored;
  const std::vector<SolvedEpoch> epochs = adjuster_->AddEnd(marker, now_.toSec(), &ignored);
  for (const LogLine& line : ignored) Log("bundle_adjuster: " + line.text);
  Solve(epochs);
}

// The adjuster's position priors: each site UAV camera's topic, or the
// graph's /uav/camera/position_prior without a site file.
bool OfflineGraph::IsPriorTopic(const std::string& topic) const {
  const AdjusterParameters& params = adjuster_->parameters();
  if (!params.cameras_from_site)
    return topic == UavCameraTopics(adjustment::DefaultUavCameras().front()).prior;
  const std::vector<std::string>& topics = params.prior_topics;
  return std::find(topics.begin(), topics.end(), topic) != topics.end();
}

bool OfflineGraph::IsPicksTopic(const std::string& topic) const {
  for (const std::string& cam : adjuster_->parameters().collector.uav_cameras)
    if (topic == UavCameraTopics(cam).picks) return true;
  return false;
}

// A receiver's block (/radio/<id>/samples) through the radio step, as the
// radio_phase_solver nodelet takes it (a recording: no wall-clock test of
// the stamps, now = 0).
void OfflineGraph::OnRadioBlock(const slope_monitor::RadioSampleBlock& block,
                                const std::string& topic) {
  const std::string receiver = RadioReceiverOfTopic(topic);
  if (!radio_ || receiver.empty()) return;
  if (!radio_->Accept(block, receiver, 0.0)) {
    Log("radio_phase_solver: rejected " + radio_->last_problem());
    return;
  }
  std::vector<LogLine> dropped;
  for (const RadioEpochOutput& out : radio_->Assemble(block, &dropped)) {
    for (const LogLine& line : out.log)
      if (line.level >= LogLine::kError) Log("radio_phase_solver: " + line.text);
    Write("/radio/phase_observations", out.messages.observations);
    if (out.messages.displacements) {
      Write(kRadioDisplacements, *out.messages.displacements);
      Fuse(*out.messages.displacements, kRadioDisplacements);
    }
  }
  for (const LogLine& line : dropped) Log("radio_phase_solver: " + line.text);
}

// A photo or camera_info of a fixed_targetless camera: re-orientation,
// field, fused. False for any other message.
bool OfflineGraph::OnTargetlessMessage(const rosbag::MessageInstance& m,
                                       const sensor_msgs::Image::ConstPtr& image) {
  if (!targetless_) return false;
  const std::string& topic = m.getTopic();
  for (const std::string& cam : targetless_->cameras()) {
    std::optional<TargetlessOutputs> out;
    try {
      if (topic == "/" + cam + "/camera/image_raw") {
        if (image) out = targetless_->AddImage(cam, image);
      } else if (topic == "/" + cam + "/camera/camera_info") {
        if (const auto info = m.instantiate<sensor_msgs::CameraInfo>())
          out = targetless_->AddCameraInfo(cam, info);
      } else {
        continue;
      }
    } catch (const std::exception& e) {
      Log(Message("targetless_camera: dropped photo of '", cam, "' (topic ", topic,
                  "): ", e.what()));
      return true;
    }
    if (out) PublishTargetless(*out);
    return true;
  }
  return false;
}

void OfflineGraph::PublishTargetless(const TargetlessOutputs& out) {
  Log("targetless_camera: " + out.info);
  for (const std::string& w : out.warnings) Log("targetless_camera: WARN " + w);
  diagnostic_msgs::DiagnosticArray d;
  d.header.stamp = now_;
  d.status.push_back(out.status);
  Write("/diagnostics", d);
  if (out.site_from_optical) {
    tf2_msgs::TFMessage tf;
    tf.transforms.push_back(*out.site_from_optical);
    Write("/tf", tf);
  }
  if (out.displacements) {
    Write(kTargetlessDisplacements, *out.displacements);
    Fuse(*out.displacements, kTargetlessDisplacements);
  }
}

// -------------------------------- the hex matcher (mode sequence), per UAV camera

// The matcher whose topic `field` (image or prior) is `topic`, if any.
OfflineGraph::UavMatcher* OfflineGraph::UavMatcherOf(const std::string& topic,
                                                     std::string UavTopics::*field) {
  for (UavMatcher& uav : uav_matchers_)
    if (uav.topics.*field == topic) return &uav;
  return nullptr;
}

void OfflineGraph::OnUavImage(UavMatcher* uav, const sensor_msgs::Image::ConstPtr& image) {
  OnSequenceStep(*uav,
                 WallTimed(&stages_.matching, [&] { return uav->step->AddImage(image, 0.0); }));
}

// The sequence matcher's step for a UAV position prior (pure: nothing is
// written or collected); none for a prior in another frame (logged).
std::optional<SequenceOutput> OfflineGraph::MatchUavPrior(
    UavMatcher* uav, const geometry_msgs::PoseWithCovarianceStamped& prior) {
  if (const auto why = uav->step->CheckPrior(prior)) {
    Log("hex_matcher: " + *why);
    return std::nullopt;
  }
  return WallTimed(&stages_.matching, [&] { return uav->step->AddPrior(prior); });
}

// The tie points written and collected; the pairs' progress only with --verbose.
void OfflineGraph::OnSequenceStep(const UavMatcher& uav, const SequenceOutput& out) {
  for (const LogLine& line : out.log)
    if (line.level != LogLine::kDebug || options_.verbose) Log("hex_matcher: " + line.text);
  for (const slope_monitor::TiePointArray& msg : out.tie_points) {
    ++stages_.pairs;
    stages_.tie_points += static_cast<int>(msg.points.size());
    Write(uav.topics.tie_points, msg);
    Solve(adjuster_->AddTies(msg, now_.toSec()));
  }
}

// The sequence matchers' time on photo features so far [s].
double OfflineGraph::FeatureSeconds() const {
  double s = 0.0;
  for (const UavMatcher& uav : uav_matchers_) s += uav.step->matcher().summary().feature_seconds;
  return s;
}

// ------------------------------------------------ the bundle adjuster's epochs

void OfflineGraph::Solve(const std::vector<SolvedEpoch>& epochs) {
  for (const SolvedEpoch& e : epochs) Solve(e);
}

void OfflineGraph::Solve(const SolvedEpoch& out) {
  const double adjustment = out.wall_time;
  const uint32_t epoch = out.solution.epoch;
  if (!out.accepted)
    last_failure_ = "epoch " + std::to_string(epoch) + " not accepted: " + out.solution.message;
  for (const LogLine& line : out.log)
    if (line.level >= LogLine::kWarn || options_.verbose) Log("bundle_adjuster: " + line.text);
  Publish(out);
  LogStages(epoch, out, adjustment);
}

// Wall time of each stage since the previous adjustment epoch, and the
// process's peak memory so far: one line per epoch (doc/process_bag.md).
void OfflineGraph::LogStages(uint32_t epoch, const SolvedEpoch& out, double adjustment) {
  char line[400];
  std::snprintf(line, sizeof line,
                "epoch %u stages: targets %.2f s, tie points %.2f s (%d pairs, %d points, "
                "photo features %.2f s), adjustment %.2f s (Ceres %.2f s in %u iterations, "
                "covariance %.2f s), dense %.2f s, estimator %.2f s; peak memory %.0f MB",
                epoch, stages_.targets, stages_.matching, stages_.pairs, stages_.tie_points,
                FeatureSeconds() - stages_.features_before, adjustment, out.solution.solve_time,
                out.solution.iterations, out.covariance_time, stages_.dense, stages_.estimator,
                1024.0 * PeakResidentGb());
  Log(std::string(line) + (out.adjusted && out.photos.total > 0 ? "; " + out.photos.Brief() : ""));
  stages_ = StageTimes();
  stages_.features_before = FeatureSeconds();
}

// Publishes a solved epoch as the bundle adjuster nodelet does; the
// accepted one's displacements go to the estimator.
void OfflineGraph::Publish(const SolvedEpoch& out) {
  Write("/bundle_adjuster/solution", out.solution);
  if (dense_) WallTimed(&stages_.dense, [&] { dense_->OnSolution(out.solution, now_.toSec()); });
  if (!out.accepted) return;
  if (!out.fixed_transforms.empty()) {
    tf2_msgs::TFMessage tf;
    tf.transforms = out.fixed_transforms;
    Write("/tf_static", tf);
  }
  if (!out.moving_transforms.empty()) {
    tf2_msgs::TFMessage tf;
    tf.transforms = out.moving_transforms;
    Write("/tf", tf);
  }
  Write("/bundle_adjuster/points", out.points);
  Write("/bundle_adjuster/frustums", adjuster_->Frustums(out));
  if (out.displacements) {
    Write(kAdjusterDisplacements, *out.displacements);
    Fuse(*out.displacements, kAdjusterDisplacements);
  }
}

// ------------------------------------------------- the deformation estimator

void OfflineGraph::Fuse(const slope_monitor::PointDisplacementArray& msg,
                        const std::string& topic) {
  Publish(
      WallTimed(&stages_.estimator, [&] { return estimator_->AddDisplacements(msg, topic, 0.0); }));
}

// The dense step's areas of significant change (source surface), as the
// estimator nodelet takes them from /dense/change_areas.
void OfflineGraph::OnAreas(const slope_monitor::ChangeAreaArray& msg) {
  Write(OfflineDense::kAreasTopic, msg);
  Publish(estimator_->AddAreas(msg, OfflineDense::kAreasTopic));
}

// The estimator's problems and snapshots, written as the estimator nodelet publishes them.
void OfflineGraph::Publish(const EstimatorResult& result) {
  for (const LogLine& line : result.problems) Log("deformation_estimator: " + line.text);
  for (const EstimatorPublication& p : result.publications) {
    for (const LogLine& line : p.log) Log("deformation_estimator: " + line.text);
    Write("/deformation_estimator/deformation", ToMsg(p.snapshot, p.header));
    Write("/deformation_estimator/markers",
          ToMarkers(p.snapshot, p.header, estimator_->parameters().markers));
    Write("/deformation_estimator/points", ToCloud(p.snapshot, p.header));
    Write("/deformation_estimator/alerts", ToAlerts(p.snapshot, p.header));
  }
}

// The reports at the end of the input, written as the estimator nodelet
// writes them (deformation::WriteAllReports); the hook's queue is drained first.
void OfflineGraph::WriteReportFiles() {
  estimator_->FlushHook();
  const EstimatorParameters& p = estimator_->parameters();
  const auto files = estimator_->WriteReports("", p.report_formats);
  Log("wrote " + std::to_string(files.size()) + " report file(s) to " + p.report_dir);
}

void OfflineGraph::Finish() {
  TakeCentroided();
  // The centroider's debug_image of each camera's latest photo (rviz's
  // photo panel), once: every photo would multiply the output bag's size.
  for (auto& [camera, c] : centroiders_)
    if (c.last) Write("/" + camera + "/debug_image", ToDebugImage(*c.last, c.last_image->header));
  for (UavMatcher& uav : uav_matchers_)
    OnSequenceStep(uav, WallTimed(&stages_.matching, [&] { return uav.step->Finish(); }));
  if (const std::optional<SolvedEpoch> e = adjuster_->Finish()) Solve(*e);
  // The inputs have ended: what waits for a later stamp of another input is fused.
  Publish(WallTimed(&stages_.estimator, [&] { return estimator_->Flush(); }));
  if (radio_) {
    // A recording before radio epochs already in the history: those tracked
    // again after it, their displacements revised (RadioStep::Finish).
    std::vector<LogLine> log;
    for (const RadioEpochOutput& out : radio_->Finish(&log)) {
      if (!out.messages.displacements) continue;
      Write(kRadioDisplacements, *out.messages.displacements);
      Publish(WallTimed(&stages_.estimator, [&] {
        return estimator_->ReviseDisplacements(*out.messages.displacements, kRadioDisplacements);
      }));
    }
    for (const LogLine& line : log) Log("radio_phase_solver: " + line.text);
  }
  if (dense_) {
    dense_->Finish();
    char line[120];
    std::snprintf(line, sizeof line, "dense step: %d surface(s) in %.1f s (%.1f s CPU)",
                  dense_->epochs_measured(), dense_->seconds(), dense_->cpu_seconds());
    Log(line);
  }
  Log("end of input: " + std::to_string(adjuster_->accepted()) + " adjustment epoch(s) accepted, " +
      std::to_string(radio_epochs()) + " radio epoch(s) solved");
  if (estimator_->GetSnapshot().points.empty()) {
    Log("no point was ever measured: no reports written to " + estimator_->parameters().report_dir);
    return;
  }
  WriteReportFiles();
}

}  // namespace ros_adapters
}  // namespace slope_monitor
