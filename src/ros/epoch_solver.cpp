#include "slope_monitor/ros/epoch_solver.h"

#include <set>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/adjustment_conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

void Log(SolvedEpoch* out, LogLine::Level level, const std::string& text) {
  out->log.push_back({level, text});
}

void LogResult(uint32_t n, const adjustment::EpochAdjustmentResult& result, bool no_unidentified,
               SolvedEpoch* out) {
  if (!result.initialization.empty())
    Log(out, LogLine::kWarn, Message("initialisation: ", result.initialization));
  if (!result.pruned.dropped_images.empty() || !result.pruned.dropped_cameras.empty())
    Log(out, LogLine::kWarn, Message("epoch ", n, ": ", result.pruned.Summary()));
  for (const std::string& r : result.rejected_names)
    Log(out, LogLine::kWarn,
        Message("epoch ", n, ": target name given by projection rejected: ", r));
  for (size_t i = 0; i < result.naming.notes.size() && i < 5; ++i)
    Log(out, LogLine::kDebug, Message("epoch ", n, ": ", result.naming.notes[i]));
  out->adjusted = true;
  out->photos = result.photos;
  out->naming = result.naming;
  out->rejected_names = static_cast<int>(result.rejected_names.size());
  if (result.photos.total > 0 || !no_unidentified)
    Log(out, LogLine::kInfo,
        Message("epoch ", n, ": ", result.photos.Brief(), "; ", result.naming.Brief(), "; ",
                result.oriented_from_approximate, " oriented from approximate target coordinates; ",
                result.rejected_names.size(), " names rejected by the residual test"));
}

}  // namespace

SolvedEpoch SolveCollectedEpoch(const adjustment::CollectedEpoch& epoch,
                                const std::map<std::string, camera::CameraModel>& models,
                                const AdjusterParameters& params, const std::string& source_name,
                                adjustment::EpochStore* store) {
  SolvedEpoch out;
  const uint32_t n = epoch.epoch;
  for (const std::string& line : epoch.incomplete)
    Log(&out, LogLine::kWarn, Message("epoch ", n, " (", epoch.reason, "): incomplete: ", line));
  for (const std::string& line : epoch.dropped)
    Log(&out, LogLine::kWarn, Message("epoch ", n, ": ", line));
  slope_monitor::AdjustmentSolution& s_out = out.solution;
  s_out.header.frame_id = params.frame_id;
  s_out.epoch = n;
  s_out.usable = false;
  if (epoch.observations.empty()) {
    s_out.message = "no observations collected";
    return out;
  }
  try {
    const adjustment::BuiltScene built =
        adjustment::BuildScene(epoch, models, *store, params.targets, params.scene);
    const adjustment::EpochAdjustmentResult result = adjustment::AdjustEpoch(
        built.scene, built.unidentified, adjustment::ListedTargets(params.targets), params.epoch);
    LogResult(n, result, built.unidentified.empty(), &out);
    const adjustment::Summary& s = result.summary;
    out.covariance_time = s.covariance_time;
    s_out = MakeSolution(epoch, result.scene, s, params.frame_id);
    if (!s.IsSolutionUsable()) {
      Log(&out, LogLine::kError,
          Message("epoch ", n, " not usable: ", s.reason, " (previous solution kept)"));
      return out;
    }
    // Accepted: the store keeps poses and calibration.
    const adjustment::EpochPoints ep =
        store->Accept(result.scene, s, static_cast<int>(n), s_out.header.stamp.toSec(),
                      params.epoch.adjustment.compute_datum_free_covariance);
    out.accepted = true;
    std::set<std::string> moving;  // the site file's kind uav, else the name rule
    for (const auto& camera : result.scene.cameras)
      if (adjustment::IsUavCamera(camera.name, params.collector.uav_cameras)) moving.insert(camera.name);
    CameraTransforms tfs = MakeTransforms(result.scene, epoch, params.frame_id, s_out.header.stamp, moving);
    out.fixed_transforms = std::move(tfs.fixed);
    out.moving_transforms = std::move(tfs.moving);
    out.points = MakePointCloud(result.scene, s, s_out.header);
    Log(&out, LogLine::kInfo,
        Message("epoch ", n, " accepted: ", result.scene.images.size(), " images, ",
                result.scene.points.size(), " points, ", s.num_observations,
                " observations, sigma0 ", s.sigma0, ", rms ", s.rms_residual_px, " px"));
    const std::optional<adjustment::EpochComparison> cmp =
        store->CompareWithReference(ep, params.displacement);
    if (!cmp) return out;
    if (!cmp->success) {
      Log(&out, LogLine::kError, cmp->message);
      return out;
    }
    const adjustment::EpochPoints& ref = *store->Reference();
    Log(&out, LogLine::kInfo,
        Message("epoch ", ep.epoch, " vs reference ", ref.epoch, ": ", cmp->displacements.size(),
                " monitoring displacements"));
    out.displacements = MakeDisplacements(*cmp, ref, ep.epoch, source_name, s_out.header);
  } catch (const std::exception& e) {
    s_out.usable = false;
    s_out.message = std::string("adjustment failed: ") + e.what();
    Log(&out, LogLine::kError, s_out.message + " (previous solution kept)");
  }
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
