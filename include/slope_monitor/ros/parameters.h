// Typed, checked parameter loading at the ROS boundary (doc/style.md: parameters
// are read once into typed Options and checked; a bad key names the key and
// the reason, and the node does not advertise).
//
//   ParamReader p(private_nh);
//   options.window = p.Int("window", 11, 3, 51, "px");
//   p.CheckNoUnknownKeys();   // every key under ~ must have been read
//
// Every getter throws slope_monitor::ConfigError naming the full key.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <ros/node_handle.h>
#include <xmlrpcpp/XmlRpcValue.h>

namespace slope_monitor {
namespace ros_adapters {

// `~graph_ready`: set by the launch and the node (setup.h GraphReady) for
// replay_start, never a node's own parameter; CheckNoUnknownKeys accepts it.
inline constexpr char kGraphReadyParam[] = "graph_ready";

class ParamReader {
 public:
  explicit ParamReader(const ros::NodeHandle& nh) : nh_(nh) {}
  // Without a master (process_bag): the keys of `params` (a dictionary, see
  // ros/param_files.h), named in messages as "<ns>/<key>".
  ParamReader(const XmlRpc::XmlRpcValue& params, const std::string& ns);

  double Double(const std::string& key, double default_value, double min, double max,
                const std::string& unit = "");
  int Int(const std::string& key, int default_value, int min, int max,
          const std::string& unit = "");
  bool Bool(const std::string& key, bool default_value);
  std::string String(const std::string& key, const std::string& default_value,
                     const std::vector<std::string>& allowed = {});
  std::vector<double> DoubleList(const std::string& key, const std::vector<double>& default_value);
  std::vector<std::string> StringList(const std::string& key,
                                      const std::vector<std::string>& default_value);

  // Throws ConfigError naming every parameter under the node's namespace that
  // no getter asked for (a misspelt key must not be silently ignored).
  // Keys in `ignored` (and the nodelet manager's own) are allowed.
  void CheckNoUnknownKeys(const std::set<std::string>& ignored = {}) const;

  std::string FullKey(const std::string& key) const;

  // Every key asked for so far with the default its getter was given (the
  // value a node gets when no file or launch sets it): the test that checks
  // config/defaults/*.yaml against the Options structs compares the files'
  // values with these (test/ros/config_files_test.cpp).
  const std::map<std::string, XmlRpc::XmlRpcValue>& Defaults() const { return defaults_; }

 private:
  bool Get(const std::string& key, XmlRpc::XmlRpcValue* v) const;

  std::optional<ros::NodeHandle> nh_;  // empty: read `tree_`
  bool use_tree_ = false;              // read `tree_`, not the parameter server
  XmlRpc::XmlRpcValue tree_;
  std::string tree_ns_;
  std::set<std::string> read_;
  std::map<std::string, XmlRpc::XmlRpcValue> defaults_;  // key -> default given
};

}  // namespace ros_adapters
}  // namespace slope_monitor
