#include "slope_monitor/ros/epoch_solver.h"

#include <map>
#include <optional>
#include <set>

#include "slope_monitor/core/adjustment/leave_one_out.h"
#include "slope_monitor/core/adjustment/survey_residuals.h"
#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/flight/flight_export.h"
#include "slope_monitor/core/flight/flight_scene.h"
#include "slope_monitor/core/io/gcp_list.h"
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
  if (result.wrong_picks_removed > 0)
    Log(out, LogLine::kWarn,
        Message("epoch ", n, ": ", result.wrong_picks_removed,
                " pick(s) of points picked in the photos removed: far off the other picks"));
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

// The UAV cameras of the scene whose photos the existing initialisation
// (InitializeScene, OrientFromApproximatePoints) cannot start: no photo of
// the camera sees 4 targets (control, check or monitoring points; 2 with a
// GNSS prior) or has the flight log's attitude (Image::attitude_from_prior),
// but the camera's photos have tie points (a UAV-only site without targets,
// or with a few control points picked in each photo).
std::vector<int> UavCamerasWithoutControl(const adjustment::Scene& scene,
                                          const AdjusterParameters& params) {
  std::vector<int> targets_seen(scene.images.size(), 0), ties_seen(scene.images.size(), 0);
  for (const adjustment::Observation& o : scene.observations)
    ++(scene.points[o.point].role == adjustment::PointRole::kTie ? ties_seen
                                                                 : targets_seen)[o.image];
  std::vector<int> out;
  for (size_t c = 0; c < scene.cameras.size(); ++c) {
    if (!adjustment::IsUavCamera(scene.cameras[c].name, params.collector.uav_cameras)) continue;
    bool started = false, tied = false;
    for (size_t i = 0; i < scene.images.size(); ++i) {
      if (scene.images[i].camera != static_cast<int>(c)) continue;
      const adjustment::Image& im = scene.images[i];
      started = started || targets_seen[i] >= 4 || (im.position_prior && targets_seen[i] >= 2) ||
                im.attitude_from_prior;
      tied = tied || ties_seen[i] > 0;
    }
    if (!started && tied) out.push_back(static_cast<int>(c));
  }
  return out;
}

// Whether the heights of camera `cam`'s block are given: a photo with a
// GNSS position prior, or a control point it sees whose survey has a height
// (a gcp list without heights gives io::kNoHeightSigma).
bool HeightsInDatum(const adjustment::Scene& scene, int cam) {
  for (const adjustment::Image& im : scene.images)
    if (im.camera == cam && im.position_prior) return true;
  for (const adjustment::Observation& o : scene.observations) {
    const adjustment::ObjectPoint& p = scene.points[o.point];
    if (scene.images[o.image].camera == cam && p.role == adjustment::PointRole::kControl &&
        p.surveyed && !io::HeightUnknown(p.surveyed_covariance(2, 2)))
      return true;
  }
  return false;
}

// A UAV flight without targets in its photos (a UAV-only site): its photos
// and tie points are oriented by the flight module (the same code as
// process_flight), georeferenced by the GNSS priors, and the camera's
// interior it self-calibrated (distortion model radial) becomes the
// adjustment's start; unless the parameters say otherwise (uav_free_interior),
// the adjustment self-calibrates c, k1, k2 of it. Returns why a flight could
// not be oriented ("" when all were; logged as an error too).
std::string StartFlightsFromTiePoints(adjustment::Scene* scene, const AdjusterParameters& params,
                                      uint32_t n, adjustment::EpochAdjustmentOptions* options,
                                      SolvedEpoch* out, bool* no_heights) {
  std::string failed;
  for (const int c : UavCamerasWithoutControl(*scene, params)) {
    const std::string camera = scene->cameras[c].name;
    const flight::FlightSummary f = flight::OrientSceneFromTiePoints(scene, camera);
    if (!f.success) {
      failed = Message("UAV camera '", camera,
                       "' sees too few targets to start from and its tie points could not orient ",
                       "them: ", f.message);
      Log(out, LogLine::kError, Message("epoch ", n, ": ", failed));
      continue;
    }
    Log(out, LogLine::kInfo,
        Message("epoch ", n, ": UAV camera '", camera,
                "' started from its tie points: ", f.oriented, " of ", f.photos,
                " photos oriented, ", f.points, " points, rms ", f.rms_px, " px, datum ", f.datum));
    if (options->free_interior_by_camera.count(camera) == 0) {
      // Without heights in the datum c and the flying height trade off
      // exactly over a nadir block: c stays at the flight start's value.
      const bool heights = HeightsInDatum(*scene, c);
      *no_heights = *no_heights || !heights;
      if (!heights)
        Log(out, LogLine::kInfo,
            Message("epoch ", n, ": UAV camera '", camera,
                    "': no heights in the datum (no GNSS, control points without heights): c "
                    "held, k1 and k2 self-calibrated"));
      std::vector<int> free;
      for (const char* name : {"c", "k1", "k2"})
        if (heights || name != std::string("c"))
          for (int i = 0; i < camera::kNumInterior; ++i)
            if (camera::InteriorNames()[i] == std::string(name)) free.push_back(i);
      options->free_interior_by_camera[camera] = free;
    }
  }
  return failed;
}

// One epoch's adjustment as SolveCollectedEpoch ran it, for TakeAccepted.
struct EpochSolve {
  const adjustment::CollectedEpoch& epoch;
  const adjustment::EpochAdjustmentResult& result;
  const std::vector<adjustment::ListedTarget>& listed;
  const adjustment::EpochAdjustmentOptions& options;  // as adjusted (a flight start may hold c)
  bool no_heights = false;  // the datum has no heights (no GNSS, control without heights)
};

// An accepted epoch's datum (a covariance relative to the control), its
// control and check points' residuals and (leave_one_out) each control
// point's residual with it left out.
void LogDatumAndSurvey(const EpochSolve& e, bool leave_one_out, SolvedEpoch* out) {
  const uint32_t n = e.epoch.epoch;
  const adjustment::Scene& scene = e.result.scene;
  const adjustment::Summary& s = e.result.summary;
  const bool no_heights = e.no_heights;
  if (s.precision.relative_to_control)
    Log(out, LogLine::kWarn,
        Message("epoch ", n,
                ": the absolute covariance is singular; precisions and "
                "displacement significance are relative to the control points held",
                no_heights ? " (the datum has no heights: the block's tilt rests on the control "
                             "points; give their heights for absolute heights)"
                           : ""));
  std::vector<std::string> listed;
  std::map<std::string, std::string> names;
  for (const adjustment::ListedTarget& t : e.listed)
    if (t.role == adjustment::PointRole::kControl || t.role == adjustment::PointRole::kCheck) {
      listed.push_back(t.id);
      names[t.id] = t.name;
    }
  const adjustment::SurveyResiduals survey =
      adjustment::ComputeSurveyResiduals(scene, listed, names);
  if (survey.control.empty() && survey.check.empty()) return;
  Log(out, LogLine::kInfo, Message("epoch ", n, ": ", survey.Brief()));
  for (const std::string& line : survey.Lines())
    Log(out, LogLine::kDebug, Message("epoch ", n, ": ", line));
  if (!leave_one_out || survey.control.empty()) return;
  const adjustment::LeaveOneOutReport loo = adjustment::LeaveOneOut(scene, e.options, names);
  Log(out, LogLine::kInfo, Message("epoch ", n, ": ", loo.Brief(), " (", loo.seconds, " s)"));
  for (const std::string& line : loo.Lines())
    Log(out, LogLine::kDebug, Message("epoch ", n, ": ", line));
}

// Each UAV camera's block of an accepted epoch into
// <dir>/epoch_<n>/<camera>/ (flight_export.h), said in the log.
void WriteUavBlocks(const adjustment::Scene& scene, const adjustment::Summary& summary,
                    const std::set<std::string>& cameras, const SiteCrsOptions& crs,
                    const std::string& dir, uint32_t n, SolvedEpoch* out) {
  std::optional<flight::FlightFrame> frame;
  for (const std::string& camera : cameras) {
    const std::string to = Message(dir, "/epoch_", n, "/", camera);
    try {
      const flight::FlightResult block = flight::BlockOfCamera(scene, summary, camera);
      if (!frame) frame = flight::FrameOfSite(crs);
      flight::WriteBlockOutputs(block, *frame, to);
      Log(out, LogLine::kInfo,
          Message("epoch ", n, ": ", camera, "'s block (", block.scene.images.size(), " photos, ",
                  block.scene.points.size(), " points, mean reprojection error ",
                  block.summary.mean_px, " px) written to ", to,
                  " (COLMAP text model in sparse/, points.ply, cameras.csv, crs.txt)"));
    } catch (const std::exception& e) {
      Log(out, LogLine::kError,
          Message("epoch ", n, ": ", camera, "'s block not written: ", e.what()));
    }
  }
}

// An accepted epoch: the store keeps poses and calibration; its transforms,
// points, UAV blocks (block_dir) and displacements against the reference.
void TakeAccepted(const EpochSolve& solve, const AdjusterParameters& params,
                  const std::string& source_name, adjustment::EpochStore* store, SolvedEpoch* out) {
  const adjustment::CollectedEpoch& epoch = solve.epoch;
  const adjustment::EpochAdjustmentResult& result = solve.result;
  const uint32_t n = epoch.epoch;
  const adjustment::Summary& s = result.summary;
  LogDatumAndSurvey(solve, params.leave_one_out, out);
  const adjustment::EpochPoints ep =
      store->Accept(result.scene, s, static_cast<int>(n), out->solution.header.stamp.toSec(),
                    params.epoch.adjustment.compute_datum_free_covariance);
  out->accepted = true;
  std::set<std::string> moving;  // the site file's kind uav, else the name rule
  for (const auto& camera : result.scene.cameras)
    if (adjustment::IsUavCamera(camera.name, params.collector.uav_cameras))
      moving.insert(camera.name);
  CameraTransforms tfs =
      MakeTransforms(result.scene, epoch, params.frame_id, out->solution.header.stamp, moving);
  out->fixed_transforms = std::move(tfs.fixed);
  out->moving_transforms = std::move(tfs.moving);
  out->points = MakePointCloud(result.scene, s, out->solution.header);
  if (!params.block_dir.empty() && params.site_crs)
    WriteUavBlocks(result.scene, s, moving, *params.site_crs, params.block_dir, n, out);
  Log(out, LogLine::kInfo,
      Message("epoch ", n, " accepted: ", result.scene.images.size(), " images, ",
              result.scene.points.size(), " points, ", s.num_observations, " observations, sigma0 ",
              s.sigma0, ", rms ", s.rms_residual_px, " px"));
  const std::optional<adjustment::EpochComparison> cmp =
      store->CompareWithReference(ep, params.displacement);
  if (!cmp) return;
  if (!cmp->success) {
    Log(out, LogLine::kError, cmp->message);
    return;
  }
  const adjustment::EpochPoints& ref = *store->Reference();
  Log(out, LogLine::kInfo,
      Message("epoch ", ep.epoch, " vs reference ", ref.epoch, ": ", cmp->displacements.size(),
              " monitoring displacements"));
  out->displacements = MakeDisplacements(*cmp, ref, ep.epoch, source_name, out->solution.header);
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
    adjustment::BuiltScene built =
        adjustment::BuildScene(epoch, models, *store, params.targets, params.scene);
    adjustment::EpochAdjustmentOptions options = params.epoch;
    bool no_heights = false;
    const std::string failed =
        StartFlightsFromTiePoints(&built.scene, params, n, &options, &out, &no_heights);
    if (!failed.empty()) {
      s_out.message = failed;
      return out;
    }
    const std::vector<adjustment::ListedTarget> listed = adjustment::ListedTargets(params.targets);
    const adjustment::EpochAdjustmentResult result =
        adjustment::AdjustEpoch(built.scene, built.unidentified, listed, options);
    LogResult(n, result, built.unidentified.empty(), &out);
    const adjustment::Summary& s = result.summary;
    out.covariance_time = s.covariance_time;
    s_out = MakeSolution(epoch, result.scene, s, params.frame_id);
    if (!s.IsSolutionUsable()) {
      if (no_heights && s.reason.rfind("covariance could not be computed", 0) == 0)
        s_out.message +=
            "; the datum has no heights (no GNSS, control points without heights): the block's "
            "tilt is not determined; give the control points' heights";
      Log(&out, LogLine::kError,
          Message("epoch ", n, " not usable: ", s_out.message, " (previous solution kept)"));
      return out;
    }
    TakeAccepted({epoch, result, listed, options, no_heights}, params, source_name, store, &out);
  } catch (const std::exception& e) {
    s_out.usable = false;
    s_out.message = std::string("adjustment failed: ") + e.what();
    Log(&out, LogLine::kError, s_out.message + " (previous solution kept)");
  }
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
