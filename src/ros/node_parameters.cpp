#include "slope_monitor/ros/node_parameters.h"

#include "slope_monitor/core/adjustment/site_options.h"
#include "slope_monitor/core/deformation/site_options.h"
#include "slope_monitor/core/io/site_file.h"

#include <cmath>
#include <sstream>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/sim/truth.h"
#include "slope_monitor/ros/uav_topics.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

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

}  // namespace

AdjusterParameters ReadAdjusterParameters(ParamReader& p) {
  AdjusterParameters a;
  // The site file (io::LoadSiteFile) gives the targets when it lists them
  // (target_list is then not read: replay.launch defaults it to the bag's),
  // and each camera's pixel size and kind.
  const std::string site_file = p.String("site_file", "");
  std::optional<io::SiteFile> site;
  if (!site_file.empty()) site = io::LoadSiteFile(site_file);
  a.target_list_path = p.String("target_list", "");
  if (site && site->targets) {
    a.targets = *site->targets;
    a.target_list_path =
        site->targets_file.empty() ? site_file + " (inline targets)" : site->targets_file;
  } else if (!a.target_list_path.empty()) {
    a.targets = io::TargetList::Load(a.target_list_path);
  } else if (site) {
    // A site without targets (a UAV flight oriented by its tie points and
    // GNSS, fixed_targetless cameras) is a normal site: no target list.
    a.target_list_path = site_file + " (no targets)";
  } else {
    throw ConfigError("parameter '" + p.FullKey("target_list") + "' is required (or '" +
                      p.FullKey("site_file") + "' naming a site file with targets)");
  }
  // The camera kind is the site file's field, not the name.
  if (site) a.pixel_size_by_camera = adjustment::ApplySite(*site, &a.collector, &a.scene);
  std::vector<std::string> site_cameras, site_targets, site_epochs;
  a.prior_topics = {"position_prior"};
  a.tie_topics = {"tie_points"};
  if (site) {
    std::vector<std::string> priors, ties;
    for (const io::SiteCamera* cam : site->CamerasWithTargets()) {
      site_cameras.push_back(cam->name);
      site_targets.push_back("/" + cam->name + "/targets");
      site_epochs.push_back("/" + cam->name + "/camera/epoch");
      if (cam->kind == io::CameraKind::kUav) {
        priors.push_back(UavCameraTopics(cam->name).prior);
        ties.push_back(UavCameraTopics(cam->name).tie_points);
      }
    }
    if (!site_cameras.empty()) {
      a.prior_topics = priors;
      a.tie_topics = ties;
    }
  }
  // A site file that lists cameras decides them (cameras, target_topics and
  // epoch_topics are then not used, as target_list is not).
  a.cameras_from_site = !site_cameras.empty();
  adjustment::EpochCollectorOptions& c = a.collector;
  a.target_topics = p.StringList("target_topics", {"targets"});
  c.cameras = p.StringList("cameras", {});
  a.epoch_topics = p.StringList("epoch_topics", {"epoch"});
  if (a.cameras_from_site) {
    c.cameras = site_cameras;
    a.target_topics = site_targets;
    a.epoch_topics = site_epochs;
  }
  c.epoch_wait = p.Double("epoch_wait", 30.0, 0.0, 3600.0, "s");
  // The UAV cameras' photos wait for their tie points (replay.launch
  // uav_tie_points:=true, process_bag --uav-tie-points).
  if (p.Bool("uav_tie_points", false)) c.tie_point_cameras = c.uav_cameras;
  c.tie_point_wait = p.Double("tie_point_wait", 300.0, 0.0, 86400.0, "s");
  c.tie_pixel_sigma_floor = p.Double("tie_pixel_sigma_floor", 0.2, 0.0, 100.0, "px");
  c.min_tie_quality = p.Double("min_tie_quality", 0.25, 0.0, 1.0);
  a.frame_id = p.String("frame_id", "site");
  a.enable_run_adjustment = p.Bool("enable_run_adjustment", true);
  a.enable_set_reference_epoch = p.Bool("enable_set_reference_epoch", true);
  a.pixel_size = p.Double("pixel_size", 1.0, 1e-6, 1.0, "mm/px");
  c.pixel_sigma = p.Double("pixel_sigma", 0.3, 1e-4, 100.0, "px");
  c.pixel_sigma_floor = p.Double("pixel_sigma_floor", 0.05, 0.0, 100.0, "px");
  c.uav_pixel_sigma_floor = p.Double("uav_pixel_sigma_floor", 1.0, 0.0, 100.0, "px");
  c.epoch_gap = p.Double("epoch_gap", 600.0, 0.0, 1e7, "s");
  c.Check();
  a.scene.position_prior_max_dt = p.Double("position_prior_max_dt", 0.1, 0.0, 10.0, "s");
  a.scene.position_prior_min_sigma = p.Double("position_prior_min_sigma", 0.01, 1e-4, 100.0, "m");
  a.scene.min_images = p.Int("min_images", 2, 1, 10000);
  a.scene.attitude_prior_max_sigma =
      p.Double("attitude_prior_max_sigma", a.scene.attitude_prior_max_sigma * 180.0 / M_PI, 0.0, 180.0, "deg") *
      M_PI / 180.0;
  a.scene.Check();
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
  adjustment::EpochAdjustmentOptions& e = a.epoch;
  e.free_interior = interior_list("free_interior");
  const std::vector<int> uav_free_interior = interior_list("uav_free_interior");
  adjustment::Options& o = e.adjustment;
  o.loss = p.String("loss", "huber", {"none", "huber", "cauchy"});
  o.loss_scale = p.Double("loss_scale", 3.0, 1e-3, 1e3, "sigma");
  o.outlier_threshold = p.Double("outlier_threshold", 5.0, 1e-3, 1e3, "sigma");
  o.linear_solver =
      p.String("linear_solver", "auto", {"auto", "dense_schur", "sparse_schur", "iterative_schur"});
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
  e.max_tie_outlier_share = p.Double("max_tie_outlier_share", e.max_tie_outlier_share, 1e-3, 1.0);
  e.naming.gate_sigma = p.Double("naming_gate_sigma", 3.0, 0.1, 100.0, "sigma");
  e.naming.gate_extra_px = p.Double("naming_gate_extra_px", 10.0, 0.0, 10000.0, "px");
  e.naming.coarse_extra_px = p.Double("naming_coarse_extra_px", 100.0, 0.0, 10000.0, "px");
  e.naming.ambiguity_factor = p.Double("naming_ambiguity_factor", 2.0, 1.0, 100.0);
  e.Check();
  a.displacement.stable_threshold = p.Double("stable_threshold", 0.02, 1e-6, 100.0, "m");
  a.displacement.significance_threshold = p.Double("significance_threshold", 3.0, 0.1, 100.0);
  a.displacement.estimate_scale = p.Bool("coregistration_scale", false);
  a.displacement.Check();
  a.frustums.depth = p.Double("frustum_depth", a.frustums.depth, 1e-3, 1e4, "m");
  a.frustums.line_width = p.Double("frustum_line_width", a.frustums.line_width, 1e-3, 100.0, "m");
  a.frustums.uav_cameras = c.uav_cameras;
  a.frustums.Check();
  p.CheckNoUnknownKeys();
  return a;
}

RadioParameters ReadRadioParameters(ParamReader& p) {
  RadioParameters r;
  const std::string network_file = p.String("network_file", "");
  const std::string site_file = p.String("site_file", "");  // its radio_network, when it names one
  const std::string truth_file = p.String("truth_file", "");
  const double truth_sigma = p.Double("truth_initial_sigma", 0.005, 1e-5, 10.0, "m");
  const double truth_rate = p.Double("truth_sample_rate", 20000.0, 1.0, 1e10, "Hz");
  radio::RadioSolverOptions& o = r.options;
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
  r.stamp_tolerance = p.Double("stamp_tolerance", 1e-3, 0.0, 10.0, "s");
  r.max_wait = p.Double("max_wait", 2.5, 0.0, 86400.0, "s");
  r.frame_id = p.String("frame_id", "site");
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
  if (network_file.empty() && truth_file.empty()) return r;
  if (network_file.empty() == truth_file.empty())
    throw ConfigError(p.FullKey("network_file") + " / " + p.FullKey("truth_file") +
                      ": set exactly one of them");
  r.has_network = true;
  if (!network_file.empty()) {
    r.network = radio::NetworkConfig::Load(network_file);
  } else {
    r.network =
        NetworkFromTruth(sim::SurveyTruth::Load(truth_file), truth_sigma, truth_rate, truth_file);
  }
  return r;
}

EstimatorParameters ReadEstimatorParameters(ParamReader& p) {
  EstimatorParameters e;
  deformation::EstimatorOptions* o = &e.options;
  e.input_topics = p.StringList("input_topics", {"displacements"});
  if (e.input_topics.empty())
    throw ConfigError(Message("parameter '", p.FullKey("input_topics"), "' is empty"));
  e.area_topics = p.StringList("area_topics", {});
  o->areas.growth_watch = p.Double("area_growth_watch", o->areas.growth_watch, 1e-6, 1e9, "m^2");
  o->areas.growth_warning =
      p.Double("area_growth_warning", o->areas.growth_warning, 1e-6, 1e9, "m^2");
  e.frame_id = p.String("frame_id", "site");
  e.database = p.String("database", "");
  e.report_dir = p.String("report_dir", "");
  e.report_on_shutdown = p.Bool("report_on_shutdown", true);
  e.report_formats = p.StringList("report_formats", {});
  e.enable_export_report = p.Bool("enable_export_report", true);
  e.enable_set_reference_epoch = p.Bool("enable_set_reference_epoch", true);
  for (const std::string& f : e.report_formats)
    if (f != "csv" && f != "geojson" && f != "geotiff" && f != "gpkg" && f != "png")
      throw ConfigError(
          Message("parameter '", p.FullKey("report_formats"), "' has unknown format '", f, "'"));
  const std::string unit = p.String("velocity_unit", "mm/day", {"mm/day", "mm/h"});
  const double to_si = unit == "mm/day" ? 1e-3 / 86400.0 : 1e-3 / 3600.0;
  // Defaults 2 / 10 / 50 mm/day, expressed in the chosen unit.
  const double per_day = unit == "mm/day" ? 1.0 : 1.0 / 24.0;
  o->alerts.thresholds.watch = p.Double("threshold_watch", 2.0 * per_day, 0.0, 1e6, unit) * to_si;
  o->alerts.thresholds.warning =
      p.Double("threshold_warning", 10.0 * per_day, 0.0, 1e6, unit) * to_si;
  o->alerts.thresholds.alarm = p.Double("threshold_alarm", 50.0 * per_day, 0.0, 1e6, unit) * to_si;
  for (const std::string& entry : p.StringList("point_thresholds", {})) {
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
    deformation::Thresholds t;
    t.watch = v[0] * to_si;
    t.warning = v[1] * to_si;
    t.alarm = v[2] * to_si;
    o->alerts.point_thresholds[Trim(entry.substr(0, colon))] = t;
  }
  for (const std::string& entry : p.StringList("aliases", {})) {
    const size_t eq = entry.find('=');
    if (eq == std::string::npos || Trim(entry.substr(0, eq)).empty() ||
        Trim(entry.substr(eq + 1)).empty())
      throw ConfigError(Message("parameter '", p.FullKey("aliases"), "' entry '", entry,
                                "' must read 'measured_id = monitoring_point_id'"));
    o->aliases[Trim(entry.substr(0, eq))] = Trim(entry.substr(eq + 1));
  }
  o->alerts.significance = p.Double("alert_significance", 3.0, 0.0, 10.0, "sigma");
  o->alerts.confirm_points = p.Int("confirm_points", 2, 1, 1000);
  o->alerts.confirm_sources = p.Int("confirm_sources", 2, 1, 10);
  o->alerts.hysteresis = p.Double("hysteresis", 0.8, 0.01, 1.0);
  o->filter.jerk_spectral_density = p.Double("jerk_spectral_density", 1e-25, 0.0, 1e-20, "m^2/s^5");
  o->filter.initial_velocity_sigma = p.Double("initial_velocity_sigma", 1e-6, 1e-12, 1.0, "m/s");
  o->filter.initial_acceleration_sigma =
      p.Double("initial_acceleration_sigma", 1e-10, 1e-18, 1.0, "m/s^2");
  o->reorder_window = p.Double("reorder_window", 3 * 86400.0, 0.0, 365 * 86400.0, "s");
  o->reference_tolerance = p.Double("reference_tolerance", 3600.0, 0.0, 30 * 86400.0, "s");
  o->disagreement_threshold = p.Double("disagreement_threshold", 16.27, 0.1, 1e6, "chi2(3)");
  o->comparison_max_gap = p.Double("comparison_max_gap", 86400.0, 1.0, 365 * 86400.0, "s");
  o->innovation_gate = p.Double("innovation_gate", 0.0, 0.0, 1e6, "chi2(3)");
  o->velocity_sample_interval = p.Double("velocity_sample_interval", 3600.0, 1.0, 86400.0, "s");
  o->forecast.window = p.Double("forecast_window", 48.0, 0.1, 24.0 * 365, "h") * 3600.0;
  o->forecast.alpha = p.Double("forecast_alpha", 2.0, 1.01, 10.0);
  o->forecast.min_samples = p.Int("forecast_min_samples", 6, 4, 100000);
  o->forecast.min_velocity = p.Double("forecast_min_velocity", 0.0, 0.0, 1e6, unit) * to_si;
  o->forecast.significance = p.Double("forecast_significance", 3.0, 0.0, 100.0, "sigma");
  o->forecast.max_horizon = p.Double("forecast_max_horizon", 365.0, 0.01, 3650.0, "days") * 86400.0;
  const std::vector<double> origin = p.DoubleList("geodetic_origin", {});
  if (!origin.empty()) {
    if (origin.size() != 3 || std::abs(origin[0]) > 90 || std::abs(origin[1]) > 180)
      throw ConfigError(Message("parameter '", p.FullKey("geodetic_origin"),
                                "' must be [] or [lat_deg, lon_deg, height_m]"));
    e.report.geodetic_origin = Eigen::Vector3d(origin[0], origin[1], origin[2]);
  }
  e.report.grid_resolution = p.Double("report_grid_resolution", 1.0, 0.01, 1000.0, "m");
  e.report.grid_margin = p.Double("report_grid_margin", 10.0, 0.0, 10000.0, "m");
  e.report.idw_power = p.Double("report_idw_power", 2.0, 0.1, 10.0);
  e.report.idw_radius = p.Double("report_idw_radius", 50.0, 0.1, 1e5, "m");
  e.report.map_width = p.Int("report_map_width", 1200, 200, 8000, "px");
  e.markers.arrow_scale = p.Double("marker_arrow_scale", e.markers.arrow_scale, 0.0, 1e6);
  e.markers.text_size = p.Double("marker_text_size", e.markers.text_size, 0.01, 100.0, "m");
  e.markers.point_size = p.Double("marker_point_size", e.markers.point_size, 0.01, 100.0, "m");
  e.report_interval = p.Double("report_interval", 0.0, 0.0, 30 * 86400.0, "s");
  e.order_timeout = p.Double("order_timeout", 300.0, 0.0, 86400.0, "s");
  e.report_on_alert_change = p.Bool("report_on_alert_change", false);
  e.plot.script = p.String("plot_script", "");
  e.plot.dem = p.String("report_dem", "");
  const std::string site_file = p.String("site_file", "");
  p.CheckNoUnknownKeys();
  if (!site_file.empty()) {
    e.site = io::LoadSiteFile(site_file);
    deformation::ApplySite(*e.site, o, &e.report);
    e.plot.site = e.site->name;
  }
  e.report.Check();
  o->Check();
  return e;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
