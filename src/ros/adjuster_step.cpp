#include "slope_monitor/ros/adjuster_step.h"

#include <algorithm>
#include <chrono>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/view_markers.h"

namespace slope_monitor {
namespace ros_adapters {

std::vector<std::string> ReplayCameras(const AdjusterParameters& parameters,
                                       const std::function<bool(const std::string&)>& present,
                                       std::vector<LogLine>* log) {
  const std::vector<std::string>& cameras = parameters.collector.cameras;
  if (!parameters.cameras_from_site) return cameras;
  std::vector<std::string> kept, left_out;
  for (const std::string& camera : cameras) (present(camera) ? kept : left_out).push_back(camera);
  if (kept.empty() || left_out.empty()) return cameras;
  for (const std::string& camera : left_out)
    log->push_back({LogLine::kInfo,
                    "camera '" + camera + "' of the " +
                        (parameters.site_file.empty() ? "graph's default cameras" : "site file") +
                        " has no input in this replay: epochs do not wait for it"});
  return kept;
}

EpochMarkerOrder::EpochMarkerOrder(const std::vector<std::string>& cameras) : cameras_(cameras) {
  if (!cameras_.empty()) order_ = std::make_unique<InputOrder<Marker>>(cameras_);
}

std::vector<EpochMarkerOrder::Marker> EpochMarkerOrder::Add(const Marker& msg, double now) {
  if (!order_ || msg->epoch == 0 ||
      std::find(cameras_.begin(), cameras_.end(), msg->source) == cameras_.end())
    return {msg};
  return Items(order_->Add(msg->source, msg->epoch, msg, now));
}

std::vector<EpochMarkerOrder::Marker> EpochMarkerOrder::Expire(double now, double wait,
                                                               std::vector<std::string>* given_up) {
  if (!order_) return {};
  return Items(order_->Expire(now, wait, given_up));
}

std::vector<EpochMarkerOrder::Marker> EpochMarkerOrder::Flush() {
  if (!order_) return {};
  return Items(order_->Flush());
}

std::vector<EpochMarkerOrder::Marker> EpochMarkerOrder::Items(
    const std::vector<InputOrder<Marker>::Released>& released) const {
  std::vector<Marker> out;
  out.reserve(released.size());
  for (const auto& r : released) out.push_back(r.item);
  return out;
}

AdjusterStep::AdjusterStep(const AdjusterParameters& parameters, const std::string& source_name)
    : parameters_(parameters),
      source_name_(source_name),
      collector_(std::make_unique<adjustment::EpochCollector>(parameters_.collector,
                                                              &parameters_.targets)) {
  if (parameters_.database.empty()) return;
  states_ = std::make_unique<deformation::SavedStates>(parameters_.database);
  if (const auto saved = states_->Get(kStoreKey)) {
    store_.Load(saved->value);
    saved_reference_ = store_.reference_epoch();
    if (const adjustment::EpochPoints* ref = store_.Reference())
      resumed_ =
          Message("reference epoch ", ref->epoch, " (stamp ", Fixed(ref->stamp, 3), ", ",
                  ref->points.size(), " points) from the history '", parameters_.database, "'");
  }
}

void AdjusterStep::SaveStore() {
  const adjustment::EpochPoints* ref = store_.Reference();
  if (!states_ || ref == nullptr) return;
  states_->Put(kStoreKey, ref->stamp, store_.Save());
  saved_reference_ = ref->epoch;
}

void AdjusterStep::KeepCameras(const std::vector<std::string>& cameras) {
  if (cameras == parameters_.collector.cameras) return;
  parameters_.collector.cameras = cameras;
  collector_ =
      std::make_unique<adjustment::EpochCollector>(parameters_.collector, &parameters_.targets);
  reported_ignored_ = 0;
}

std::optional<std::string> AdjusterStep::OnCameraInfo(const std::string& camera,
                                                      const sensor_msgs::CameraInfo& info) {
  try {
    models_[camera] = CameraModelFromCameraInfo(info, parameters_.PixelSizeOf(camera));
  } catch (const Error& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

std::vector<SolvedEpoch> AdjusterStep::AddTargets(const slope_monitor::TargetObservationArray& msg,
                                                  double now) {
  return Solve(collector_->AddTargets(FromMsg(msg), now));
}

std::vector<SolvedEpoch> AdjusterStep::AddTies(const slope_monitor::TiePointArray& msg,
                                               double now) {
  return Solve(collector_->AddTies(FromMsg(msg), now));
}

void AdjusterStep::AddPrior(const geometry_msgs::PoseWithCovarianceStamped& msg) {
  collector_->AddPrior(FromMsg(msg));
}

std::vector<SolvedEpoch> AdjusterStep::AddEnd(const slope_monitor::EpochMarker& msg, double now,
                                              std::vector<LogLine>* ignored) {
  // The ignored markers are said before the epochs' own lines, as they are found.
  const std::vector<adjustment::CollectedEpoch> epochs = collector_->AddEnd(FromMsg(msg), now);
  for (; reported_ignored_ < collector_->ignored().size(); ++reported_ignored_)
    ignored->push_back({LogLine::kWarn, collector_->ignored()[reported_ignored_]});
  return Solve(epochs);
}

std::vector<SolvedEpoch> AdjusterStep::Poll(double now) { return Solve(collector_->Poll(now)); }

std::optional<SolvedEpoch> AdjusterStep::Finish() {
  if (const std::optional<adjustment::CollectedEpoch> e = collector_->Finish()) return Solve(*e);
  return std::nullopt;
}

SolvedEpoch AdjusterStep::SolveNow() { return Solve(collector_->TakeNow()); }

std::vector<SolvedEpoch> AdjusterStep::Solve(
    const std::vector<adjustment::CollectedEpoch>& epochs) {
  std::vector<SolvedEpoch> out;
  out.reserve(epochs.size());
  for (const adjustment::CollectedEpoch& e : epochs) out.push_back(Solve(e));
  return out;
}

SolvedEpoch AdjusterStep::Solve(const adjustment::CollectedEpoch& epoch) {
  const auto start = std::chrono::steady_clock::now();
  SolvedEpoch out = SolveCollectedEpoch(epoch, models_, parameters_, source_name_, &store_);
  out.wall_time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (out.adjusted) {
    last_photos_ = out.photos;
    last_naming_ = out.naming;
    last_rejected_names_ = out.rejected_names;
  }
  last_message_ = out.solution.message;
  last_usable_ = out.accepted;
  if (out.accepted) {
    ++accepted_;
    // The history keeps the reference: written when it is new, not every epoch.
    if (store_.reference_epoch() != saved_reference_) SaveStore();
  }
  return out;
}

visualization_msgs::MarkerArray AdjusterStep::Frustums(const SolvedEpoch& epoch) const {
  return ToFrustumMarkers(epoch.solution, models_, parameters_.frustums);
}

void AdjusterStep::Diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) const {
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

}  // namespace ros_adapters
}  // namespace slope_monitor
