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

}  // namespace ros_adapters
}  // namespace slope_monitor
