// Parameters of a node without a parameter server (process_bag): the same
// YAML files a launch file loads with <rosparam command="load">, in the same
// order, into one dictionary that ros_adapters::ParamReader reads.
//
//   XmlRpc::XmlRpcValue p = LoadParamFile(defaults_dir + "/bundle_adjuster.yaml");
//   SetParam(&p, "target_list", XmlRpc::XmlRpcValue(path));
//   MergeParams(&p, LoadParamFile(overlay));     // later keys win, as rosparam load
//   ParamReader reader(p, "/bundle_adjuster");
#pragma once

#include <string>
#include <vector>

#include <xmlrpcpp/XmlRpcValue.h>

namespace slope_monitor {
namespace ros_adapters {

// A YAML file whose top level is a map, as XmlRpc values (bool, int, double,
// string, list, dictionary). Throws ConfigError naming the file.
XmlRpc::XmlRpcValue LoadParamFile(const std::string& path);

// Top-level keys of `from` replace those of `into` (nested dictionaries are
// merged key by key, as `rosparam load` does).
void MergeParams(XmlRpc::XmlRpcValue* into, const XmlRpc::XmlRpcValue& from);

void SetParam(XmlRpc::XmlRpcValue* params, const std::string& key,
              const XmlRpc::XmlRpcValue& value);

// A list parameter of strings (e.g. a node's `cameras`).
XmlRpc::XmlRpcValue StringListParam(const std::vector<std::string>& values);

// The installed package's config/ folder (ros::package); ConfigError when the
// package is not found (the workspace not sourced).
std::string PackageConfigDir();

// A node's parameters as replay.launch loads them, without the command line's:
// <config_dir>/defaults/<node>.yaml, then <config_dir>/process_bag/<node>.yaml
// (what the launch files add) when there is one.
XmlRpc::XmlRpcValue LoadNodeParams(const std::string& config_dir, const std::string& node);

}  // namespace ros_adapters
}  // namespace slope_monitor
