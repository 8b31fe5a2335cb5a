// Checked reading of YAML configuration files. Every error names the file and
// the key path ("config/sim/demo_site.yaml: cameras[2].pixel_size = -1 ...").
//
//   YamlMap root = YamlMap::Load("site.yaml");
//   double c = root.Map("camera").RequiredDouble("principal_distance", 1.0, 500.0, "mm");
//   root.CheckNoUnknownKeys();   // this map's keys; call it on every sub-map you read too
#pragma once

#include <set>
#include <string>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace slope_monitor {
namespace io {

class YamlMap {
 public:
  // Loads a file whose top level is a map; throws IoError naming the file.
  static YamlMap Load(const std::string& path);
  // Parses text (context names it in messages).
  static YamlMap Parse(const std::string& text, const std::string& context);
  YamlMap(const YAML::Node& node, const std::string& context);

  bool Has(const std::string& key) const;
  const std::string& context() const { return context_; }

  double Double(const std::string& key, double default_value, double min, double max,
                const std::string& unit = "");
  double RequiredDouble(const std::string& key, double min, double max,
                        const std::string& unit = "");
  int Int(const std::string& key, int default_value, int min, int max,
          const std::string& unit = "");
  int RequiredInt(const std::string& key, int min, int max, const std::string& unit = "");
  bool Bool(const std::string& key, bool default_value);
  std::string String(const std::string& key, const std::string& default_value,
                     const std::vector<std::string>& allowed = {});
  std::string RequiredString(const std::string& key, const std::vector<std::string>& allowed = {});
  // A list of numbers; size_required < 0 accepts any length.
  std::vector<double> Doubles(const std::string& key, const std::vector<double>& default_value,
                              int size_required = -1);
  std::vector<double> RequiredDoubles(const std::string& key, int size_required = -1);
  std::vector<std::string> Strings(const std::string& key,
                                   const std::vector<std::string>& default_value);

  // A nested map (required or optional: an absent optional map is empty).
  YamlMap Map(const std::string& key);
  YamlMap OptionalMap(const std::string& key);
  // A list of maps (absent: empty list).
  std::vector<YamlMap> List(const std::string& key);
  // The raw node of a key (marked as read; undefined when absent), for
  // shapes the typed readers do not cover (lists of coordinate pairs).
  YAML::Node Node(const std::string& key) { return Get(key); }

  // Throws ConfigError naming the first key of this map (with its path) that
  // was never read. Sub-maps and list elements check their own keys.
  void CheckNoUnknownKeys() const;

  // Error helper: throws ConfigError "<context>.<key>: <what>".
  [[noreturn]] void Fail(const std::string& key, const std::string& what) const;

 private:
  YAML::Node Get(const std::string& key);
  YAML::Node node_;
  std::string context_;
  std::set<std::string> read_;
};

}  // namespace io
}  // namespace slope_monitor
