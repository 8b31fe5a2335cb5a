#include "slope_monitor/ros/parameters.h"

#include <cmath>

#include <xmlrpcpp/XmlRpcValue.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

const char* TypeName(const XmlRpc::XmlRpcValue& v) {
  switch (v.getType()) {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return "bool";
    case XmlRpc::XmlRpcValue::TypeInt:
      return "int";
    case XmlRpc::XmlRpcValue::TypeDouble:
      return "double";
    case XmlRpc::XmlRpcValue::TypeString:
      return "string";
    case XmlRpc::XmlRpcValue::TypeArray:
      return "list";
    case XmlRpc::XmlRpcValue::TypeStruct:
      return "dictionary";
    default:
      return "unknown type";
  }
}

bool ToDouble(XmlRpc::XmlRpcValue& v, double* out) {
  if (v.getType() == XmlRpc::XmlRpcValue::TypeDouble) {
    *out = static_cast<double>(v);
    return true;
  }
  if (v.getType() == XmlRpc::XmlRpcValue::TypeInt) {
    *out = static_cast<int>(v);
    return true;
  }
  return false;
}

template <typename T>
XmlRpc::XmlRpcValue ListValue(const std::vector<T>& values) {
  XmlRpc::XmlRpcValue list;
  list.setSize(static_cast<int>(values.size()));
  for (size_t i = 0; i < values.size(); ++i)
    list[static_cast<int>(i)] = XmlRpc::XmlRpcValue(values[i]);
  return list;
}

// The keys of a parameter tree as the parameter server names them: a
// dictionary's members as "<dictionary>/<member>", recursively.
void ListTreeKeys(const XmlRpc::XmlRpcValue& tree, const std::string& prefix,
                  std::vector<std::string>* out) {
  if (tree.getType() != XmlRpc::XmlRpcValue::TypeStruct) return;
  XmlRpc::XmlRpcValue& t = const_cast<XmlRpc::XmlRpcValue&>(tree);
  for (auto it = t.begin(); it != t.end(); ++it) {
    if (it->second.getType() == XmlRpc::XmlRpcValue::TypeStruct && it->second.size() > 0)
      ListTreeKeys(it->second, prefix + it->first + "/", out);
    else
      out->push_back(prefix + it->first);
  }
}

std::string UnitSuffix(const std::string& unit) { return unit.empty() ? "" : " " + unit; }

}  // namespace

ParamReader::ParamReader(const XmlRpc::XmlRpcValue& params, const std::string& ns)
    : use_tree_(true), tree_(params), tree_ns_(ns) {}

std::string ParamReader::FullKey(const std::string& key) const {
  return use_tree_ ? tree_ns_ + "/" + key : nh_->resolveName(key);
}

bool ParamReader::Get(const std::string& key, XmlRpc::XmlRpcValue* v) const {
  if (!use_tree_) return nh_->getParam(key, *v);
  // "schedule/interval" is member interval of dictionary schedule, as the
  // parameter server resolves it.
  const XmlRpc::XmlRpcValue* node = &tree_;
  size_t begin = 0;
  while (true) {
    const size_t slash = key.find('/', begin);
    const std::string part =
        key.substr(begin, slash == std::string::npos ? std::string::npos : slash - begin);
    if (node->getType() != XmlRpc::XmlRpcValue::TypeStruct || !node->hasMember(part)) return false;
    node = &const_cast<XmlRpc::XmlRpcValue&>(*node)[part];
    if (slash == std::string::npos) break;
    begin = slash + 1;
  }
  *v = *node;
  return true;
}

double ParamReader::Double(const std::string& key, double default_value, double min, double max,
                           const std::string& unit) {
  read_.insert(FullKey(key));
  defaults_[key] = XmlRpc::XmlRpcValue(default_value);
  XmlRpc::XmlRpcValue v;
  if (!Get(key, &v)) return default_value;
  double value;
  if (!ToDouble(v, &value)) {
    throw ConfigError(Message("parameter '", FullKey(key), "' must be a number", UnitSuffix(unit),
                              ", got a ", TypeName(v)));
  }
  if (!std::isfinite(value) || value < min || value > max) {
    throw ConfigError(Message("parameter '", FullKey(key), "' = ", value, UnitSuffix(unit),
                              " is outside [", min, ", ", max, "]"));
  }
  return value;
}

int ParamReader::Int(const std::string& key, int default_value, int min, int max,
                     const std::string& unit) {
  read_.insert(FullKey(key));
  defaults_[key] = XmlRpc::XmlRpcValue(default_value);
  XmlRpc::XmlRpcValue v;
  if (!Get(key, &v)) return default_value;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeInt) {
    throw ConfigError(Message("parameter '", FullKey(key), "' must be an integer", UnitSuffix(unit),
                              ", got a ", TypeName(v)));
  }
  const int value = static_cast<int>(v);
  if (value < min || value > max) {
    throw ConfigError(Message("parameter '", FullKey(key), "' = ", value, UnitSuffix(unit),
                              " is outside [", min, ", ", max, "]"));
  }
  return value;
}

bool ParamReader::Bool(const std::string& key, bool default_value) {
  read_.insert(FullKey(key));
  defaults_[key] = XmlRpc::XmlRpcValue(default_value);
  XmlRpc::XmlRpcValue v;
  if (!Get(key, &v)) return default_value;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeBoolean) {
    throw ConfigError(
        Message("parameter '", FullKey(key), "' must be true or false, got a ", TypeName(v)));
  }
  return static_cast<bool>(v);
}

std::string ParamReader::String(const std::string& key, const std::string& default_value,
                                const std::vector<std::string>& allowed) {
  read_.insert(FullKey(key));
  defaults_[key] = XmlRpc::XmlRpcValue(default_value);
  XmlRpc::XmlRpcValue v;
  std::string value = default_value;
  if (Get(key, &v)) {
    if (v.getType() != XmlRpc::XmlRpcValue::TypeString) {
      throw ConfigError(
          Message("parameter '", FullKey(key), "' must be a string, got a ", TypeName(v)));
    }
    value = static_cast<std::string>(v);
  }
  if (!allowed.empty()) {
    bool ok = false;
    std::string list;
    for (const auto& a : allowed) {
      ok = ok || a == value;
      list += (list.empty() ? "" : ", ") + a;
    }
    if (!ok)
      throw ConfigError(
          Message("parameter '", FullKey(key), "' = '", value, "' is not one of: ", list));
  }
  return value;
}

std::vector<double> ParamReader::DoubleList(const std::string& key,
                                            const std::vector<double>& default_value) {
  read_.insert(FullKey(key));
  defaults_[key] = ListValue(default_value);
  XmlRpc::XmlRpcValue v;
  if (!Get(key, &v)) return default_value;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeArray) {
    throw ConfigError(
        Message("parameter '", FullKey(key), "' must be a list of numbers, got a ", TypeName(v)));
  }
  std::vector<double> out;
  for (int i = 0; i < v.size(); ++i) {
    double d;
    if (!ToDouble(v[i], &d) || !std::isfinite(d)) {
      throw ConfigError(
          Message("parameter '", FullKey(key), "' element ", i, " is not a finite number"));
    }
    out.push_back(d);
  }
  return out;
}

std::vector<std::string> ParamReader::StringList(const std::string& key,
                                                 const std::vector<std::string>& default_value) {
  read_.insert(FullKey(key));
  defaults_[key] = ListValue(default_value);
  XmlRpc::XmlRpcValue v;
  if (!Get(key, &v)) return default_value;
  if (v.getType() != XmlRpc::XmlRpcValue::TypeArray) {
    throw ConfigError(
        Message("parameter '", FullKey(key), "' must be a list of strings, got a ", TypeName(v)));
  }
  std::vector<std::string> out;
  for (int i = 0; i < v.size(); ++i) {
    if (v[i].getType() != XmlRpc::XmlRpcValue::TypeString) {
      throw ConfigError(Message("parameter '", FullKey(key), "' element ", i, " is not a string"));
    }
    out.push_back(static_cast<std::string>(v[i]));
  }
  return out;
}

void ParamReader::CheckNoUnknownKeys(const std::set<std::string>& ignored) const {
  std::vector<std::string> all;
  std::string prefix;
  if (use_tree_) {
    prefix = tree_ns_ + "/";
    ListTreeKeys(tree_, prefix, &all);
  } else {
    if (!nh_->getParamNames(all)) return;
    prefix = nh_->getNamespace() + "/";
  }
  std::string unknown;
  for (const std::string& name : all) {
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string relative = name.substr(prefix.size());
    bool known = relative == kGraphReadyParam;
    for (const std::string& r : read_)
      known = known || name == r || name.compare(0, r.size() + 1, r + "/") == 0;
    for (const std::string& i : ignored)
      known = known || relative == i || relative.compare(0, i.size() + 1, i + "/") == 0;
    if (!known) unknown += (unknown.empty() ? "" : ", ") + name;
  }
  if (!unknown.empty()) throw ConfigError(Message("unknown parameter(s): ", unknown));
}

}  // namespace ros_adapters
}  // namespace slope_monitor
