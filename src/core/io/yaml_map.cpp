#include "slope_monitor/core/io/yaml_map.h"

#include <cmath>
#include <fstream>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

std::string Unit(const std::string& unit) { return unit.empty() ? "" : " " + unit; }

}  // namespace

YamlMap YamlMap::Load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw IoError(Message("cannot open YAML file '", path, "'"));
  YAML::Node node;
  try {
    node = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw IoError(Message("YAML file '", path, "' is malformed: ", e.what()));
  }
  if (!node.IsMap())
    throw IoError(Message("YAML file '", path, "' must hold a map at its top level"));
  return YamlMap(node, path);
}

YamlMap YamlMap::Parse(const std::string& text, const std::string& context) {
  YAML::Node node;
  try {
    node = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw IoError(Message(context, ": malformed YAML: ", e.what()));
  }
  if (node.IsNull()) node = YAML::Node(YAML::NodeType::Map);
  if (!node.IsMap()) throw IoError(Message(context, ": must hold a map at its top level"));
  return YamlMap(node, context);
}

YamlMap::YamlMap(const YAML::Node& node, const std::string& context)
    : node_(node), context_(context) {}

bool YamlMap::Has(const std::string& key) const {
  return node_.IsMap() && node_[key].IsDefined() && !node_[key].IsNull();
}

void YamlMap::Fail(const std::string& key, const std::string& what) const {
  throw ConfigError(Message(context_, ": '", key, "' ", what));
}

YAML::Node YamlMap::Get(const std::string& key) {
  read_.insert(key);
  if (!node_.IsMap()) return YAML::Node();
  return node_[key];
}

double YamlMap::Double(const std::string& key, double default_value, double min, double max,
                       const std::string& unit) {
  const YAML::Node n = Get(key);
  if (!n.IsDefined() || n.IsNull()) return default_value;
  double v;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    Fail(key, Message("must be a number", Unit(unit), ", got '", n.Scalar(), "'"));
  }
  if (!std::isfinite(v) || v < min || v > max) {
    Fail(key, Message("= ", v, Unit(unit), " is outside [", min, ", ", max, "]"));
  }
  return v;
}

double YamlMap::RequiredDouble(const std::string& key, double min, double max,
                               const std::string& unit) {
  if (!Has(key))
    Fail(key, Message("is missing (a number", Unit(unit), " in [", min, ", ", max, "])"));
  return Double(key, 0.0, min, max, unit);
}

int YamlMap::Int(const std::string& key, int default_value, int min, int max,
                 const std::string& unit) {
  const YAML::Node n = Get(key);
  if (!n.IsDefined() || n.IsNull()) return default_value;
  int v;
  try {
    v = n.as<int>();
  } catch (const YAML::Exception&) {
    Fail(key, Message("must be an integer", Unit(unit), ", got '", n.Scalar(), "'"));
  }
  if (v < min || v > max)
    Fail(key, Message("= ", v, Unit(unit), " is outside [", min, ", ", max, "]"));
  return v;
}

int YamlMap::RequiredInt(const std::string& key, int min, int max, const std::string& unit) {
  if (!Has(key))
    Fail(key, Message("is missing (an integer", Unit(unit), " in [", min, ", ", max, "])"));
  return Int(key, 0, min, max, unit);
}

bool YamlMap::Bool(const std::string& key, bool default_value) {
  const YAML::Node n = Get(key);
  if (!n.IsDefined() || n.IsNull()) return default_value;
  try {
    return n.as<bool>();
  } catch (const YAML::Exception&) {
    Fail(key, Message("must be true or false, got '", n.Scalar(), "'"));
  }
}

std::string YamlMap::String(const std::string& key, const std::string& default_value,
                            const std::vector<std::string>& allowed) {
  const YAML::Node n = Get(key);
  std::string v = default_value;
  if (n.IsDefined() && !n.IsNull()) {
    if (!n.IsScalar()) Fail(key, "must be a string");
    v = n.Scalar();
  }
  if (!allowed.empty()) {
    std::string list;
    bool ok = false;
    for (const auto& a : allowed) {
      ok = ok || a == v;
      list += (list.empty() ? "" : ", ") + a;
    }
    if (!ok) Fail(key, Message("= '", v, "' is not one of: ", list));
  }
  return v;
}

std::string YamlMap::RequiredString(const std::string& key,
                                    const std::vector<std::string>& allowed) {
  if (!Has(key)) Fail(key, "is missing (a string)");
  return String(key, "", allowed);
}

std::vector<double> YamlMap::Doubles(const std::string& key,
                                     const std::vector<double>& default_value, int size_required) {
  const YAML::Node n = Get(key);
  if (!n.IsDefined() || n.IsNull()) return default_value;
  if (!n.IsSequence()) Fail(key, "must be a list of numbers");
  std::vector<double> out;
  for (size_t i = 0; i < n.size(); ++i) {
    double v;
    try {
      v = n[i].as<double>();
    } catch (const YAML::Exception&) {
      Fail(key, Message("element ", i, " is not a number"));
    }
    if (!std::isfinite(v)) Fail(key, Message("element ", i, " is not finite"));
    out.push_back(v);
  }
  if (size_required >= 0 && static_cast<int>(out.size()) != size_required) {
    Fail(key, Message("must have ", size_required, " elements, has ", out.size()));
  }
  return out;
}

std::vector<double> YamlMap::RequiredDoubles(const std::string& key, int size_required) {
  if (!Has(key)) Fail(key, "is missing (a list of numbers)");
  return Doubles(key, {}, size_required);
}

std::vector<std::string> YamlMap::Strings(const std::string& key,
                                          const std::vector<std::string>& default_value) {
  const YAML::Node n = Get(key);
  if (!n.IsDefined() || n.IsNull()) return default_value;
  if (!n.IsSequence()) Fail(key, "must be a list of strings");
  std::vector<std::string> out;
  for (size_t i = 0; i < n.size(); ++i) {
    if (!n[i].IsScalar()) Fail(key, Message("element ", i, " is not a string"));
    out.push_back(n[i].Scalar());
  }
  return out;
}

YamlMap YamlMap::Map(const std::string& key) {
  if (!Has(key)) Fail(key, "is missing (a map)");
  return OptionalMap(key);
}

YamlMap YamlMap::OptionalMap(const std::string& key) {
  YAML::Node n = Get(key);
  if (n.IsDefined() && !n.IsNull() && !n.IsMap()) Fail(key, "must be a map");
  return YamlMap(n.IsDefined() && !n.IsNull() ? n : YAML::Node(YAML::NodeType::Map),
                 context_ + ": " + key);
}

std::vector<YamlMap> YamlMap::List(const std::string& key) {
  YAML::Node n = Get(key);
  std::vector<YamlMap> out;
  if (!n.IsDefined() || n.IsNull()) return out;
  if (!n.IsSequence()) Fail(key, "must be a list");
  for (size_t i = 0; i < n.size(); ++i) {
    if (!n[i].IsMap()) Fail(key, Message("element ", i, " must be a map"));
    out.emplace_back(n[i], Message(context_, ": ", key, "[", i, "]"));
  }
  return out;
}

void YamlMap::CheckNoUnknownKeys() const {
  if (!node_.IsMap()) return;
  for (const auto& kv : node_) {
    const std::string key = kv.first.Scalar();
    if (!read_.count(key)) {
      throw ConfigError(Message(context_, ": unknown key '", key, "'"));
    }
  }
}

}  // namespace io
}  // namespace slope_monitor
