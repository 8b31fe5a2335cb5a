// The offline graph's set-up (ros/offline_graph.h): each node's step made
// from the parameters replay.launch gives that node, read by the node's own
// reader (ros/node_parameters.h and the steps' readers).
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <set>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/offline_graph.h"
#include "slope_monitor/ros/param_files.h"

namespace slope_monitor {
namespace ros_adapters {

void ResolveReplayTargets(OfflineGraphOptions* a,
                          const std::function<void(const std::string&)>& log) {
  const std::optional<io::SiteFile> site =
      a->site.empty() ? std::nullopt : std::optional<io::SiteFile>(io::LoadSiteFile(a->site));
  if (site && site->targets && site->targets->OnlyPicked()) {
    // Points picked in the photos only (a gcp list): the picks come from the
    // bag (camera_capture), the photos are tied by their tie points.
    if (!a->uav_tie_points)
      log("site '" + site->name +
          "' lists only points picked in photos: no target stage; UAV photos tied by their tie "
          "points (as --uav-tie-points)");
    a->uav_tie_points = true;
    return;
  }
  if (site && site->targets) return;
  if (!a->target_list.empty()) return;
  const std::string beside =
      a->bags.front().substr(0, a->bags.front().size() - 4) + ".targets.yaml";
  if (std::filesystem::is_regular_file(beside)) {
    a->target_list = beside;
    return;
  }
  if (!site)
    throw InvalidArgument(
        "no target list: file '" + beside +
        "' not found (give --target-list FILE, or --site FILE naming the targets)");
  a->no_targets = true;
  std::string uav;
  for (const io::SiteCamera& c : site->cameras)
    if (c.kind == io::CameraKind::kUav) uav += (uav.empty() ? "" : ", ") + c.name;
  if (!uav.empty() && !a->uav_tie_points) {
    a->uav_tie_points = true;
    log("site '" + site->name + "' lists no targets: no target stage; UAV camera(s) " + uav +
        " tied by their tie points (as --uav-tie-points)");
  } else {
    log("site '" + site->name + "' lists no targets: no target stage");
  }
}

std::vector<std::string> BagCameras(rosbag::View& view) {
  std::set<std::string> names;
  for (const rosbag::ConnectionInfo* c : view.getConnections()) {
    const std::string& t = c->topic;
    const std::string suffix = "/camera/image_raw";
    if (t.size() > suffix.size() + 1 && t[0] == '/' &&
        t.compare(t.size() - suffix.size(), suffix.size(), suffix) == 0)
      names.insert(t.substr(1, t.size() - suffix.size() - 1));
  }
  return {names.begin(), names.end()};
}

bool BagHasTopic(rosbag::View& view, const std::string& topic) {
  for (const rosbag::ConnectionInfo* c : view.getConnections())
    if (c->topic == topic) return true;
  return false;
}

OfflineGraph::OfflineGraph(const OfflineGraphOptions& options,
                           const std::vector<std::string>& cameras, rosbag::Bag* output,
                           std::function<void(const std::string&)> log,
                           std::unique_ptr<deformation::History> history)
    : log_(std::move(log)), options_(options), output_(output) {
  SetUpTargetless();
  std::vector<std::string> with_targets;
  for (const std::string& cam : cameras)
    if (!targetless_ || !targetless_->Handles(cam)) with_targets.push_back(cam);
  if (!options_.site.empty()) site_ = io::LoadSiteFile(options_.site);
  for (const std::string& cam : with_targets) SetUpCentroider(cam);
  SetUpAdjuster(with_targets);
  SetUpRadio();
  SetUpEstimator(std::move(history));
  if (options_.dense) SetUpDense();
}

void OfflineGraph::SetUpUavTiePoints(const std::function<bool(const std::string&)>& has_topic) {
  for (const std::string& camera : adjuster_->parameters().collector.uav_cameras) {
    XmlRpc::XmlRpcValue p = LoadNodeParams(PackageConfigDir(), "hex_matcher");
    SetParam(&p, "mode", std::string("sequence"));
    SetParam(&p, "camera", camera);
    ParamReader r(p, "/" + camera + "/hex_matcher");
    UavMatcher uav;
    uav.step = std::make_unique<SequenceMatcherStep>(ReadHexMatcherParameters(r));
    uav.topics = UavCameraTopics(camera);
    uav.step->matcher().SetPriorsExpected(has_topic(uav.topics.prior));
    uav_matchers_.push_back(std::move(uav));
  }
}

void OfflineGraph::SetUpCentroider(const std::string& cam) {
  XmlRpc::XmlRpcValue p = LoadNodeParams(PackageConfigDir(), "target_centroider");
  SetParam(&p, "target_list", options_.target_list);
  SetParam(&p, "camera_name", cam);
  ParamReader r(p, "/" + cam + "/target_centroider");
  const TargetCentroiderParameters params = ReadTargetCentroiderParameters(r);
  const io::SiteFile* site = site_ ? &*site_ : nullptr;
  // A site without targets: nothing to look for (each photo gets an empty
  // target list, what a centroider would find).
  std::optional<io::TargetList> targets;
  if (!options_.no_targets) targets = CentroiderTargets(params.node, site);
  centroiders_[cam].step = std::make_unique<TargetCentroiderStep>(
      cam, CameraPixelSize(params.node, site ? site->FindCamera(cam) : nullptr), params, targets,
      "/" + cam + "/camera/image_raw");
}

void OfflineGraph::SetUpAdjuster(const std::vector<std::string>& cameras) {
  XmlRpc::XmlRpcValue p = LoadNodeParams(PackageConfigDir(), "bundle_adjuster");
  if (!options_.target_list.empty()) SetParam(&p, "target_list", options_.target_list);
  SetParam(&p, "cameras", StringListParam(cameras));
  if (!options_.site.empty()) SetParam(&p, "site_file", options_.site);
  if (!options_.adjuster_config.empty()) MergeParams(&p, LoadParamFile(options_.adjuster_config));
  if (options_.uav_tie_points) SetParam(&p, "uav_tie_points", true);
  // As processing_graph.xml: the UAV blocks beside the reports.
  if (!options_.report_dir.empty()) SetParam(&p, "block_dir", options_.report_dir);
  SetParam(&p, "database", options_.database);  // the reference epoch is the site's
  ParamReader r(p, "/bundle_adjuster");
  adjuster_ = std::make_unique<AdjusterStep>(ReadAdjusterParameters(r), "/bundle_adjuster");
  if (!adjuster_->resumed().empty()) Log("bundle_adjuster: " + adjuster_->resumed());
  // The site's cameras that this bag has (a UAV that did not fly is not
  // waited for), as the replay graph decides it.
  std::vector<LogLine> log;
  adjuster_->KeepCameras(ReplayCameras(
      adjuster_->parameters(),
      [&](const std::string& c) {
        return std::find(cameras.begin(), cameras.end(), c) != cameras.end();
      },
      &log));
  for (const LogLine& line : log) Log("bundle_adjuster: " + line.text);
  adjuster_->SetTiePointsExpected(options_.uav_tie_points);
}

void OfflineGraph::SetUpRadio() {
  XmlRpc::XmlRpcValue p = LoadNodeParams(PackageConfigDir(), "radio_phase_solver");
  const std::string stem = options_.bags.front().substr(0, options_.bags.front().size() - 4);
  // The simulator's truth beside the bag when there is one (replay.launch's
  // truth_file); a recorded bag has none, and a site without radio_network
  // has no radio: the solver does not run.
  if (options_.radio_network.empty()) {
    if (std::filesystem::is_regular_file(stem + ".truth.yaml"))
      SetParam(&p, "truth_file", stem + ".truth.yaml");
  } else
    SetParam(&p, "network_file", options_.radio_network);
  if (!options_.site.empty()) SetParam(&p, "site_file", options_.site);
  SetParam(&p, "database", options_.database);  // the reference solution is the site's
  ParamReader r(p, "/radio/radio_phase_solver");
  RadioParameters params;
  try {
    params = ReadRadioParameters(r);
  } catch (const Error& e) {
    // As the graph: without a radio network the radio solver does not run.
    Log(std::string("radio_phase_solver not running: ") + e.what());
    return;
  }
  if (!params.has_network) {
    Log("radio_phase_solver not running: no radio network");
    return;
  }
  radio_ = std::make_unique<RadioStep>(params);
}

void OfflineGraph::SetUpEstimator(std::unique_ptr<deformation::History> history) {
  const std::string config_dir = PackageConfigDir();
  XmlRpc::XmlRpcValue p = LoadNodeParams(config_dir, "deformation_estimator");
  if (!options_.site_config.empty()) MergeParams(&p, LoadParamFile(options_.site_config));
  if (!options_.site.empty()) SetParam(&p, "site_file", options_.site);
  SetParam(&p, "database", options_.database);
  SetParam(&p, "report_dir", options_.report_dir);
  if (!options_.site_name.empty()) SetParam(&p, "site_name", options_.site_name);
  std::string recording;
  for (const std::string& bag : options_.bags)
    recording += (recording.empty() ? "" : ", ") + std::filesystem::path(bag).filename().string();
  SetParam(&p, "recording", recording);
  std::vector<std::string> inputs = {kAdjusterDisplacements, kRadioDisplacements};
  if (targetless_) inputs.push_back(kTargetlessDisplacements);
  SetParam(&p, "input_topics", StringListParam(inputs));
  // As deformation_estimator.launch: the pictures by scripts/plot_report.
  SetParam(&p, "plot_script",
           std::filesystem::path(config_dir).parent_path().string() + "/scripts/plot_report");
  ParamReader r(p, "/deformation_estimator");
  // Fused in stamp order over the inputs that run (without a radio network
  // the radio solver does not: nothing to wait for).
  std::vector<std::string> ordered = {kAdjusterDisplacements};
  if (radio_) ordered.push_back(kRadioDisplacements);
  if (targetless_) ordered.push_back(kTargetlessDisplacements);
  estimator_ = std::make_unique<EstimatorStep>(
      ReadEstimatorParameters(r), ordered,
      // The site's notification hook, from its worker thread: straight to
      // stderr, not through the progress line.
      [](bool, const std::string& m) { std::cerr << "deformation_estimator: " << m << std::endl; },
      std::move(history));
}

// The fixed_targetless cameras of the site (launch/include/processing_graph.xml
// runs the targetless_camera nodelet for them).
void OfflineGraph::SetUpTargetless() {
  if (options_.site.empty()) return;
  XmlRpc::XmlRpcValue p = LoadNodeParams(PackageConfigDir(), "targetless_camera");
  SetParam(&p, "site_file", options_.site);
  SetParam(&p, "report_dir", options_.report_dir);
  ParamReader r(p, "/targetless_camera");
  const TargetlessParameters params = ReadTargetlessParameters(r);
  r.CheckNoUnknownKeys();
  targetless_ = std::make_unique<TargetlessCameras>(params);
  if (targetless_->cameras().empty()) targetless_.reset();
}

// The dense_epoch node's parameters as processing_graph.xml sets them.
void OfflineGraph::SetUpDense() {
  XmlRpc::XmlRpcValue p = LoadNodeParams(PackageConfigDir(), "dense_epoch");
  SetParam(&p, "report_dir", options_.report_dir);
  // The site's CRS (site file, else the overlay's geodetic_origin) is the
  // GeoTIFFs' map CRS, as in processing_graph.xml.
  if (!options_.site.empty()) SetParam(&p, "site_file", options_.site);
  if (!options_.site_config.empty()) SetParam(&p, "site_config", options_.site_config);
  dense_ = std::make_unique<OfflineDense>(
      p,
      [this](const DenseEpochOutput& out) {
        if (out.cloud) Write(OfflineDense::kCloudTopic, *out.cloud);
        if (out.legend) Write(OfflineDense::kLegendTopic, *out.legend);
        if (out.areas) OnAreas(*out.areas);
      },
      log_);
}

std::string OfflineGraph::WhyNothingSolved() const {
  if (!last_failure_.empty()) return last_failure_;
  if (centroiders_.empty() && !radio_)
    return "the bags hold no camera images (/<camera>/camera/image_raw) and no radio network "
           "runs";
  return "no adjustment epoch was completed (no epoch end marker of the cameras; see the "
         "warnings above)";
}

}  // namespace ros_adapters
}  // namespace slope_monitor
