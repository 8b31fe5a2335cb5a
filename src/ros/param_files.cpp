#include "slope_monitor/ros/param_files.h"

#include <filesystem>

#include <ros/package.h>
#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

// A YAML scalar as rosparam types it: bool, int, double, else string.
XmlRpc::XmlRpcValue FromScalar(const YAML::Node& n) {
  const std::string& text = n.Scalar();
  if (n.Tag() != "!") {  // unquoted
    if (text == "true" || text == "True" || text == "TRUE") return XmlRpc::XmlRpcValue(true);
    if (text == "false" || text == "False" || text == "FALSE") return XmlRpc::XmlRpcValue(false);
    try {
      size_t used = 0;
      const long long i = std::stoll(text, &used, 0);
      if (used == text.size()) return XmlRpc::XmlRpcValue(static_cast<int>(i));
    } catch (const std::exception&) {
    }
    try {
      size_t used = 0;
      const double d = std::stod(text, &used);
      if (used == text.size()) return XmlRpc::XmlRpcValue(d);
    } catch (const std::exception&) {
    }
  }
  return XmlRpc::XmlRpcValue(text);
}

XmlRpc::XmlRpcValue FromYaml(const YAML::Node& n, const std::string& path) {
  switch (n.Type()) {
    case YAML::NodeType::Scalar:
      return FromScalar(n);
    case YAML::NodeType::Sequence: {
      XmlRpc::XmlRpcValue list;
      list.setSize(static_cast<int>(n.size()));
      for (size_t i = 0; i < n.size(); ++i) list[static_cast<int>(i)] = FromYaml(n[i], path);
      return list;
    }
    case YAML::NodeType::Map: {
      XmlRpc::XmlRpcValue map;
      map.begin();  // makes it a (possibly empty) dictionary
      for (const auto& kv : n) map[kv.first.as<std::string>()] = FromYaml(kv.second, path);
      return map;
    }
    default:
      return XmlRpc::XmlRpcValue(std::string());  // null: as rosparam, an empty value
  }
}

}  // namespace

XmlRpc::XmlRpcValue LoadParamFile(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const std::exception& e) {
    throw ConfigError(Message("parameter file '", path, "': ", e.what()));
  }
  if (root.IsNull()) {
    XmlRpc::XmlRpcValue empty;
    empty.begin();
    return empty;
  }
  if (!root.IsMap())
    throw ConfigError(Message("parameter file '", path, "': the top level is not a map"));
  return FromYaml(root, path);
}

void MergeParams(XmlRpc::XmlRpcValue* into, const XmlRpc::XmlRpcValue& from) {
  if (from.getType() != XmlRpc::XmlRpcValue::TypeStruct) return;
  if (into->getType() != XmlRpc::XmlRpcValue::TypeStruct) into->begin();
  XmlRpc::XmlRpcValue& f = const_cast<XmlRpc::XmlRpcValue&>(from);
  for (auto it = f.begin(); it != f.end(); ++it) {
    if (it->second.getType() == XmlRpc::XmlRpcValue::TypeStruct && into->hasMember(it->first) &&
        (*into)[it->first].getType() == XmlRpc::XmlRpcValue::TypeStruct) {
      MergeParams(&(*into)[it->first], it->second);
    } else {
      (*into)[it->first] = it->second;
    }
  }
}

void SetParam(XmlRpc::XmlRpcValue* params, const std::string& key,
              const XmlRpc::XmlRpcValue& value) {
  if (params->getType() != XmlRpc::XmlRpcValue::TypeStruct) params->begin();
  (*params)[key] = value;
}

XmlRpc::XmlRpcValue StringListParam(const std::vector<std::string>& values) {
  XmlRpc::XmlRpcValue list;
  list.setSize(static_cast<int>(values.size()));
  for (size_t i = 0; i < values.size(); ++i) list[static_cast<int>(i)] = values[i];
  return list;
}

std::string PackageConfigDir() {
  const std::string pkg = ros::package::getPath("slope_monitor");
  if (pkg.empty())
    throw ConfigError("package 'slope_monitor' not found (source the workspace's setup.bash)");
  return pkg + "/config";
}

XmlRpc::XmlRpcValue LoadNodeParams(const std::string& config_dir, const std::string& node) {
  XmlRpc::XmlRpcValue p = LoadParamFile(config_dir + "/defaults/" + node + ".yaml");
  const std::string overlay = config_dir + "/process_bag/" + node + ".yaml";
  if (std::filesystem::exists(overlay)) MergeParams(&p, LoadParamFile(overlay));
  return p;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
