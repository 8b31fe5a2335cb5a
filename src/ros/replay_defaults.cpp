#include "slope_monitor/ros/replay_defaults.h"

#include <cstdlib>
#include <filesystem>

#include <yaml-cpp/yaml.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

// The string at `path` (keys) in a YAML file; "" when the file or the key is absent.
std::string YamlString(const std::string& file, const std::vector<std::string>& path) {
  if (file.empty() || !std::filesystem::is_regular_file(file)) return "";
  YAML::Node node;
  try {
    node = YAML::LoadFile(file);
    for (const std::string& key : path) {
      if (!node.IsMap() || !node[key]) return "";
      node = node[key];
    }
    return node.IsScalar() ? node.as<std::string>() : "";
  } catch (const YAML::Exception& e) {
    throw ConfigError(Message("'", file, "': cannot read its site name: ", e.what()));
  }
}

}  // namespace

std::string SiteNameOf(const SiteNameSources& s, std::string* from) {
  // The site file's name, then a name given as it is, then the files that carry one.
  const std::string file_name = YamlString(s.site_file, {"name"});
  if (!file_name.empty()) {
    if (from) *from = Message("site file '", s.site_file, "'");
    return file_name;
  }
  if (!s.site_name.empty()) {
    if (from) *from = "parameter site_name";
    return s.site_name;
  }
  const struct {
    const std::string& file;
    std::vector<std::string> path;
    const char* what;
  } candidates[] = {{s.site_config, {"site_name"}, "estimator overlay"},
                    {s.truth_file, {"site", "name"}, "simulator truth"}};
  for (const auto& c : candidates) {
    const std::string name = YamlString(c.file, c.path);
    if (name.empty()) continue;
    if (from) *from = Message(c.what, " '", c.file, "'");
    return name;
  }
  return "";
}

std::string DefaultHistory(const SiteNameSources& s, const std::string& home) {
  std::string name = SiteNameOf(s);
  if (name.empty() && !s.recording.empty()) {
    name = std::filesystem::path(s.recording).filename().string();
    if (name.size() > 4 && name.substr(name.size() - 4) == ".bag") name.resize(name.size() - 4);
  }
  if (name.empty())
    throw ConfigError(
        "database 'auto': no site name (a site file, an overlay with site_name or a simulator "
        "truth) and no recording name; name the history with database:=FILE");
  return home + "/.ros/slope_monitor/" + name + ".db";
}

std::string ResolveDatabase(const std::string& database, const SiteNameSources& s) {
  if (database != "auto") return database;
  const char* home = std::getenv("HOME");
  return DefaultHistory(s, home ? home : ".");
}

}  // namespace ros_adapters
}  // namespace slope_monitor
