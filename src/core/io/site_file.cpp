#include "slope_monitor/core/io/site_file.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/target_csv.h"
#include "slope_monitor/core/io/target_file.h"
#include "slope_monitor/core/io/yaml_map.h"

namespace slope_monitor {
namespace io {
namespace {

std::string Resolve(const std::string& folder, const std::string& file) {
  if (file.empty() || file[0] == '/' || folder.empty()) return file;
  return folder + "/" + file;
}

std::vector<Eigen::Vector2d> ReadPolygon(const YAML::Node& node, const std::string& where,
                                         const SiteCrs& site, const std::string& crs) {
  if (!node.IsSequence() || node.size() < 3)
    throw ConfigError(Message(where, ": must be a list of at least 3 [x, y] vertices"));
  std::vector<Eigen::Vector2d> polygon;
  for (size_t k = 0; k < node.size(); ++k) {
    const YAML::Node v = node[k];
    double x = NAN, y = NAN;
    try {
      if (v.IsSequence() && v.size() == 2) {
        x = v[0].as<double>();
        y = v[1].as<double>();
      }
    } catch (const YAML::Exception&) {
    }
    if (!std::isfinite(x) || !std::isfinite(y))
      throw ConfigError(
          Message(where, "[", k, "]: must be [x, y] with two finite numbers (", crs, ")"));
    // Vertices are horizontal: the site CRS origin's height puts them on its level.
    const double z = crs == "site" ? 0.0 : site.CrsFromSite(Eigen::Vector3d::Zero()).z();
    polygon.push_back(SiteFromListCrs(site, crs, Eigen::Vector3d(x, y, z)).head<2>());
  }
  return polygon;
}

void ReadCameras(YamlMap& root, const std::string& folder, SiteFile* s) {
  std::set<std::string> names;
  std::vector<YamlMap> list = root.List("cameras");
  for (size_t k = 0; k < list.size(); ++k) {
    YamlMap& c = list[k];
    SiteCamera cam;
    cam.name = c.RequiredString("name");
    if (cam.name.empty() || cam.name.find_first_of(" /\t") != std::string::npos)
      c.Fail("name",
             Message("'", cam.name, "' must be a non-empty namespace without '/' or blanks"));
    if (!names.insert(cam.name).second) c.Fail("name", Message("'", cam.name, "' is listed twice"));
    cam.kind = CameraKindFromName(c.RequiredString("kind", {"fixed", "fixed_targetless", "uav"}));
    cam.calibration_url = c.String("calibration_url", "");
    cam.pixel_size = c.Double("pixel_size", 0.0, 0.0, 1.0, "mm/px");
    // A UAV camera's photos carry their pitch in EXIF (the capture reads it);
    // without it the graph works in pixels.
    if (cam.calibration_url.empty() && cam.pixel_size == 0.0 && cam.kind != CameraKind::kUav)
      c.Fail("pixel_size", "is required when no calibration_url is given [mm/px]");
    if (cam.kind == CameraKind::kFixedTargetless) {
      cam.pose_file = Resolve(folder, c.RequiredString("pose_file"));
      cam.dem = Resolve(folder, c.RequiredString("dem"));
      cam.stable_polygons = Resolve(folder, c.String("stable_polygons", ""));
    } else {
      for (const char* key : {"pose_file", "dem", "stable_polygons"})
        if (c.Has(key)) c.Fail(key, "is a key of fixed_targetless cameras only");
    }
    c.CheckNoUnknownKeys();
    s->cameras.push_back(cam);
  }
}

void ReadTargets(YamlMap& root, const std::string& folder, const SiteCrs& site, SiteFile* s) {
  if (!root.Has("targets")) return;
  YamlMap t = root.Map("targets");
  const double size = t.Double("size", kDefaultTargetSize, 0.01, 100.0, "m");
  if (t.Has("file")) {
    if (t.Has("list")) t.Fail("list", "and 'file' are both given; give one");
    s->targets_file = Resolve(folder, t.RequiredString("file"));
    if (IsGcpListName(s->targets_file)) {
      // A gcp list: which of its points are checks, and what its coordinates are worth.
      const std::vector<std::string> check = t.Strings("check", {});
      const double sigma = t.Double("sigma", kDefaultGcpSigma, 1e-4, 100.0, "m");
      s->targets = LoadGcpTargets(s->targets_file, site, check, sigma, size);
    } else {
      s->targets = LoadTargetFile(s->targets_file, &site, size);
    }
  } else {
    const std::string crs = t.String("crs", site.options().crs);
    TargetList list;
    std::vector<YamlMap> entries = t.List("list");
    if (entries.empty()) t.Fail("list", "is empty or absent: give 'file' or a non-empty 'list'");
    for (YamlMap& e : entries) {
      SurveyedPoint p;
      const std::string id = e.RequiredString("id");
      const size_t slash = id.find('/');
      p.family = slash == std::string::npos ? "tag36h11" : id.substr(0, slash);
      try {
        size_t used = 0;
        const std::string number = slash == std::string::npos ? id : id.substr(slash + 1);
        p.id = std::stoi(number, &used);
        if (used != number.size() || p.id < 0) throw std::invalid_argument(id);
      } catch (const std::exception&) {
        e.Fail("id", Message("'", id, "' is not <family>/<number> or a number >= 0"));
      }
      if (list.Find(p.family, p.id)) e.Fail("id", Message("'", id, "' is listed twice"));
      p.role = TargetRoleFromName(e.String("role", "control"));
      const std::vector<double> x = e.RequiredDoubles("position", 3);
      p.position_in_site = SiteFromListCrs(site, crs, Eigen::Vector3d(x[0], x[1], x[2]));
      const std::vector<double> sigma = e.Doubles("sigma", {0.01, 0.01}, 2);
      p.sigma = Eigen::Vector2d(sigma[0], sigma[1]);
      e.CheckNoUnknownKeys();
      ApplySurveyedPoints({p}, e.Double("size", size, 0.01, 100.0, "m"), &list);
    }
    s->targets = list;
  }
  t.CheckNoUnknownKeys();
}

void ReadAreas(YamlMap& root, const SiteCrs& site, SiteFile* s) {
  YamlMap a = root.OptionalMap("areas");
  const std::string crs = a.String("crs", site.options().crs);
  const YAML::Node outline = a.Node("outline");
  if (outline.IsDefined() && !outline.IsNull())
    s->outline = ReadPolygon(outline, a.context() + ".outline", site, crs);
  const YAML::Node stable = a.Node("stable");
  if (stable.IsDefined() && !stable.IsNull()) {
    if (!stable.IsSequence())
      throw ConfigError(Message(a.context(), ".stable: must be a list of polygons"));
    for (size_t k = 0; k < stable.size(); ++k)
      s->stable_areas.push_back(
          ReadPolygon(stable[k], Message(a.context(), ".stable[", k, "]"), site, crs));
  }
  a.CheckNoUnknownKeys();
}

void ReadThresholds(YamlMap& root, SiteFile* s) {
  YamlMap t = root.OptionalMap("thresholds");
  s->thresholds.unit = t.String("unit", s->thresholds.unit, {"mm/day", "mm/h"});
  for (const auto& [key, value] : {std::make_pair("watch", &s->thresholds.watch),
                                   std::make_pair("warning", &s->thresholds.warning),
                                   std::make_pair("alarm", &s->thresholds.alarm)}) {
    if (t.Has(key)) *value = t.RequiredDouble(key, 1e-9, 1e6, s->thresholds.unit);
  }
  for (const auto& [key, value] :
       {std::make_pair("displacement_watch", &s->thresholds.displacement_watch),
        std::make_pair("displacement_warning", &s->thresholds.displacement_warning),
        std::make_pair("displacement_alarm", &s->thresholds.displacement_alarm)}) {
    if (t.Has(key)) *value = t.RequiredDouble(key, 1e-6, 1e7, "mm");
  }
  for (const auto& [key, value] :
       {std::make_pair("area_growth_watch", &s->thresholds.area_growth_watch),
        std::make_pair("area_growth_warning", &s->thresholds.area_growth_warning)}) {
    if (t.Has(key)) *value = t.RequiredDouble(key, 1e-6, 1e9, "m^2");
  }
  const auto& th = s->thresholds;
  if (th.area_growth_watch && th.area_growth_warning &&
      *th.area_growth_watch >= *th.area_growth_warning)
    t.Fail("area_growth_watch", "must be below area_growth_warning");
  if (th.watch && th.warning && *th.watch >= *th.warning) t.Fail("watch", "must be below warning");
  if (th.warning && th.alarm && *th.warning >= *th.alarm) t.Fail("warning", "must be below alarm");
  if (th.displacement_watch && th.displacement_warning &&
      *th.displacement_watch >= *th.displacement_warning)
    t.Fail("displacement_watch", "must be below displacement_warning");
  if (th.displacement_warning && th.displacement_alarm &&
      *th.displacement_warning >= *th.displacement_alarm)
    t.Fail("displacement_warning", "must be below displacement_alarm");
  t.CheckNoUnknownKeys();
}

void ReadNotification(YamlMap& root, const std::string& folder, SiteFile* s) {
  YamlMap n = root.OptionalMap("notification");
  NotificationOptions& o = s->notification;
  o.hook = n.String("hook", o.hook);
  // A bare name is looked up in PATH; a path is taken relative to the site file.
  if (o.hook.find('/') != std::string::npos) o.hook = Resolve(folder, o.hook);
  o.timeout = n.Double("timeout", o.timeout, 0.1, 600.0, "s");
  o.retries = n.Int("retries", o.retries, 0, 10);
  o.retry_delay = n.Double("retry_delay", o.retry_delay, 0.0, 3600.0, "s");
  n.CheckNoUnknownKeys();
}

}  // namespace

CameraKind CameraKindFromName(const std::string& name) {
  if (name == "fixed") return CameraKind::kFixed;
  if (name == "fixed_targetless") return CameraKind::kFixedTargetless;
  if (name == "uav") return CameraKind::kUav;
  throw ConfigError(Message("camera kind '", name, "' is not fixed, fixed_targetless or uav"));
}

std::string CameraKindName(CameraKind kind) {
  switch (kind) {
    case CameraKind::kFixed:
      return "fixed";
    case CameraKind::kFixedTargetless:
      return "fixed_targetless";
    case CameraKind::kUav:
      return "uav";
  }
  return "fixed";
}

std::vector<SiteCamera> DefaultCameras() {
  std::vector<SiteCamera> cameras(3);
  cameras[0].name = "fixed_cam_1";
  cameras[1].name = "fixed_cam_2";
  cameras[2].name = "uav";
  cameras[2].kind = CameraKind::kUav;
  return cameras;
}

std::vector<std::string> CameraNames(const std::vector<SiteCamera>& cameras, CameraKind kind) {
  std::vector<std::string> names;
  for (const SiteCamera& c : cameras)
    if (c.kind == kind) names.push_back(c.name);
  return names;
}

void NotificationOptions::Check() const {
  if (!(timeout >= 0.1 && timeout <= 600.0))
    throw InvalidArgument(Message("notification timeout ", timeout, " s is outside 0.1..600"));
  if (retries < 0 || retries > 10)
    throw InvalidArgument(Message("notification retries ", retries, " is outside 0..10"));
  if (!(retry_delay >= 0.0 && retry_delay <= 3600.0))
    throw InvalidArgument(
        Message("notification retry_delay ", retry_delay, " s is outside 0..3600"));
}

const SiteCamera* SiteFile::FindCamera(const std::string& name) const {
  for (const SiteCamera& c : cameras)
    if (c.name == name) return &c;
  return nullptr;
}

std::vector<const SiteCamera*> SiteFile::CamerasWithTargets() const {
  std::vector<const SiteCamera*> out;
  for (const SiteCamera& c : cameras)
    if (c.kind != CameraKind::kFixedTargetless) out.push_back(&c);
  return out;
}

bool SiteWithoutTargets(const SiteFile& site, const std::string& target_list) {
  return !site.targets && (target_list.empty() || !std::filesystem::is_regular_file(target_list));
}

bool SiteWithoutDetectableTargets(const SiteFile& site, const std::string& target_list) {
  return SiteWithoutTargets(site, target_list) || (site.targets && site.targets->OnlyPicked());
}

SiteFile ParseSiteFile(const std::string& text, const std::string& context,
                       const std::string& folder) {
  YamlMap root = YamlMap::Parse(text, context);
  SiteFile s;
  s.path = context;
  s.name = root.RequiredString("name");
  s.crs.crs = root.RequiredString("crs");
  const std::vector<double> origin = root.RequiredDoubles("origin", 3);
  s.crs.origin = Eigen::Vector3d(origin[0], origin[1], origin[2]);
  try {
    s.crs.frame = ParseSiteFrame(root.String("frame", "local_enu", {"local_enu", "shifted_crs"}));
    s.crs.Check();
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message(context, ": ", e.what()));
  }
  std::optional<SiteCrs> site;
  try {
    site.emplace(s.crs);
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message(context, ": 'crs' / 'origin': ", e.what()));
  }
  ReadCameras(root, folder, &s);
  s.radio_network = Resolve(folder, root.String("radio_network", ""));
  if (!s.radio_network.empty() && !std::ifstream(s.radio_network))
    root.Fail("radio_network", Message("names '", s.radio_network, "', which cannot be opened"));
  ReadTargets(root, folder, *site, &s);
  ReadAreas(root, *site, &s);
  ReadThresholds(root, &s);
  s.aliases = root.Strings("aliases", {});
  for (const std::string& a : s.aliases)
    if (a.find('=') == std::string::npos)
      root.Fail("aliases",
                Message("entry '", a, "' must read 'measured_id = monitoring_point_id'"));
  ReadNotification(root, folder, &s);
  root.CheckNoUnknownKeys();
  return s;
}

SiteFile LoadSiteFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(Message("cannot open the site file '", path, "'"));
  std::stringstream text;
  text << in.rdbuf();
  const size_t slash = path.find_last_of('/');
  const std::string folder = slash == std::string::npos ? "." : path.substr(0, slash);
  return ParseSiteFile(text.str(), path, folder);
}

}  // namespace io
}  // namespace slope_monitor
