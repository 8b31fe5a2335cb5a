// Reading config/sim/*.yaml into a SurveyConfig (every key documented in
// config/sim/demo_site.yaml).
#include <cmath>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/io/yaml_map.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace sim {
namespace {

Eigen::Vector2d Vec2(io::YamlMap& m, const std::string& key) {
  const auto v = m.RequiredDoubles(key, 2);
  return Eigen::Vector2d(v[0], v[1]);
}

Eigen::Vector3d Vec3(io::YamlMap& m, const std::string& key) {
  const auto v = m.RequiredDoubles(key, 3);
  return Eigen::Vector3d(v[0], v[1], v[2]);
}

camera::CameraModel ReadInterior(io::YamlMap& cam, const camera::Sensor& sensor,
                                 const std::string& key, camera::DistortionModel dm) {
  io::YamlMap in = cam.Map(key);
  std::array<double, camera::kNumInterior> a{};
  a[camera::kC] = in.RequiredDouble("c", 0.5, 1000.0, "mm");
  a[camera::kX0] = in.Double("x0", 0.0, -5.0, 5.0, "mm");
  a[camera::kY0] = in.Double("y0", 0.0, -5.0, 5.0, "mm");
  a[camera::kK1] = in.Double("k1", 0.0, -1.0, 1.0, "mm^-2");
  a[camera::kK2] = in.Double("k2", 0.0, -1.0, 1.0, "mm^-4");
  a[camera::kK3] = in.Double("k3", 0.0, -1.0, 1.0, "mm^-6");
  a[camera::kP1] = in.Double("p1", 0.0, -0.1, 0.1, "mm^-1");
  a[camera::kP2] = in.Double("p2", 0.0, -0.1, 0.1, "mm^-1");
  a[camera::kB1] = in.Double("b1", 0.0, -0.1, 0.1);
  a[camera::kB2] = in.Double("b2", 0.0, -0.1, 0.1);
  in.CheckNoUnknownKeys();
  camera::CameraModel m(sensor, dm, a);
  try {
    m.Check();
  } catch (const InvalidArgument& e) {
    cam.Fail(key, e.what());
  }
  return m;
}

ExposureOptions ReadExposure(io::YamlMap& cam, CameraSpec* spec) {
  io::YamlMap e = cam.OptionalMap("exposure");
  ExposureOptions o;
  o.gain = e.Double("gain", o.gain, 1.0, 2000.0, "DN");
  o.vignetting = e.Double("vignetting", o.vignetting, 0.0, 0.9);
  o.read_noise = e.Double("read_noise", o.read_noise, 0.0, 50.0, "DN");
  o.shot_noise = e.Double("shot_noise", o.shot_noise, 0.0, 5.0, "DN/DN");
  o.noise = e.Bool("noise", true);
  spec->exposure_jitter = e.Double("jitter", spec->exposure_jitter, 0.0, 0.5);
  for (io::YamlMap& j : e.List("jumps")) {
    const int epoch = j.RequiredInt("epoch", 0, 1000);
    spec->exposure_jumps[epoch] = j.RequiredDouble("factor", 0.05, 20.0);
    j.CheckNoUnknownKeys();
  }
  e.CheckNoUnknownKeys();
  return o;
}

}  // namespace

namespace {
SurveyConfig FromRoot(io::YamlMap& root);
}  // namespace

SurveyConfig SurveyConfig::Load(const std::string& path) {
  io::YamlMap root = io::YamlMap::Load(path);
  return FromRoot(root);
}

SurveyConfig SurveyConfig::Parse(const std::string& yaml_text, const std::string& context) {
  io::YamlMap root = io::YamlMap::Parse(yaml_text, context);
  return FromRoot(root);
}

namespace {

// site: geodetic origin, extent and the terrain.
void ReadSiteSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap site = root.Map("site");
  std::string stem =
      c.path.substr(c.path.find_last_of('/') + 1);  // demo_site.sim.yaml -> demo_site
  stem = stem.substr(0, stem.find('.'));
  c.name = site.String("name", stem.empty() ? "simulated_site" : stem);
  if (c.name.empty() || c.name.find_first_of("/ \t") != std::string::npos)
    site.Fail("name", "must be a non-empty name without '/' or spaces");
  const auto o = site.Doubles("origin", {46.5, 8.0, 1200.0}, 3);
  c.origin = Eigen::Vector3d(o[0], o[1], o[2]);
  if (std::abs(o[0]) > 90.0) site.Fail("origin", "latitude must be in [-90, 90] deg");
  const auto e = site.Doubles("extent", {0.0, 200.0, 0.0, 150.0}, 4);
  if (!(e[1] > e[0] && e[3] > e[2]))
    site.Fail("extent", "must be [xmin, xmax, ymin, ymax] with xmax > xmin, ymax > ymin");
  if ((e[1] - e[0]) > 5000.0 || (e[3] - e[2]) > 5000.0) site.Fail("extent", "is larger than 5 km");
  TerrainOptions& t = c.scene.terrain;
  t.extent = Eigen::Vector4d(e[0], e[1], e[2], e[3]);
  t.grid_spacing = site.Double("grid_spacing", t.grid_spacing, 0.05, 10.0, "m");
  const double cells = (e[1] - e[0]) / t.grid_spacing * (e[3] - e[2]) / t.grid_spacing;
  if (cells > 4e6) site.Fail("grid_spacing", Message("gives ", cells, " cells (more than 4e6)"));
  t.relief = site.Double("relief", t.relief, 0.0, 1000.0, "m");
  t.undulation = site.Double("undulation", t.undulation, 0.0, 50.0, "m");
  t.undulation_wavelength =
      site.Double("undulation_wavelength", t.undulation_wavelength, 1.0, 2000.0, "m");
  c.surface_cell = t.grid_spacing;
  site.CheckNoUnknownKeys();
}

// texture and lighting (optional).
void ReadTextureAndLighting(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap tx = root.OptionalMap("texture");
  TextureOptions& t = c.scene.texture;
  t.contrast = tx.Double("contrast", t.contrast, 0.0, 1.0);
  t.vegetation_fraction = tx.Double("vegetation_fraction", t.vegetation_fraction, 0.0, 1.0);
  t.rock_fraction = tx.Double("rock_fraction", t.rock_fraction, 0.0, 1.0);
  t.finest_wavelength = tx.Double("finest_wavelength", t.finest_wavelength, 0.001, 10.0, "m");
  t.coarsest_wavelength =
      tx.Double("coarsest_wavelength", t.coarsest_wavelength, t.finest_wavelength, 1000.0, "m");
  tx.CheckNoUnknownKeys();
  io::YamlMap li = root.OptionalMap("lighting");
  const double az = li.Double("sun_azimuth_deg", 200.0, -360.0, 360.0, "deg") * kRadPerDeg;
  const double el = li.Double("sun_elevation_deg", 45.0, 1.0, 90.0, "deg") * kRadPerDeg;
  // Azimuth clockwise from north (as a compass): x = sin, y = cos.
  c.scene.lighting.sun =
      Eigen::Vector3d(std::cos(el) * std::sin(az), std::cos(el) * std::cos(az), std::sin(el));
  c.scene.lighting.ambient = li.Double("ambient", 0.35, 0.0, 1.0);
  c.scene.lighting.sky = li.Double("sky", 0.85, 0.0, 1.5);
  li.CheckNoUnknownKeys();
}

// epochs (optional): count, start time and interval.
void ReadEpochSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap ep = root.OptionalMap("epochs");
  c.num_epochs = ep.Int("count", c.num_epochs, 1, 100);
  c.start_time = ep.Double("start_time", c.start_time, 1.0, 4e9, "s");
  c.epoch_interval = ep.Double("interval", c.epoch_interval, 60.0, 3.2e7, "s");
  ep.CheckNoUnknownKeys();
}

// landslide: the moving body and its scarp.
void ReadLandslideSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap ls = root.Map("landslide");
  LandslideModel& l = c.scene.landslide;
  l.centre = Vec2(ls, "centre");
  l.length = ls.RequiredDouble("length", 1.0, 2000.0, "m");
  l.width = ls.RequiredDouble("width", 1.0, 2000.0, "m");
  l.taper = ls.Double("taper", 0.25, 0.01, 1.0);
  l.azimuth = ls.Double("azimuth_deg", -90.0, -360.0, 360.0, "deg") * kRadPerDeg;
  l.plunge = ls.Double("plunge_deg", 20.0, -89.0, 89.0, "deg") * kRadPerDeg;
  const std::string model = ls.String("model", "constant", {"constant", "accelerating"});
  l.velocity = LandslideModel::VelocityFromName(model);
  l.velocity0 = ls.Double("velocity", 0.05, 0.0, 100.0, "m/day") / 86400.0;
  l.reference_time = c.start_time;
  const double failure_after = ls.Double("failure_after", 2.0, 0.001, 36500.0, "day");
  l.failure_time = l.velocity == LandslideModel::Velocity::kAccelerating
                       ? c.start_time + failure_after * 86400.0
                       : 0.0;
  if (l.velocity == LandslideModel::Velocity::kAccelerating &&
      l.failure_time <= c.start_time + (c.num_epochs - 1) * c.epoch_interval + 3600.0) {
    ls.Fail("failure_after", Message("= ", failure_after,
                                     " day falls before the last epoch (+1 h); "
                                     "the displacement is infinite at failure"));
  }
  c.scene.scarp.depth = ls.Double("scarp_depth", 3.0, 0.0, 50.0, "m");
  c.scene.scarp.band = ls.Double("scarp_band", 0.05, 0.005, 0.5);
  c.scene.scarp.head_fraction = ls.Double("scarp_head_fraction", 0.0, -1.0, 1.0);
  ls.CheckNoUnknownKeys();
}

// obstacles (optional): trees and boulders.
void ReadObstacleSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  std::vector<io::YamlMap> list = root.List("obstacles");
  for (io::YamlMap& o : list) {
    Obstacle ob;
    ob.kind = Obstacle::KindFromName(o.String("kind", "boulder", {"tree", "boulder"}));
    const Eigen::Vector2d xy = Vec2(o, "position");
    ob.base = Eigen::Vector3d(xy.x(), xy.y(), std::nan(""));
    ob.radius = o.Double("radius", ob.kind == Obstacle::Kind::kTree ? 2.0 : 1.0, 0.1, 20.0, "m");
    ob.height = o.Double("height", ob.kind == Obstacle::Kind::kTree ? 8.0 : 0.5 * ob.radius, 0.0,
                         60.0, "m");
    o.CheckNoUnknownKeys();
    c.scene.obstacles.push_back(ob);
  }
}

// targets: survey noise and the target list.
void ReadTargetSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap tg = root.Map("targets");
  const auto sigma = tg.Doubles("survey_sigma", {0.03, 0.01}, 2);
  if (sigma[0] < 0 || sigma[1] < 0) tg.Fail("survey_sigma", "must be >= 0");
  c.survey_sigma = Eigen::Vector2d(sigma[0], sigma[1]);
  c.monitoring_approx_sigma = tg.Double("monitoring_approx_sigma", 0.0, 0.0, 10.0, "m");
  const double mount = tg.Double("mount_height", 0.03, 0.0, 2.0, "m");
  const double tag_size = tg.Double("tag_size", 1.0, 0.05, 10.0, "m");
  const double circle_size = tg.Double("circle_size", 0.5, 0.05, 10.0, "m");
  const bool facing_default = tg.Has("face_toward");
  const Eigen::Vector3d face_default =
      facing_default ? Vec3(tg, "face_toward") : Eigen::Vector3d::Zero();
  std::vector<io::YamlMap> list = tg.List("list");
  if (list.empty()) tg.Fail("list", "is empty (the survey needs targets)");
  for (io::YamlMap& t : list) {
    TargetPlacement p;
    p.family = t.String("family", "tag36h11", {"tag36h11", "circle"});
    p.id = t.RequiredInt("id", 0, 100000);
    p.role =
        io::TargetRoleFromName(t.String("role", "control", {"control", "monitoring", "check"}));
    p.xy = Vec2(t, "position");
    p.size = t.Double("size", p.family == "circle" ? circle_size : tag_size, 0.05, 10.0, "m");
    p.mount_height = t.Double("mount_height", mount, 0.0, 2.0, "m");
    p.facing = facing_default || t.Has("face_toward");
    p.face_toward = t.Has("face_toward") ? Vec3(t, "face_toward") : face_default;
    if (p.family == "tag36h11" && p.id >= 587)
      t.Fail("id", Message("= ", p.id, " is outside tag36h11's 587 codes"));
    const std::string key = p.family + "/" + std::to_string(p.id);
    for (const auto& q : c.scene.targets) {
      if (q.family + "/" + std::to_string(q.id) == key)
        t.Fail("id", Message("duplicates target ", key));
    }
    c.target_keys_for_error.push_back(t.context());
    t.CheckNoUnknownKeys();
    c.scene.targets.push_back(p);
  }
  tg.CheckNoUnknownKeys();
}

// cameras: one CameraSpec each (ReadCameraSpec).
void ReadCameraSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  std::vector<io::YamlMap> list = root.List("cameras");
  for (io::YamlMap& cm : list) {
    CameraSpec s;
    s.key = cm.context();
    s.name = cm.RequiredString("name");
    s.kind = cm.String("kind", "fixed", {"fixed", "fixed_targetless", "uav"});
    s.encoding = cm.String("encoding", "mono8", {"mono8", "bgr8"});
    io::YamlMap sensor_map = cm.Map("sensor");
    camera::Sensor sensor;
    sensor.width = sensor_map.RequiredInt("width", 16, 10000, "px");
    sensor.height = sensor_map.RequiredInt("height", 16, 10000, "px");
    sensor.pixel_size = sensor_map.RequiredDouble("pixel_size", 1e-4, 0.1, "mm");
    sensor_map.CheckNoUnknownKeys();
    camera::DistortionModel dm;
    const std::string dm_name =
        cm.String("distortion_model", "brown", {"none", "radial", "brown", "brown_affinity"});
    dm = camera::DistortionModelFromName(dm_name);
    s.model = ReadInterior(cm, sensor, "interior", dm);
    // Nominal: what the camera_info says (a rounded principal distance, no distortion unless
    // given).
    if (cm.Has("nominal_interior")) {
      s.nominal = ReadInterior(cm, sensor, "nominal_interior", dm);
    } else {
      std::array<double, camera::kNumInterior> a{};
      a[camera::kC] = s.model.principal_distance();
      s.nominal = camera::CameraModel(sensor, dm, a);
    }
    s.exposure = ReadExposure(cm, &s);
    if (s.kind != "uav") {  // fixed, fixed_targetless
      const Eigen::Vector3d position = Vec3(cm, "position");
      const Eigen::Vector3d look_at = Vec3(cm, "look_at");
      if ((look_at - position).norm() < 1.0)
        cm.Fail("look_at", "is less than 1 m from the camera position");
      const double roll = cm.Double("roll_deg", 0.0, -180.0, 180.0, "deg") * kRadPerDeg;
      s.pose = LookAt(position, look_at, Eigen::Vector3d::UnitZ(), roll);
      s.jitter_position = cm.Double("jitter_position", s.jitter_position, 0.0, 1.0, "m");
      s.jitter_angle =
          cm.Double("jitter_angle_deg", s.jitter_angle / kRadPerDeg, 0.0, 5.0, "deg") * kRadPerDeg;
      const std::vector<double> turn = cm.Doubles("mast_rotation_deg", {0.0, 0.0});
      if (turn.size() != 2 || !(turn[0] >= 0.0) || !(turn[1] >= turn[0]) || !(turn[1] <= 5.0))
        cm.Fail("mast_rotation_deg", "must be [min, max] with 0 <= min <= max <= 5 (deg)");
      s.mast_rotation_min = turn[0] * kRadPerDeg;
      s.mast_rotation_max = turn[1] * kRadPerDeg;
      s.surveyed_points = cm.Int("surveyed_points", 0, 0, 200);
      s.picked_pixel_sigma = cm.Double("picked_pixel_sigma", s.picked_pixel_sigma, 0.0, 10.0, "px");
    } else {
      for (io::YamlMap& st : cm.List("strips")) {
        StripSpec strip;
        strip.start = Vec2(st, "start");
        strip.end = Vec2(st, "end");
        if ((strip.end - strip.start).norm() < 1.0) st.Fail("end", "is less than 1 m from start");
        strip.altitude = st.Double("altitude", 60.0, 5.0, 1000.0, "m");
        strip.overlap = st.Double("overlap", 0.7, 0.0, 0.95);
        strip.tilt = st.Double("tilt_deg", 0.0, 0.0, 80.0, "deg") * kRadPerDeg;
        strip.tilt_azimuth = st.Double("tilt_azimuth_deg", 90.0, -360.0, 360.0, "deg") * kRadPerDeg;
        st.CheckNoUnknownKeys();
        s.strips.push_back(strip);
      }
      if (s.strips.empty())
        cm.Fail("strips", "is missing or empty (a uav camera needs at least one strip)");
      s.image_interval = cm.Double("image_interval", s.image_interval, 0.1, 600.0, "s");
      s.start_offset = cm.Double("start_offset", s.start_offset, 0.0, 86400.0, "s");
      const auto g = cm.Doubles("gnss_sigma", {0.03, 0.05}, 2);
      if (g[0] < 0 || g[1] < 0) cm.Fail("gnss_sigma", "must be >= 0");
      s.gnss_sigma = Eigen::Vector2d(g[0], g[1]);
      s.attitude_sigma =
          cm.Double("attitude_sigma_deg", s.attitude_sigma / kRadPerDeg, 0.0, 20.0, "deg") *
          kRadPerDeg;
      s.track_sigma = cm.Double("track_sigma", s.track_sigma, 0.0, 50.0, "m");
      s.imu_sigma =
          cm.Double("imu_sigma_deg", s.imu_sigma / kRadPerDeg, 0.0, 20.0, "deg") * kRadPerDeg;
      s.crab = cm.Double("crab_deg", 0.0, -30.0, 30.0, "deg") * kRadPerDeg;
      s.altitude_variation = cm.Double("altitude_variation", 0.0, 0.0, 0.5);
      s.turn_images = cm.Int("turn_images", 0, 0, 20);
    }
    cm.CheckNoUnknownKeys();
    for (const auto& other : c.cameras) {
      if (other.name == s.name)
        cm.Fail("name", Message("= '", s.name, "' is used by another camera"));
    }
    c.cameras.push_back(s);
  }
  if (c.cameras.empty()) root.Fail("cameras", "is missing or empty");
}

// render (optional): supersampling and threads.
void ReadRenderSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap r = root.OptionalMap("render");
  c.render.target_supersampling = r.Int("target_supersampling", 8, 1, 32);
  c.render.obstacle_supersampling = r.Int("obstacle_supersampling", 3, 1, 16);
  c.render.threads = r.Int("threads", 2, 1, 64);
  r.CheckNoUnknownKeys();
}

// radio (optional): receivers, transmitters and faults.
void ReadRadioSection(io::YamlMap& root, SurveyConfig* out) {
  SurveyConfig& c = *out;
  io::YamlMap ra = root.Map("radio");
  RadioNetworkSpec& n = c.radio;
  n.enabled = ra.Bool("enabled", true);
  RadioSimConfig& s = n.sim;
  s.wavelength = ra.Double("wavelength", s.wavelength, 0.001, 10.0, "m");
  s.center_frequency = ra.Double("center_frequency", s.center_frequency, 1e3, 1e11, "Hz");
  s.sample_rate = ra.Double("sample_rate", s.sample_rate, 1.0, 1e9, "Hz");
  s.block_size = ra.Int("block_size", 1024, 8, 1 << 20, "samples");
  s.block_interval = ra.Double("block_interval", 600.0, 0.01, 86400.0, "s");
  s.noise_sigma = ra.Double("noise_sigma", s.noise_sigma, 0.0, 1e6, "ADC units");
  s.full_scale = ra.Double("full_scale", s.full_scale, 1.0, 1e9, "ADC units");
  s.adc_bits = ra.Int("adc_bits", s.adc_bits, 0, 32);
  n.tail = ra.Double("tail", n.tail, 0.0, 864000.0, "s");
  s.seed = c.seed;
  for (io::YamlMap& rx : ra.List("receivers")) {
    RadioSimReceiver r;
    r.id = rx.RequiredString("id");
    r.xi = rx.Double("xi", 0.0, -M_PI, M_PI, "rad");
    n.receiver_xy.push_back(Vec2(rx, "position"));
    n.receiver_mast.push_back(rx.Double("mast", 3.0, 0.0, 100.0, "m"));
    rx.CheckNoUnknownKeys();
    s.receivers.push_back(r);
  }
  for (io::YamlMap& tx : ra.List("transmitters")) {
    RadioSimTransmitter t;
    t.id = tx.RequiredString("id");
    t.frequency_offset = tx.RequiredDouble("frequency_offset", -1e8, 1e8, "Hz");
    t.psi = tx.Double("psi", 0.0, -M_PI, M_PI, "rad");
    t.amplitude = tx.Double("amplitude", t.amplitude, 0.0, 1e9, "ADC units");
    n.transmitter_xy.push_back(Vec2(tx, "position"));
    n.transmitter_mast.push_back(tx.Double("mast", 1.5, 0.0, 100.0, "m"));
    tx.CheckNoUnknownKeys();
    s.transmitters.push_back(t);
  }
  for (io::YamlMap& f : ra.List("faults")) {
    const std::string kind =
        f.String("kind", "blocked_path", {"blocked_path", "multipath_jump", "dropped_blocks"});
    const double start =
        c.start_time + f.RequiredDouble("start", 0.0, 3.2e8, "s after epochs.start_time");
    const double duration = f.Double("duration", 60.0, -1.0, 3.2e8, "s");
    const std::string rx = f.RequiredString("receiver");
    if (kind == "dropped_blocks") {
      s.faults.push_back(RadioFault::DroppedBlocks(rx, start, duration));
    } else {
      const std::string tx = f.RequiredString("transmitter");
      if (kind == "blocked_path") {
        s.faults.push_back(RadioFault::BlockedPath(tx, rx, start, duration,
                                                   f.Double("attenuation", 0.02, 0.0, 1.0)));
      } else {
        s.faults.push_back(RadioFault::MultipathJump(tx, rx, start, duration,
                                                     f.RequiredDouble("bias", -M_PI, M_PI, "rad"),
                                                     f.Double("attenuation", 1.0, 0.0, 1.0)));
      }
    }
    f.CheckNoUnknownKeys();
  }
  if (n.enabled && (s.receivers.size() < 1 || s.transmitters.size() < 1)) {
    ra.Fail("receivers", "and 'transmitters' must not be empty when the radio is enabled");
  }
  ra.CheckNoUnknownKeys();
}

SurveyConfig FromRoot(io::YamlMap& root) {
  SurveyConfig c;
  c.path = root.context();
  c.seed = static_cast<unsigned int>(root.Int("seed", 7, 0, 2147483647));
  c.scene.seed = c.seed;

  ReadSiteSection(root, &c);
  ReadTextureAndLighting(root, &c);
  ReadEpochSection(root, &c);
  ReadLandslideSection(root, &c);
  ReadObstacleSection(root, &c);
  ReadTargetSection(root, &c);
  ReadCameraSection(root, &c);
  ReadRenderSection(root, &c);
  if (root.Has("radio")) ReadRadioSection(root, &c);
  root.CheckNoUnknownKeys();
  return c;
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
