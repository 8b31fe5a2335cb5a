#include "slope_monitor/ros/node_parameters.h"

#include "slope_monitor/core/adjustment/site_options.h"
#include "slope_monitor/core/deformation/site_options.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_file.h"

#include <cmath>
#include <filesystem>
#include <sstream>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/sim/truth.h"
#include "slope_monitor/ros/replay_defaults.h"
#include "slope_monitor/ros/uav_topics.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

// The `database` parameter ("auto": the site's history, ros/replay_defaults.h)
// with what names the site: site_name (given), site_config (the estimator
// overlay's site_name), truth_file, recording. *site_name (may be null): the site's name.
std::string ReadDatabase(ParamReader& p, const std::string& site_file,
                         const std::string& truth_file, std::string* site_name = nullptr) {
  const std::string database = p.String("database", "");
  SiteNameSources sources;
  sources.site_file = site_file;
  sources.site_config = p.String("site_config", "");
  sources.truth_file = truth_file.empty() ? p.String("truth_file", "") : truth_file;
  sources.recording = p.String("recording", "");
  sources.site_name = p.String("site_name", "");
  if (site_name) *site_name = SiteNameOf(sources);
  if (database != "auto") return database;
  try {
    return ResolveDatabase(database, sources);
  } catch (const ConfigError& e) {
    throw ConfigError(Message("parameter '", p.FullKey("database"), "': ", e.what()));
  }
}

std::string Trim(const std::string& s) {
  const size_t a = s.find_first_not_of(" \t");
  const size_t b = s.find_last_not_of(" \t");
  return a == std::string::npos ? "" : s.substr(a, b - a + 1);
}

// The simulator's truth as a network file: receivers as surveyed, the
// transmitters' epoch-0 positions as the installation survey.
radio::NetworkConfig NetworkFromTruth(const sim::SurveyTruth& truth, double sigma,
                                      double sample_rate, const std::string& path) {
  radio::NetworkConfig n;
  if (truth.radio.Empty()) throw ConfigError(path + ": radio: the truth has no radio network");
  n.wavelength = truth.radio.wavelength;
  n.center_frequency = truth.radio.center_frequency;
  n.sample_rate = sample_rate;  // the truth does not hold it: parameter truth_sample_rate
  for (const auto& r : truth.radio.receivers) n.receivers.push_back({r.id, r.position});
  for (const auto& t : truth.radio.transmitters) {
    if (t.positions.empty())
      throw ConfigError(path + ": radio.transmitters '" + t.id + "' has no positions");
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

// The names (camera::InteriorNames) of interior parameter indices.
std::vector<std::string> InteriorNamesOf(const std::vector<int>& indices) {
  std::vector<std::string> names;
  names.reserve(indices.size());
  for (int i : indices) names.push_back(camera::InteriorNames()[i]);
  return names;
}

// ReadAdjusterParameters, stage 1: the targets (site file, target list) and
// the cameras with their topics (the site file's, else the parameters').
void ReadAdjusterTargetsAndCameras(ParamReader& p, AdjusterParameters& a) {
  // The site file (io::LoadSiteFile) gives the targets when it lists them
  // (target_list is then not read: replay.launch defaults it to the bag's),
  // and each camera's pixel size and kind.
  a.site_file = p.String("site_file", a.site_file);
  const std::string& site_file = a.site_file;
  std::optional<io::SiteFile> site;
  if (!site_file.empty()) site = io::LoadSiteFile(site_file);
  if (site) a.site_crs = site->crs;
  a.block_dir = p.String("block_dir", a.block_dir);
  a.leave_one_out = p.Bool("leave_one_out", a.leave_one_out);
  a.target_list_path = p.String("target_list", a.target_list_path);
  if (site && site->targets) {
    a.targets = *site->targets;
    a.site_without_targets = a.targets.OnlyPicked();  // picked points only (a gcp list)
    a.target_list_path =
        site->targets_file.empty() ? site_file + " (inline targets)" : site->targets_file;
  } else if (site && io::SiteWithoutTargets(*site, a.target_list_path)) {
    // A site without targets (a UAV flight oriented by its tie points and
    // GNSS, fixed_targetless cameras) is a normal site: no target list
    // (replay.launch's default, the bag's <name>.targets.yaml, not there).
    a.target_list_path = site_file + " (no targets)";
    a.site_without_targets = true;
  } else if (!a.target_list_path.empty()) {
    // YAML or a surveyors' CSV (in the site's CRS when a site file is given).
    a.targets = io::LoadTargetFileInSite(a.target_list_path, site ? &site->crs : nullptr);
  } else {
    throw ConfigError("parameter '" + p.FullKey("target_list") + "' is required (or '" +
                      p.FullKey("site_file") + "' naming a site file with targets)");
  }
  // The camera kind is the site file's field, not the name.
  if (site) a.pixel_size_by_camera = adjustment::ApplySite(*site, &a.collector, &a.scene);
  std::vector<std::string> site_cameras, site_targets, site_epochs;
  a.prior_topics = {"position_prior"};
  a.tie_topics = {"tie_points"};
  // The graph's cameras: the site file's when it lists any, else (graph_cameras)
  // io::DefaultCameras(); those with targets (kind fixed or uav).
  a.graph_cameras = p.Bool("graph_cameras", a.graph_cameras);
  std::vector<io::SiteCamera> graph_cameras;
  if (site && !site->cameras.empty())
    for (const io::SiteCamera* cam : site->CamerasWithTargets()) graph_cameras.push_back(*cam);
  else if (a.graph_cameras)
    for (const io::SiteCamera& cam : io::DefaultCameras())
      if (cam.kind != io::CameraKind::kFixedTargetless) graph_cameras.push_back(cam);
  std::vector<std::string> priors, ties;
  for (const io::SiteCamera& cam : graph_cameras) {
    site_cameras.push_back(cam.name);
    site_targets.push_back("/" + cam.name + "/targets");
    site_epochs.push_back("/" + cam.name + "/camera/epoch");
    if (cam.kind == io::CameraKind::kUav) {
      priors.push_back(UavCameraTopics(cam.name).prior);
      ties.push_back(UavCameraTopics(cam.name).tie_points);
      site_targets.push_back(UavCameraTopics(cam.name).picks);
    }
  }
  if (!site_cameras.empty()) {
    a.prior_topics = priors;
    a.tie_topics = ties;
  }
  // A site file that lists cameras (or graph_cameras) decides them (cameras,
  // target_topics and epoch_topics are then not used, as target_list is not).
  a.cameras_from_site = !site_cameras.empty();
  adjustment::EpochCollectorOptions& c = a.collector;
  a.target_topics = p.StringList("target_topics", a.target_topics);
  c.cameras = p.StringList("cameras", c.cameras);
  a.epoch_topics = p.StringList("epoch_topics", a.epoch_topics);
  if (a.cameras_from_site) {
    c.cameras = site_cameras;
    a.target_topics = site_targets;
    a.epoch_topics = site_epochs;
  }
}

// Stage 2: how an epoch is collected (waits, sigmas) and the scene's priors.
void ReadAdjusterCollectorAndScene(ParamReader& p, AdjusterParameters& a) {
  adjustment::EpochCollectorOptions& c = a.collector;
  c.epoch_wait = p.Double("epoch_wait", c.epoch_wait, 0.0, 3600.0, "s");
  // The UAV cameras' photos wait for their tie points (replay.launch
  // uav_tie_points:=true, process_bag --uav-tie-points).
  // A site without targets: its UAV cameras by their tie points (as process_bag).
  a.uav_tie_points = p.Bool("uav_tie_points", a.uav_tie_points) || a.site_without_targets;
  if (a.uav_tie_points) c.tie_point_cameras = c.uav_cameras;
  c.tie_point_wait = p.Double("tie_point_wait", c.tie_point_wait, 0.0, 86400.0, "s");
  c.tie_pixel_sigma_floor =
      p.Double("tie_pixel_sigma_floor", c.tie_pixel_sigma_floor, 0.0, 100.0, "px");
  c.min_tie_quality = p.Double("min_tie_quality", c.min_tie_quality, 0.0, 1.0);
  a.frame_id = p.String("frame_id", a.frame_id);
  a.enable_run_adjustment = p.Bool("enable_run_adjustment", a.enable_run_adjustment);
  a.enable_set_reference_epoch = p.Bool("enable_set_reference_epoch", a.enable_set_reference_epoch);
  a.pixel_size = p.Double("pixel_size", a.pixel_size, 1e-6, 1.0, "mm/px");
  c.pixel_sigma = p.Double("pixel_sigma", c.pixel_sigma, 1e-4, 100.0, "px");
  c.pixel_sigma_floor = p.Double("pixel_sigma_floor", c.pixel_sigma_floor, 0.0, 100.0, "px");
  c.uav_pixel_sigma_floor =
      p.Double("uav_pixel_sigma_floor", c.uav_pixel_sigma_floor, 0.0, 100.0, "px");
  c.epoch_gap = p.Double("epoch_gap", c.epoch_gap, 0.0, 1e7, "s");
  c.Check();
  a.scene.position_prior_max_dt =
      p.Double("position_prior_max_dt", a.scene.position_prior_max_dt, 0.0, 10.0, "s");
  a.scene.position_prior_min_sigma =
      p.Double("position_prior_min_sigma", a.scene.position_prior_min_sigma, 1e-4, 100.0, "m");
  a.scene.min_images = p.Int("min_images", a.scene.min_images, 1, 10000);
  a.scene.attitude_prior_max_sigma =
      p.Double("attitude_prior_max_sigma", a.scene.attitude_prior_max_sigma * 180.0 / M_PI, 0.0,
               180.0, "deg") *
      M_PI / 180.0;
  a.scene.Check();
}

// Stage 3: the epoch adjustment (interior parameters set free, the solver,
// the robust loss, naming of unidentified targets).
void ReadAdjusterEpochOptions(ParamReader& p, AdjusterParameters& a) {
  const adjustment::EpochCollectorOptions& c = a.collector;
  auto interior_list = [&p](const std::string& key, const std::vector<std::string>& names) {
    std::vector<int> out;
    for (const std::string& name : names) {
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
  adjustment::EpochAdjustmentOptions& e = a.epoch;
  e.free_interior = interior_list("free_interior",
                                  p.StringList("free_interior", InteriorNamesOf(e.free_interior)));
  a.uav_free_interior = p.StringList("uav_free_interior", a.uav_free_interior);
  const std::vector<int> uav_free_interior =
      interior_list("uav_free_interior", a.uav_free_interior);
  adjustment::Options& o = e.adjustment;
  o.loss = p.String("loss", o.loss, {"none", "huber", "cauchy"});
  o.loss_scale = p.Double("loss_scale", o.loss_scale, 1e-3, 1e3, "sigma");
  o.outlier_threshold = p.Double("outlier_threshold", o.outlier_threshold, 1e-3, 1e3, "sigma");
  o.linear_solver = p.String("linear_solver", o.linear_solver,
                             {"auto", "dense_schur", "sparse_schur", "iterative_schur"});
  o.max_iterations = p.Int("max_iterations", o.max_iterations, 1, 10000);
  const int threads = p.Int("num_threads", o.num_threads, 0, 64);
  o.num_threads = threads > 0 ? threads : adjustment::Options::HardwareThreads();
  o.minimizer_progress = p.Bool("minimizer_progress", o.minimizer_progress);
  o.min_control_points = p.Int("min_control_points", o.min_control_points, 0, 1000);
  o.max_sigma0 = p.Double("max_sigma0", o.max_sigma0, 0.01, 1e6);
  o.max_outlier_fraction = p.Double("max_outlier_fraction", o.max_outlier_fraction, 0.0, 1.0);
  o.min_observations_with_prior =
      p.Int("min_observations_with_prior", o.min_observations_with_prior, 2, 1000);
  o.min_variance_factor = p.Double("min_variance_factor", o.min_variance_factor, 0.0, 100.0);
  o.compute_datum_free_covariance =
      p.Bool("datum_free_displacements", o.compute_datum_free_covariance);
  o.Check();
  // A UAV camera self-calibrated in every flight: its own list (the fixed
  // cameras keep free_interior).
  if (!uav_free_interior.empty())
    for (const std::string& cam : c.cameras)
      if (adjustment::IsUavCamera(cam, c.uav_cameras))
        e.free_interior_by_camera[cam] = uav_free_interior;
  e.name_unidentified = p.Bool("name_unidentified", e.name_unidentified);
  e.orient_from_approximate = p.Bool("orient_from_approximate", e.orient_from_approximate);
  e.max_tie_outlier_share = p.Double("max_tie_outlier_share", e.max_tie_outlier_share, 1e-3, 1.0);
  e.naming.gate_sigma = p.Double("naming_gate_sigma", e.naming.gate_sigma, 0.1, 100.0, "sigma");
  e.naming.gate_extra_px =
      p.Double("naming_gate_extra_px", e.naming.gate_extra_px, 0.0, 10000.0, "px");
  e.naming.coarse_extra_px =
      p.Double("naming_coarse_extra_px", e.naming.coarse_extra_px, 0.0, 10000.0, "px");
  e.naming.ambiguity_factor =
      p.Double("naming_ambiguity_factor", e.naming.ambiguity_factor, 1.0, 100.0);
  e.Check();
}

}  // namespace

AdjusterParameters ReadAdjusterParameters(ParamReader& p) {
  AdjusterParameters a;
  ReadAdjusterTargetsAndCameras(p, a);
  a.database = ReadDatabase(p, a.site_file, "");
  ReadAdjusterCollectorAndScene(p, a);
  ReadAdjusterEpochOptions(p, a);
  a.displacement.stable_threshold =
      p.Double("stable_threshold", a.displacement.stable_threshold, 1e-6, 100.0, "m");
  a.displacement.significance_threshold =
      p.Double("significance_threshold", a.displacement.significance_threshold, 0.1, 100.0);
  a.displacement.estimate_scale = p.Bool("coregistration_scale", a.displacement.estimate_scale);
  a.displacement.Check();
  a.frustums.depth = p.Double("frustum_depth", a.frustums.depth, 1e-3, 1e4, "m");
  a.frustums.line_width = p.Double("frustum_line_width", a.frustums.line_width, 1e-3, 100.0, "m");
  a.frustums.uav_cameras = a.collector.uav_cameras;
  a.frustums.Check();
  p.CheckNoUnknownKeys();
  return a;
}

RadioParameters ReadRadioParameters(ParamReader& p) {
  RadioParameters r;
  r.network_file = p.String("network_file", r.network_file);
  r.site_file = p.String("site_file", r.site_file);  // its radio_network, when it names one
  r.truth_file = p.String("truth_file", r.truth_file);
  r.database = ReadDatabase(p, r.site_file, r.truth_file);
  r.truth_initial_sigma = p.Double("truth_initial_sigma", r.truth_initial_sigma, 1e-5, 10.0, "m");
  r.truth_sample_rate = p.Double("truth_sample_rate", r.truth_sample_rate, 1.0, 1e10, "Hz");
  const std::string &network_file = r.network_file, &site_file = r.site_file,
                    &truth_file = r.truth_file;
  radio::RadioSolverOptions& o = r.options;
  o.extraction.min_snr = p.Double("min_snr", o.extraction.min_snr, 1e-3, 1e9);
  o.extraction.max_saturated_fraction =
      p.Double("max_saturated_fraction", o.extraction.max_saturated_fraction, 0.0, 1.0);
  o.extraction.fit_dc = p.Bool("fit_dc", o.extraction.fit_dc);
  o.init_epochs = p.Int("init_epochs", o.init_epochs, 1, 1000, "epochs");
  o.ratio_threshold = p.Double("ratio_threshold", o.ratio_threshold, 1.0, 100.0);
  o.process_noise = p.Double("process_noise", o.process_noise, 0.0, 1.0, "m^2/s");
  o.outlier_sigma = p.Double("outlier_sigma", o.outlier_sigma, 2.0, 100.0);
  o.refix_after = p.Int("refix_after", o.refix_after, 1, 1000, "epochs");
  o.min_phase_sigma = p.Double("min_phase_sigma", o.min_phase_sigma, 0.0, 1.0, "rad");
  o.min_receivers = p.Int("min_receivers", o.min_receivers, 3, 100);
  o.max_refix_sigma = p.Double("max_refix_sigma", o.max_refix_sigma, 1e-6, 1.0, "m");
  r.stamp_tolerance = p.Double("stamp_tolerance", r.stamp_tolerance, 0.0, 10.0, "s");
  r.max_wait = p.Double("max_wait", r.max_wait, 0.0, 86400.0, "s");
  r.frame_id = p.String("frame_id", r.frame_id);
  p.CheckNoUnknownKeys();
  // A site file's radio network wins over network_file / truth_file
  // (replay.launch defaults truth_file to the bag's); a site without one
  // leaves them in charge.
  const std::string site_network =
      site_file.empty() ? "" : io::LoadSiteFile(site_file).radio_network;
  if (!site_network.empty()) {
    r.network = radio::NetworkConfig::Load(site_network);
    r.has_network = true;
    return r;
  }
  // With a site file, a truth file that is not there (replay.launch's
  // default, the bag's <name>.truth.yaml, on a real site's bag) means what
  // the site says: no radio network.
  if (network_file.empty() &&
      (truth_file.empty() || (!site_file.empty() && !std::filesystem::is_regular_file(truth_file))))
    return r;
  if (network_file.empty() == truth_file.empty())
    throw ConfigError(p.FullKey("network_file") + " / " + p.FullKey("truth_file") +
                      ": set exactly one of them");
  r.has_network = true;
  if (!network_file.empty()) {
    r.network = radio::NetworkConfig::Load(network_file);
  } else {
    r.network = NetworkFromTruth(sim::SurveyTruth::Load(truth_file), r.truth_initial_sigma,
                                 r.truth_sample_rate, truth_file);
  }
  return r;
}

EstimatorParameters ReadEstimatorParameters(ParamReader& p) {
  EstimatorParameters e;
  deformation::EstimatorOptions* o = &e.options;
  e.input_topics = p.StringList("input_topics", e.input_topics);
  if (e.input_topics.empty())
    throw ConfigError(Message("parameter '", p.FullKey("input_topics"), "' is empty"));
  e.area_topics = p.StringList("area_topics", e.area_topics);
  o->areas.growth_watch = p.Double("area_growth_watch", o->areas.growth_watch, 1e-6, 1e9, "m^2");
  o->areas.growth_warning =
      p.Double("area_growth_warning", o->areas.growth_warning, 1e-6, 1e9, "m^2");
  e.frame_id = p.String("frame_id", e.frame_id);
  // The recording's file names (bags: "a.bag, b.bag"), wherever they were read from.
  std::stringstream bags(p.String("recording", e.recording));
  e.recording.clear();
  for (std::string bag; std::getline(bags, bag, ',');)
    if (!Trim(bag).empty())
      e.recording +=
          (e.recording.empty() ? "" : ", ") + std::filesystem::path(Trim(bag)).filename().string();
  e.report_dir = p.String("report_dir", e.report_dir);
  e.report_on_shutdown = p.Bool("report_on_shutdown", e.report_on_shutdown);
  e.report_formats = p.StringList("report_formats", e.report_formats);
  e.enable_export_report = p.Bool("enable_export_report", e.enable_export_report);
  e.enable_set_reference_epoch = p.Bool("enable_set_reference_epoch", e.enable_set_reference_epoch);
  for (const std::string& f : e.report_formats)
    if (f != "csv" && f != "geojson" && f != "geotiff" && f != "gpkg" && f != "png")
      throw ConfigError(
          Message("parameter '", p.FullKey("report_formats"), "' has unknown format '", f, "'"));
  e.velocity_unit = p.String("velocity_unit", e.velocity_unit, {"mm/day", "mm/h"});
  const std::string& unit = e.velocity_unit;
  const double to_si = unit == "mm/day" ? 1e-3 / 86400.0 : 1e-3 / 3600.0;
  // The thresholds' defaults (deformation::Thresholds, m/s) in the chosen unit.
  deformation::Thresholds& th = o->alerts.thresholds;
  th.watch = p.Double("threshold_watch", th.watch / to_si, 0.0, 1e6, unit) * to_si;
  th.warning = p.Double("threshold_warning", th.warning / to_si, 0.0, 1e6, unit) * to_si;
  th.alarm = p.Double("threshold_alarm", th.alarm / to_si, 0.0, 1e6, unit) * to_si;
  th.displacement_watch =
      p.Double("threshold_displacement_watch", th.displacement_watch * 1e3, 0.0, 1e7, "mm") * 1e-3;
  th.displacement_warning =
      p.Double("threshold_displacement_warning", th.displacement_warning * 1e3, 0.0, 1e7, "mm") *
      1e-3;
  th.displacement_alarm =
      p.Double("threshold_displacement_alarm", th.displacement_alarm * 1e3, 0.0, 1e7, "mm") * 1e-3;
  e.point_thresholds = p.StringList("point_thresholds", e.point_thresholds);
  for (const std::string& entry : e.point_thresholds) {
    // "point_id: watch, warning, alarm" in velocity_unit
    const size_t colon = entry.rfind(':');
    std::vector<double> v;
    if (colon != std::string::npos) {
      std::stringstream ss(entry.substr(colon + 1));
      std::string item;
      while (std::getline(ss, item, ',')) {
        try {
          v.push_back(std::stod(item));
        } catch (const std::exception&) {
          v.clear();
          break;
        }
      }
    }
    if (colon == std::string::npos || v.size() != 3 || Trim(entry.substr(0, colon)).empty())
      throw ConfigError(Message("parameter '", p.FullKey("point_thresholds"), "' entry '", entry,
                                "' must read 'point_id: watch, warning, alarm' (", unit, ")"));
    deformation::Thresholds t = th;  // the displacement thresholds of the site
    t.watch = v[0] * to_si;
    t.warning = v[1] * to_si;
    t.alarm = v[2] * to_si;
    o->alerts.point_thresholds[Trim(entry.substr(0, colon))] = t;
  }
  e.aliases = p.StringList("aliases", e.aliases);
  for (const std::string& entry : e.aliases) {
    const size_t eq = entry.find('=');
    if (eq == std::string::npos || Trim(entry.substr(0, eq)).empty() ||
        Trim(entry.substr(eq + 1)).empty())
      throw ConfigError(Message("parameter '", p.FullKey("aliases"), "' entry '", entry,
                                "' must read 'measured_id = monitoring_point_id'"));
    o->aliases[Trim(entry.substr(0, eq))] = Trim(entry.substr(eq + 1));
  }
  o->alerts.significance =
      p.Double("alert_significance", o->alerts.significance, 0.0, 10.0, "sigma");
  o->alerts.confirm_points = p.Int("confirm_points", o->alerts.confirm_points, 1, 1000);
  o->alerts.confirm_sources = p.Int("confirm_sources", o->alerts.confirm_sources, 1, 10);
  o->alerts.hysteresis = p.Double("hysteresis", o->alerts.hysteresis, 0.01, 1.0);
  o->filter.jerk_spectral_density =
      p.Double("jerk_spectral_density", o->filter.jerk_spectral_density, 0.0, 1e-20, "m^2/s^5");
  o->filter.initial_velocity_sigma =
      p.Double("initial_velocity_sigma", o->filter.initial_velocity_sigma, 1e-12, 1.0, "m/s");
  o->filter.initial_acceleration_sigma = p.Double(
      "initial_acceleration_sigma", o->filter.initial_acceleration_sigma, 1e-18, 1.0, "m/s^2");
  o->filter.origin_velocity_sigma =
      p.Double("origin_velocity_sigma", o->filter.origin_velocity_sigma, 1e-9, 1.0, "m/s");
  o->reorder_window = p.Double("reorder_window", o->reorder_window, 0.0, 365 * 86400.0, "s");
  o->reference_tolerance =
      p.Double("reference_tolerance", o->reference_tolerance, 0.0, 30 * 86400.0, "s");
  o->disagreement_threshold =
      p.Double("disagreement_threshold", o->disagreement_threshold, 0.1, 1e6, "chi2(3)");
  o->comparison_max_gap =
      p.Double("comparison_max_gap", o->comparison_max_gap, 1.0, 365 * 86400.0, "s");
  o->innovation_gate = p.Double("innovation_gate", o->innovation_gate, 0.0, 1e6, "chi2(3)");
  o->velocity_sample_interval =
      p.Double("velocity_sample_interval", o->velocity_sample_interval, 1.0, 86400.0, "s");
  o->forecast.window =
      p.Double("forecast_window", o->forecast.window / 3600.0, 0.1, 24.0 * 365, "h") * 3600.0;
  o->forecast.alpha = p.Double("forecast_alpha", o->forecast.alpha, 1.01, 10.0);
  o->forecast.min_samples = p.Int("forecast_min_samples", o->forecast.min_samples, 4, 100000);
  o->forecast.min_velocity =
      p.Double("forecast_min_velocity", o->forecast.min_velocity / to_si, 0.0, 1e6, unit) * to_si;
  o->forecast.significance =
      p.Double("forecast_significance", o->forecast.significance, 0.0, 100.0, "sigma");
  o->forecast.max_horizon =
      p.Double("forecast_max_horizon", o->forecast.max_horizon / 86400.0, 0.01, 3650.0, "days") *
      86400.0;
  e.geodetic_origin = p.DoubleList("geodetic_origin", e.geodetic_origin);
  const std::vector<double>& origin = e.geodetic_origin;
  if (!origin.empty()) {
    if (origin.size() != 3 || std::abs(origin[0]) > 90 || std::abs(origin[1]) > 180)
      throw ConfigError(Message("parameter '", p.FullKey("geodetic_origin"),
                                "' must be [] or [lat_deg, lon_deg, height_m]"));
    e.report.geodetic_origin = Eigen::Vector3d(origin[0], origin[1], origin[2]);
  }
  e.report.grid_resolution =
      p.Double("report_grid_resolution", e.report.grid_resolution, 0.01, 1000.0, "m");
  e.report.grid_margin = p.Double("report_grid_margin", e.report.grid_margin, 0.0, 10000.0, "m");
  e.report.idw_power = p.Double("report_idw_power", e.report.idw_power, 0.1, 10.0);
  e.report.idw_radius = p.Double("report_idw_radius", e.report.idw_radius, 0.1, 1e5, "m");
  e.report.map_width = p.Int("report_map_width", e.report.map_width, 200, 8000, "px");
  e.markers.arrow_scale = p.Double("marker_arrow_scale", e.markers.arrow_scale, 0.0, 1e6);
  e.markers.text_size = p.Double("marker_text_size", e.markers.text_size, 0.01, 100.0, "m");
  e.markers.point_size = p.Double("marker_point_size", e.markers.point_size, 0.01, 100.0, "m");
  e.report_interval = p.Double("report_interval", e.report_interval, 0.0, 30 * 86400.0, "s");
  e.order_timeout = p.Double("order_timeout", e.order_timeout, 0.0, 86400.0, "s");
  e.report_on_alert_change = p.Bool("report_on_alert_change", e.report_on_alert_change);
  e.plot.script = p.String("plot_script", e.plot.script);
  e.plot.dem = p.String("report_dem", e.plot.dem);
  e.site_file = p.String("site_file", e.site_file);
  e.database = ReadDatabase(p, e.site_file, "", &e.site_name);
  p.CheckNoUnknownKeys();
  if (!e.site_file.empty()) {
    e.site = io::LoadSiteFile(e.site_file);
    deformation::ApplySite(*e.site, o, &e.report);
    e.plot.site = e.site->name;
  }
  e.report.Check();
  o->Check();
  return e;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
