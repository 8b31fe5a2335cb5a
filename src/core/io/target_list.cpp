#include "slope_monitor/core/io/target_list.h"

#include <algorithm>
#include <fstream>
#include <iomanip>
#include <set>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/gcp_list.h"
#include "slope_monitor/core/io/yaml_map.h"

namespace slope_monitor {
namespace io {

bool IsTagFamily(const std::string& f) {
  return f == "tag36h11" || f == "tag25h9" || f == "tag16h5" || f == "tagStandard41h12";
}

TargetRole TargetRoleFromName(const std::string& name) {
  if (name == "control") return TargetRole::kControl;
  if (name == "monitoring") return TargetRole::kMonitoring;
  if (name == "check") return TargetRole::kCheck;
  throw ConfigError(
      Message("unknown target role '", name, "' (expected control, monitoring or check)"));
}

std::string TargetRoleName(TargetRole role) {
  switch (role) {
    case TargetRole::kControl:
      return "control";
    case TargetRole::kMonitoring:
      return "monitoring";
    case TargetRole::kCheck:
      return "check";
  }
  return "unknown";
}

void TargetList::Add(const TargetSpec& spec) {
  const std::string key = spec.Key();
  if (index_.count(key)) throw InvalidArgument(Message("duplicate target ", key));
  index_[key] = targets_.size();
  targets_.push_back(spec);
}

bool TargetList::OnlyPicked() const {
  for (const TargetSpec& t : targets_)
    if (t.family != kGcpFamily) return false;
  return !targets_.empty();
}

const TargetSpec* TargetList::Find(const std::string& family, int id) const {
  const auto it = index_.find(family + "/" + std::to_string(id));
  return it == index_.end() ? nullptr : &targets_[it->second];
}

std::vector<std::string> TargetList::Families() const {
  std::set<std::string> f;
  for (const auto& t : targets_) f.insert(t.family);
  return std::vector<std::string>(f.begin(), f.end());
}

namespace {

constexpr double kMaxCoordinate = 1e5;  // [m] |x|, |y|, |z| in the site frame (100 km)
constexpr double kMinSigma = 1e-6;      // [m]
constexpr double kMaxSigma = 1e3;       // [m]
constexpr double kSamePosition =
    1e-3;  // [m] two targets closer than this are one position written twice

// Two surveyed targets at the same position are a copy-paste error.
void CheckDistinctPositions(const TargetList& list, const YamlMap& root) {
  const auto& t = list.targets();
  for (size_t i = 0; i < t.size(); ++i)
    for (size_t j = i + 1; j < t.size(); ++j)
      if (t[i].position && t[j].position &&
          (*t[i].position - *t[j].position).norm() < kSamePosition)
        root.Fail("targets", Message("targets ", t[i].Key(), " and ", t[j].Key(),
                                     " have the same position (", t[i].position->x(), ", ",
                                     t[i].position->y(), ", ", t[i].position->z(), ")"));
}

// A ring marker's edge radii (any unit, inner to outer), over the outer.
std::vector<double> ReadRings(YamlMap& t, const TargetSpec& s) {
  std::vector<double> r = t.RequiredDoubles("rings");
  if (s.family != "circle")
    t.Fail("rings", Message("of target ", s.Key(), ": only circles have rings"));
  if (r.size() < 6 || r.size() % 2 != 0)
    t.Fail("rings",
           Message("of target ", s.Key(), ": ", r.size(),
                   " radii; two per dark ring (inner and outer edge), three rings at least"));
  for (size_t k = 0; k < r.size(); ++k)
    if (!(r[k] > 0.0) || (k > 0 && !(r[k] > r[k - 1])))
      t.Fail("rings", Message("of target ", s.Key(), ": the radii must be positive and increase"));
  const double outer = r.back();
  for (double& v : r) v /= outer;
  return r;
}

TargetList FromMap(YamlMap root) {
  root.String("frame", "site", {"site"});
  if (!root.Has("targets")) root.Fail("targets", "is missing (a list of targets; [] for none)");
  TargetList list;
  for (YamlMap t : root.List("targets")) {
    TargetSpec s;
    s.id = t.RequiredInt("id", 0, 1 << 30);
    s.family =
        t.String("family", "tag36h11",
                 {"tag36h11", "tag25h9", "tag16h5", "tagStandard41h12", "circle", kGcpFamily});
    s.size = t.RequiredDouble("size", 1e-3, 100.0, "m");
    s.role = TargetRoleFromName(t.String("role", "monitoring", {"control", "monitoring", "check"}));
    if (t.Has("position")) {
      const auto p = t.RequiredDoubles("position", 3);
      s.position = Eigen::Vector3d(p[0], p[1], p[2]);
      if (!s.position->allFinite() || s.position->cwiseAbs().maxCoeff() > kMaxCoordinate)
        t.Fail("position", Message("of target ", s.Key(), " (", p[0], ", ", p[1], ", ", p[2],
                                   ") m is beyond ", kMaxCoordinate, " m from the site origin"));
    } else if (s.role != TargetRole::kMonitoring) {
      t.Fail("position", Message("is missing: target ", s.Key(), " is a ", TargetRoleName(s.role),
                                 " point and needs surveyed coordinates"));
    }
    const auto sigma = t.Doubles("sigma", {0.01, 0.01}, 2);
    for (double v : sigma)
      if (!(v >= kMinSigma && v <= kMaxSigma))
        t.Fail("sigma", Message("of target ", s.Key(), ": ", v, " m is outside [", kMinSigma, ", ",
                                kMaxSigma, "] m"));
    s.sigma = Eigen::Vector2d(sigma[0], sigma[1]);
    if (t.Has("normal")) {
      const auto n = t.RequiredDoubles("normal", 3);
      Eigen::Vector3d v(n[0], n[1], n[2]);
      if (v.norm() < 1e-9) t.Fail("normal", "must not be zero");
      s.normal = v.normalized();
    }
    if (t.Has("rings")) s.rings = ReadRings(t, s);
    t.CheckNoUnknownKeys();
    if (list.Find(s.family, s.id)) t.Fail("id", Message("duplicates target ", s.Key()));
    list.Add(s);
  }
  CheckDistinctPositions(list, root);
  root.CheckNoUnknownKeys();
  return list;
}

}  // namespace

TargetList TargetList::Load(const std::string& path) { return FromMap(YamlMap::Load(path)); }

TargetList TargetList::FromYaml(const std::string& text, const std::string& context) {
  return FromMap(YamlMap::Parse(text, context));
}

std::string TargetList::ToYaml() const {
  std::ostringstream out;
  out << std::setprecision(10);
  out << "# slope_monitor target list (schema: include/slope_monitor/core/io/target_list.h)\n";
  out << "# id: int; family: tag36h11|...|circle; size [m]; role: control|monitoring|check;\n";
  out << "# position [m] site frame; sigma [m] (horizontal, vertical); normal: unit vector "
         "(optional); rings: ring markers' edge radii over the outer (optional)\n";
  out << "frame: site\ntargets:\n";
  for (const auto& t : targets_) {
    out << "  - {id: " << t.id << ", family: " << t.family << ", size: " << t.size
        << ", role: " << TargetRoleName(t.role);
    if (t.position) {
      out << ", position: [" << t.position->x() << ", " << t.position->y() << ", "
          << t.position->z() << "]";
    }
    out << ", sigma: [" << t.sigma.x() << ", " << t.sigma.y() << "]";
    if (t.normal)
      out << ", normal: [" << t.normal->x() << ", " << t.normal->y() << ", " << t.normal->z()
          << "]";
    if (!t.rings.empty()) {
      out << ", rings: [";
      for (size_t k = 0; k < t.rings.size(); ++k) out << (k ? ", " : "") << t.rings[k];
      out << "]";
    }
    out << "}\n";
  }
  return out.str();
}

void TargetList::Save(const std::string& path) const {
  std::ofstream out(path);
  if (!out) throw IoError(Message("cannot write target list '", path, "'"));
  out << ToYaml();
  if (!out) throw IoError(Message("error writing target list '", path, "'"));
}

}  // namespace io
}  // namespace slope_monitor
