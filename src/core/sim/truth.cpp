#include "slope_monitor/core/sim/truth.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {
namespace {

double Smoothstep(double q) {
  q = std::clamp(q, 0.0, 1.0);
  return q * q * (3.0 - 2.0 * q);
}

// ---- writing --------------------------------------------------------------

YAML::Emitter& Vec(YAML::Emitter& out, const double* v, int n) {
  out << YAML::Flow << YAML::BeginSeq;
  for (int i = 0; i < n; ++i) out << v[i];
  out << YAML::EndSeq;
  return out;
}

void EmitVec3(YAML::Emitter& out, const char* key, const Eigen::Vector3d& v) {
  out << YAML::Key << key << YAML::Value;
  Vec(out, v.data(), 3);
}

void EmitCameraModel(YAML::Emitter& out, const char* interior_key, const camera::CameraModel& m) {
  out << YAML::Key << interior_key << YAML::Value;
  Vec(out, m.interior().data(), camera::kNumInterior);
}

// ---- reading ---------------------------------------------------------------

class Reader {
 public:
  explicit Reader(std::string context) : context_(std::move(context)) {}

  [[noreturn]] void Fail(const std::string& key, const std::string& what) const {
    throw IoError(Message(context_, ": '", key, "' ", what));
  }

  YAML::Node Need(const YAML::Node& map, const std::string& key, const std::string& path) const {
    if (!map.IsMap() || !map[key].IsDefined() || map[key].IsNull()) Fail(path + key, "is missing");
    return map[key];
  }

  template <typename T>
  T As(const YAML::Node& n, const std::string& path) const {
    try {
      return n.as<T>();
    } catch (const YAML::Exception& e) {
      Fail(path, Message("has the wrong type (", e.what(), ")"));
    }
  }

  template <typename T>
  T Get(const YAML::Node& map, const std::string& key, const std::string& path) const {
    return As<T>(Need(map, key, path), path + key);
  }

  template <typename T>
  T GetOr(const YAML::Node& map, const std::string& key, const T& fallback,
          const std::string& path) const {
    if (!map.IsMap() || !map[key].IsDefined() || map[key].IsNull()) return fallback;
    return As<T>(map[key], path + key);
  }

  std::vector<double> Doubles(const YAML::Node& n, size_t size, const std::string& path) const {
    if (!n.IsSequence()) Fail(path, "must be a list of numbers");
    std::vector<double> v = As<std::vector<double>>(n, path);
    if (size > 0 && v.size() != size)
      Fail(path, Message("must have ", size, " numbers, has ", v.size()));
    return v;
  }

  Eigen::Vector3d Vec3(const YAML::Node& map, const std::string& key,
                       const std::string& path) const {
    const std::vector<double> v = Doubles(Need(map, key, path), 3, path + key);
    return Eigen::Vector3d(v[0], v[1], v[2]);
  }

  std::vector<Eigen::Vector3d> Vec3List(const YAML::Node& map, const std::string& key,
                                        const std::string& path) const {
    std::vector<Eigen::Vector3d> out;
    if (!map[key].IsDefined() || map[key].IsNull()) return out;
    const YAML::Node seq = map[key];
    if (!seq.IsSequence()) Fail(path + key, "must be a list of [x, y, z]");
    for (size_t i = 0; i < seq.size(); ++i) {
      const std::vector<double> v = Doubles(seq[i], 3, Message(path, key, "[", i, "]"));
      out.emplace_back(v[0], v[1], v[2]);
    }
    return out;
  }

  camera::CameraModel Model(const YAML::Node& cam, const std::string& interior_key,
                            const std::string& path) const {
    const YAML::Node sensor = Need(cam, "sensor", path);
    camera::Sensor s;
    s.width = Get<int>(sensor, "width", path + "sensor.");
    s.height = Get<int>(sensor, "height", path + "sensor.");
    s.pixel_size = Get<double>(sensor, "pixel_size", path + "sensor.");
    camera::DistortionModel dm;
    try {
      dm = camera::DistortionModelFromName(Get<std::string>(cam, "distortion_model", path));
    } catch (const InvalidArgument& e) {
      Fail(path + "distortion_model", e.what());
    }
    const std::vector<double> v =
        Doubles(Need(cam, interior_key, path), camera::kNumInterior, path + interior_key);
    std::array<double, camera::kNumInterior> a{};
    std::copy(v.begin(), v.end(), a.begin());
    camera::CameraModel m(s, dm, a);
    try {
      m.Check();
    } catch (const InvalidArgument& e) {
      Fail(path + interior_key, e.what());
    }
    return m;
  }

  camera::ExteriorOrientation Exterior(const YAML::Node& map, const std::string& key,
                                       const std::string& path) const {
    const std::vector<double> v = Doubles(Need(map, key, path), camera::kNumExterior, path + key);
    return camera::ExteriorOrientation::FromArray(v.data());
  }

 private:
  std::string context_;
};

}  // namespace

// ---------------------------------------------------------------------------
// LandslideModel
// ---------------------------------------------------------------------------

Eigen::Vector3d LandslideModel::Direction() const {
  return Eigen::Vector3d(std::cos(plunge) * std::cos(azimuth), std::cos(plunge) * std::sin(azimuth),
                         -std::sin(plunge));
}

double LandslideModel::Weight(const Eigen::Vector2d& xy) const {
  const Eigen::Vector2d d = xy - centre;
  const double u = d.x() * std::cos(azimuth) + d.y() * std::sin(azimuth);
  const double v = -d.x() * std::sin(azimuth) + d.y() * std::cos(azimuth);
  const double rho = std::hypot(u / length, v / width);
  if (rho >= 1.0) return 0.0;
  if (rho <= 1.0 - taper) return 1.0;
  return Smoothstep((1.0 - rho) / taper);
}

double LandslideModel::Travel(double t) const {
  if (t <= reference_time) return 0.0;
  if (velocity == Velocity::kConstant) return velocity0 * (t - reference_time);
  const double span = failure_time - reference_time;
  if (t >= failure_time) return std::numeric_limits<double>::infinity();
  return velocity0 * span * std::log(span / (failure_time - t));
}

double LandslideModel::VelocityAt(double t) const {
  if (velocity == Velocity::kConstant) return velocity0;
  if (t >= failure_time) return std::numeric_limits<double>::infinity();
  return velocity0 * (failure_time - reference_time) / (failure_time - std::max(t, reference_time));
}

Eigen::Vector3d LandslideModel::DisplacementAt(const Eigen::Vector3d& x_ref, double t) const {
  const double w = Weight(x_ref.head<2>());
  if (w == 0.0) return Eigen::Vector3d::Zero();
  return w * Travel(t) * Direction();
}

Eigen::Vector3d LandslideModel::ReferencePositionOf(const Eigen::Vector3d& x_now, double t) const {
  return InverseAt(*this, t)(x_now);
}

LandslideModel::InverseAt::InverseAt(const LandslideModel& model, double t)
    : model_(model),
      travel_(model.Travel(t)),
      cos_azimuth_(std::cos(model.azimuth)),
      sin_azimuth_(std::sin(model.azimuth)),
      direction_(model.Direction()) {}

// LandslideModel::Weight with the azimuth's cosine and sine computed once.
double LandslideModel::InverseAt::Weight(const Eigen::Vector2d& xy) const {
  const Eigen::Vector2d d = xy - model_.centre;
  const double u = d.x() * cos_azimuth_ + d.y() * sin_azimuth_;
  const double v = -d.x() * sin_azimuth_ + d.y() * cos_azimuth_;
  const double rho = std::hypot(u / model_.length, v / model_.width);
  if (rho >= 1.0) return 0.0;
  if (rho <= 1.0 - model_.taper) return 1.0;
  return Smoothstep((1.0 - rho) / model_.taper);
}

Eigen::Vector3d LandslideModel::InverseAt::operator()(const Eigen::Vector3d& x_now) const {
  const double s = travel_;
  Eigen::Vector2d x = x_now.head<2>();
  if (s != 0.0) {
    for (int it = 0; it < 100; ++it) {
      const Eigen::Vector2d next = x_now.head<2>() - Weight(x) * s * direction_.head<2>();
      const double step = (next - x).norm();
      x = next;
      if (step < 1e-10) break;
    }
  }
  const double dz = Weight(x) * s * direction_.z();
  return Eigen::Vector3d(x.x(), x.y(), x_now.z() - dz);
}

std::string LandslideModel::VelocityName(Velocity v) {
  return v == Velocity::kConstant ? "constant" : "accelerating";
}

LandslideModel::Velocity LandslideModel::VelocityFromName(const std::string& name) {
  if (name == "constant") return Velocity::kConstant;
  if (name == "accelerating") return Velocity::kAccelerating;
  throw InvalidArgument(
      Message("unknown velocity model '", name, "' (expected constant or accelerating)"));
}

std::string Obstacle::KindName(Kind k) { return k == Kind::kTree ? "tree" : "boulder"; }

Obstacle::Kind Obstacle::KindFromName(const std::string& name) {
  if (name == "tree") return Kind::kTree;
  if (name == "boulder") return Kind::kBoulder;
  throw InvalidArgument(Message("unknown obstacle kind '", name, "' (expected tree or boulder)"));
}

// ---------------------------------------------------------------------------
// SurveyTruth queries
// ---------------------------------------------------------------------------

bool SurveyTruth::Unmatchable(const Eigen::Vector3d& x) const {
  for (const Obstacle& o : obstacles) {
    if ((x.head<2>() - o.base.head<2>()).norm() <= o.radius) return true;
  }
  if (scarp.depth > 0.0) {
    const LandslideModel& l = landslide;
    const Eigen::Vector2d d = x.head<2>() - l.centre;
    const double u = d.x() * std::cos(l.azimuth) + d.y() * std::sin(l.azimuth);
    const double v = -d.x() * std::sin(l.azimuth) + d.y() * std::cos(l.azimuth);
    // u along the motion (downslope); the head is upslope, at u = -length.
    const double rho = std::hypot(u / l.length, v / l.width);
    const double head = -u / l.length;
    if (rho >= 1.0 - scarp.band && rho <= 1.0 && head > scarp.head_fraction) return true;
  }
  return false;
}

const TargetTruth* SurveyTruth::FindTarget(const std::string& key) const {
  for (const auto& t : targets)
    if (t.key == key) return &t;
  return nullptr;
}

const CameraTruth* SurveyTruth::FindCamera(const std::string& name) const {
  for (const auto& c : cameras)
    if (c.name == name) return &c;
  return nullptr;
}

double SurveyTruth::EpochStamp(int k) const {
  if (k < 0 || k >= static_cast<int>(epochs.size())) {
    throw InvalidArgument(Message("epoch ", k, " out of range [0, ", epochs.size(), ")"));
  }
  return epochs[k].stamp;
}

std::map<std::string, Eigen::Vector3d> SurveyTruth::TargetPositions(int epoch) const {
  std::map<std::string, Eigen::Vector3d> out;
  for (const auto& t : targets) {
    if (epoch >= 0 && epoch < static_cast<int>(t.positions.size())) out[t.key] = t.positions[epoch];
  }
  return out;
}

// ---------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------

namespace {

// One camera of the truth file: sensor, models, images, surveyed points.
void EmitCameraTruth(YAML::Emitter& out, const CameraTruth& c) {
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << c.name;
  out << YAML::Key << "kind" << YAML::Value << c.kind;
  out << YAML::Key << "encoding" << YAML::Value << c.encoding;
  out << YAML::Key << "sensor" << YAML::Value << YAML::Flow << YAML::BeginMap << YAML::Key
      << "width" << YAML::Value << c.model.sensor().width << YAML::Key << "height" << YAML::Value
      << c.model.sensor().height << YAML::Key << "pixel_size" << YAML::Value
      << c.model.sensor().pixel_size << YAML::EndMap;
  out << YAML::Key << "distortion_model" << YAML::Value
      << camera::DistortionModelName(c.model.model());
  EmitCameraModel(out, "interior", c.model);
  EmitCameraModel(out, "nominal_interior", c.nominal);
  if (c.nominal_pose) {
    const auto a = c.nominal_pose->ToArray();
    out << YAML::Key << "nominal_exterior" << YAML::Value;
    Vec(out, a.data(), 6);
  }
  out << YAML::Key << "images" << YAML::Value << YAML::BeginSeq;
  for (const auto& im : c.images) {
    out << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "epoch" << YAML::Value << im.epoch;
    out << YAML::Key << "stamp" << YAML::Value << im.stamp;
    const auto a = im.exterior.ToArray();
    out << YAML::Key << "exterior" << YAML::Value;
    Vec(out, a.data(), 6);
    if (im.gnss) EmitVec3(out, "gnss", *im.gnss);
    out << YAML::Key << "exposure" << YAML::Value << im.exposure;
    out << YAML::Key << "visible" << YAML::Value << YAML::Flow << im.visible;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;
  if (!c.surveyed_points.empty()) {
    out << YAML::Key << "surveyed_points" << YAML::Value << YAML::BeginSeq;
    for (const SurveyedPointTruth& sp : c.surveyed_points) {
      out << YAML::Flow << YAML::BeginMap;
      out << YAML::Key << "id" << YAML::Value << sp.id;
      EmitVec3(out, "position", sp.position);
      EmitVec3(out, "surveyed", sp.surveyed);
      out << YAML::Key << "picked" << YAML::Value;
      Vec(out, sp.picked.data(), 2);
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
  }
  out << YAML::EndMap;
}

// One target of the truth file: design, role, survey and positions per epoch.
void EmitTargetTruth(YAML::Emitter& out, const TargetTruth& t) {
  out << YAML::BeginMap;
  out << YAML::Key << "key" << YAML::Value << t.key;
  out << YAML::Key << "id" << YAML::Value << t.id;
  out << YAML::Key << "family" << YAML::Value << t.family;
  out << YAML::Key << "size" << YAML::Value << t.size;
  out << YAML::Key << "role" << YAML::Value << io::TargetRoleName(t.role);
  EmitVec3(out, "normal", t.normal);
  EmitVec3(out, "up", t.up_in_plate);
  if (t.surveyed) {
    EmitVec3(out, "surveyed", *t.surveyed);
    out << YAML::Key << "survey_sigma" << YAML::Value;
    Vec(out, t.survey_sigma.data(), 2);
  }
  out << YAML::Key << "positions" << YAML::Value << YAML::BeginSeq;
  for (const auto& p : t.positions) Vec(out, p.data(), 3);
  out << YAML::EndSeq;
  out << YAML::EndMap;
}

// The radio network of the truth file: receivers, transmitters per epoch, ambiguities, faults.
void EmitRadioTruth(YAML::Emitter& out, const RadioTruth& radio) {
  out << YAML::Key << "radio" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "wavelength" << YAML::Value << radio.wavelength;
  out << YAML::Key << "center_frequency" << YAML::Value << radio.center_frequency;
  out << YAML::Key << "receivers" << YAML::Value << YAML::BeginSeq;
  for (const auto& r : radio.receivers) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "id" << YAML::Value << r.id;
    EmitVec3(out, "position", r.position);
    out << YAML::Key << "xi" << YAML::Value << r.xi << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "transmitters" << YAML::Value << YAML::BeginSeq;
  for (const auto& t : radio.transmitters) {
    out << YAML::BeginMap << YAML::Key << "id" << YAML::Value << t.id;
    out << YAML::Key << "frequency" << YAML::Value << t.frequency;
    out << YAML::Key << "psi" << YAML::Value << t.psi;
    out << YAML::Key << "positions" << YAML::Value << YAML::BeginSeq;
    for (const auto& p : t.positions) Vec(out, p.data(), 3);
    out << YAML::EndSeq << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::Key << "ambiguities" << YAML::Value << YAML::BeginSeq;
  for (const auto& row : radio.ambiguities) out << YAML::Flow << row;
  out << YAML::EndSeq;
  out << YAML::Key << "faults" << YAML::Value << YAML::BeginSeq;
  for (const auto& f : radio.faults) out << f;
  out << YAML::EndSeq;
  out << YAML::EndMap;
}

}  // namespace

std::string SurveyTruth::ToYaml() const {
  YAML::Emitter out;
  out.SetDoublePrecision(17);
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << format;
  out << YAML::Key << "seed" << YAML::Value << seed;
  out << YAML::Key << "config" << YAML::Value << config;
  out << YAML::Key << "site" << YAML::Value << YAML::BeginMap;
  if (!site_name.empty()) out << YAML::Key << "name" << YAML::Value << site_name;
  EmitVec3(out, "origin", origin);
  out << YAML::Key << "extent" << YAML::Value;
  Vec(out, extent.data(), 4);
  out << YAML::EndMap;

  out << YAML::Key << "epochs" << YAML::Value << YAML::BeginSeq;
  for (const auto& e : epochs) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "index" << YAML::Value << e.index
        << YAML::Key << "stamp" << YAML::Value << e.stamp << YAML::EndMap;
  }
  out << YAML::EndSeq;

  out << YAML::Key << "cameras" << YAML::Value << YAML::BeginSeq;
  for (const auto& c : cameras) EmitCameraTruth(out, c);
  out << YAML::EndSeq;

  out << YAML::Key << "targets" << YAML::Value << YAML::BeginSeq;
  for (const auto& t : targets) EmitTargetTruth(out, t);
  out << YAML::EndSeq;

  const LandslideModel& l = landslide;
  out << YAML::Key << "landslide" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "model" << YAML::Value << LandslideModel::VelocityName(l.velocity);
  out << YAML::Key << "centre" << YAML::Value;
  Vec(out, l.centre.data(), 2);
  out << YAML::Key << "length" << YAML::Value << l.length;
  out << YAML::Key << "width" << YAML::Value << l.width;
  out << YAML::Key << "taper" << YAML::Value << l.taper;
  out << YAML::Key << "azimuth" << YAML::Value << l.azimuth;
  out << YAML::Key << "plunge" << YAML::Value << l.plunge;
  out << YAML::Key << "velocity0" << YAML::Value << l.velocity0;
  out << YAML::Key << "reference_time" << YAML::Value << l.reference_time;
  out << YAML::Key << "failure_time" << YAML::Value << l.failure_time;
  out << YAML::EndMap;

  out << YAML::Key << "scarp" << YAML::Value << YAML::Flow << YAML::BeginMap;
  out << YAML::Key << "depth" << YAML::Value << scarp.depth << YAML::Key << "band" << YAML::Value
      << scarp.band << YAML::Key << "head_fraction" << YAML::Value << scarp.head_fraction
      << YAML::EndMap;

  out << YAML::Key << "obstacles" << YAML::Value << YAML::BeginSeq;
  for (const auto& o : obstacles) {
    out << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "kind" << YAML::Value << Obstacle::KindName(o.kind);
    EmitVec3(out, "base", o.base);
    out << YAML::Key << "radius" << YAML::Value << o.radius;
    out << YAML::Key << "height" << YAML::Value << o.height;
    out << YAML::Key << "moves" << YAML::Value << o.moves;
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;

  EmitRadioTruth(out, radio);

  out << YAML::Key << "surfaces" << YAML::Value << YAML::BeginSeq;
  for (const auto& s : surfaces) {
    out << YAML::Flow << YAML::BeginMap << YAML::Key << "epoch" << YAML::Value << s.epoch
        << YAML::Key << "geotiff" << YAML::Value << s.geotiff << YAML::EndMap;
  }
  out << YAML::EndSeq;
  out << YAML::EndMap;
  return std::string(out.c_str()) + "\n";
}

void SurveyTruth::Save(const std::string& path) const {
  std::ofstream f(path);
  if (!f) throw IoError(Message("cannot write truth file '", path, "'"));
  f << "# Ground truth of a simulated slope survey; schema: doc/simulator.md\n" << ToYaml();
  if (!f) throw IoError(Message("error writing truth file '", path, "'"));
}

// ---------------------------------------------------------------------------
// Reading
// ---------------------------------------------------------------------------

SurveyTruth SurveyTruth::Load(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw IoError(Message("cannot open truth file '", path, "'"));
  std::stringstream ss;
  ss << f.rdbuf();
  return FromYaml(ss.str(), path);
}

namespace {

// One camera of a truth file (`p`: "cameras[i]." for messages).
CameraTruth ReadCameraTruth(const Reader& r, const YAML::Node& n, const std::string& p) {
  CameraTruth c;
  c.name = r.Get<std::string>(n, "name", p);
  c.kind = r.Get<std::string>(n, "kind", p);
  c.encoding = r.GetOr<std::string>(n, "encoding", "mono8", p);
  c.model = r.Model(n, "interior", p);
  c.nominal = r.Model(n, "nominal_interior", p);
  if (n["nominal_exterior"].IsDefined()) c.nominal_pose = r.Exterior(n, "nominal_exterior", p);
  const YAML::Node ims = n["images"];
  for (size_t j = 0; ims.IsDefined() && j < ims.size(); ++j) {
    const std::string q = Message(p, "images[", j, "].");
    ImageTruth im;
    im.epoch = r.Get<int>(ims[j], "epoch", q);
    im.stamp = r.Get<double>(ims[j], "stamp", q);
    im.exterior = r.Exterior(ims[j], "exterior", q);
    if (ims[j]["gnss"].IsDefined()) im.gnss = r.Vec3(ims[j], "gnss", q);
    im.exposure = r.GetOr<double>(ims[j], "exposure", 1.0, q);
    im.visible = r.GetOr<std::vector<std::string>>(ims[j], "visible", {}, q);
    c.images.push_back(im);
  }
  const YAML::Node sps = n["surveyed_points"];
  for (size_t j = 0; sps.IsDefined() && j < sps.size(); ++j) {
    const std::string q = Message(p, "surveyed_points[", j, "].");
    SurveyedPointTruth sp;
    sp.id = r.Get<std::string>(sps[j], "id", q);
    sp.position = r.Vec3(sps[j], "position", q);
    sp.surveyed = r.Vec3(sps[j], "surveyed", q);
    const std::vector<double> px = r.Get<std::vector<double>>(sps[j], "picked", q);
    if (px.size() != 2) throw ConfigError(Message(q, "picked: expected [u, v]"));
    sp.picked = Eigen::Vector2d(px[0], px[1]);
    c.surveyed_points.push_back(sp);
  }
  return c;
}

// One target of a truth file (`p`: "targets[i]." for messages).
TargetTruth ReadTargetTruth(const Reader& r, const YAML::Node& n, const std::string& p) {
  TargetTruth tt;
  tt.key = r.Get<std::string>(n, "key", p);
  tt.id = r.Get<int>(n, "id", p);
  tt.family = r.Get<std::string>(n, "family", p);
  tt.size = r.Get<double>(n, "size", p);
  try {
    tt.role = io::TargetRoleFromName(r.Get<std::string>(n, "role", p));
  } catch (const Error& e) {
    r.Fail(p + "role", e.what());
  }
  tt.normal = r.Vec3(n, "normal", p);
  if (n["up"].IsDefined()) tt.up_in_plate = r.Vec3(n, "up", p);
  if (n["surveyed"].IsDefined()) tt.surveyed = r.Vec3(n, "surveyed", p);
  if (n["survey_sigma"].IsDefined()) {
    const auto s = r.Doubles(n["survey_sigma"], 2, p + "survey_sigma");
    tt.survey_sigma = Eigen::Vector2d(s[0], s[1]);
  }
  tt.positions = r.Vec3List(n, "positions", p);
  return tt;
}

// The radio network of a truth file.
RadioTruth ReadRadioTruth(const Reader& r, const YAML::Node& rn) {
  RadioTruth radio;
  radio.wavelength = r.Get<double>(rn, "wavelength", "radio.");
  radio.center_frequency = r.GetOr<double>(rn, "center_frequency", 0.0, "radio.");
  const YAML::Node rx = rn["receivers"];
  for (size_t i = 0; rx.IsDefined() && i < rx.size(); ++i) {
    const std::string p = Message("radio.receivers[", i, "].");
    RadioReceiverTruth rr;
    rr.id = r.Get<std::string>(rx[i], "id", p);
    rr.position = r.Vec3(rx[i], "position", p);
    rr.xi = r.Get<double>(rx[i], "xi", p);
    radio.receivers.push_back(rr);
  }
  const YAML::Node tx = rn["transmitters"];
  for (size_t i = 0; tx.IsDefined() && i < tx.size(); ++i) {
    const std::string p = Message("radio.transmitters[", i, "].");
    RadioTransmitterTruth tt;
    tt.id = r.Get<std::string>(tx[i], "id", p);
    tt.frequency = r.Get<double>(tx[i], "frequency", p);
    tt.psi = r.Get<double>(tx[i], "psi", p);
    tt.positions = r.Vec3List(tx[i], "positions", p);
    radio.transmitters.push_back(tt);
  }
  const YAML::Node amb = rn["ambiguities"];
  for (size_t i = 0; amb.IsDefined() && i < amb.size(); ++i) {
    radio.ambiguities.push_back(
        r.As<std::vector<int>>(amb[i], Message("radio.ambiguities[", i, "]")));
  }
  radio.faults = r.GetOr<std::vector<std::string>>(rn, "faults", {}, "radio.");
  return radio;
}

}  // namespace

SurveyTruth SurveyTruth::FromYaml(const std::string& text, const std::string& context) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw IoError(Message(context, ": malformed YAML: ", e.what()));
  }
  if (!root.IsMap()) throw IoError(Message(context, ": must hold a map at its top level"));
  Reader r(context);
  SurveyTruth t;
  t.format = r.Get<std::string>(root, "format", "");
  if (t.format != "slope_monitor_sim_truth/1")
    r.Fail("format", Message("= '", t.format, "' is not supported"));
  t.seed = r.GetOr<unsigned int>(root, "seed", 0u, "");
  t.config = r.GetOr<std::string>(root, "config", "", "");
  const YAML::Node site = r.Need(root, "site", "");
  t.site_name = r.GetOr<std::string>(site, "name", "", "site.");
  t.origin = r.Vec3(site, "origin", "site.");
  const std::vector<double> ext = r.Doubles(r.Need(site, "extent", "site."), 4, "site.extent");
  t.extent = Eigen::Vector4d(ext[0], ext[1], ext[2], ext[3]);

  const YAML::Node epochs = r.Need(root, "epochs", "");
  for (size_t i = 0; i < epochs.size(); ++i) {
    const std::string p = Message("epochs[", i, "].");
    EpochTruth e;
    e.index = r.Get<int>(epochs[i], "index", p);
    e.stamp = r.Get<double>(epochs[i], "stamp", p);
    t.epochs.push_back(e);
  }

  const YAML::Node cams = root["cameras"];
  for (size_t i = 0; cams.IsDefined() && i < cams.size(); ++i) {
    const std::string p = Message("cameras[", i, "].");
    t.cameras.push_back(ReadCameraTruth(r, cams[i], p));
  }

  const YAML::Node targets = root["targets"];
  for (size_t i = 0; targets.IsDefined() && i < targets.size(); ++i) {
    const std::string p = Message("targets[", i, "].");
    t.targets.push_back(ReadTargetTruth(r, targets[i], p));
  }

  const YAML::Node ls = r.Need(root, "landslide", "");
  LandslideModel& l = t.landslide;
  try {
    l.velocity = LandslideModel::VelocityFromName(r.Get<std::string>(ls, "model", "landslide."));
  } catch (const InvalidArgument& e) {
    r.Fail("landslide.model", e.what());
  }
  const auto centre = r.Doubles(r.Need(ls, "centre", "landslide."), 2, "landslide.centre");
  l.centre = Eigen::Vector2d(centre[0], centre[1]);
  l.length = r.Get<double>(ls, "length", "landslide.");
  l.width = r.Get<double>(ls, "width", "landslide.");
  l.taper = r.Get<double>(ls, "taper", "landslide.");
  l.azimuth = r.Get<double>(ls, "azimuth", "landslide.");
  l.plunge = r.Get<double>(ls, "plunge", "landslide.");
  l.velocity0 = r.Get<double>(ls, "velocity0", "landslide.");
  l.reference_time = r.Get<double>(ls, "reference_time", "landslide.");
  l.failure_time = r.GetOr<double>(ls, "failure_time", 0.0, "landslide.");

  if (root["scarp"].IsDefined()) {
    const YAML::Node s = root["scarp"];
    t.scarp.depth = r.Get<double>(s, "depth", "scarp.");
    t.scarp.band = r.Get<double>(s, "band", "scarp.");
    t.scarp.head_fraction = r.Get<double>(s, "head_fraction", "scarp.");
  }

  const YAML::Node obs = root["obstacles"];
  for (size_t i = 0; obs.IsDefined() && i < obs.size(); ++i) {
    const std::string p = Message("obstacles[", i, "].");
    Obstacle o;
    try {
      o.kind = Obstacle::KindFromName(r.Get<std::string>(obs[i], "kind", p));
    } catch (const InvalidArgument& e) {
      r.Fail(p + "kind", e.what());
    }
    o.base = r.Vec3(obs[i], "base", p);
    o.radius = r.Get<double>(obs[i], "radius", p);
    o.height = r.Get<double>(obs[i], "height", p);
    o.moves = r.GetOr<bool>(obs[i], "moves", false, p);
    t.obstacles.push_back(o);
  }

  if (root["radio"].IsDefined() && !root["radio"].IsNull())
    t.radio = ReadRadioTruth(r, root["radio"]);

  const YAML::Node surf = root["surfaces"];
  for (size_t i = 0; surf.IsDefined() && i < surf.size(); ++i) {
    const std::string p = Message("surfaces[", i, "].");
    SurfaceTruth s;
    s.epoch = r.Get<int>(surf[i], "epoch", p);
    s.geotiff = r.Get<std::string>(surf[i], "geotiff", p);
    t.surfaces.push_back(s);
  }
  return t;
}

}  // namespace sim
}  // namespace slope_monitor
