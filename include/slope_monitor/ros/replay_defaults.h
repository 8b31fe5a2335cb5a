// Where a site's history is kept when not named: one history per
// site, whatever the recording. A crew records after every event and
// processes each recording with the same command; every recording of a site
// continues that site's one history, its reference epoch and its filters.
// One rule for process_bag (--database) and the graph's nodes (their
// `database` parameter "auto", the default of replay.launch and
// live.launch): test/ros/safe_defaults_test.cpp checks both.
#pragma once

#include <string>

namespace slope_monitor {
namespace ros_adapters {

// What may name a recording's site, in this order: the site file's `name`,
// a name given as it is (a node's `site_name` parameter: the overlay loaded
// into its namespace), the estimator overlay's `site_name` (make_survey_bag
// writes it beside a simulated survey), the simulator truth's `site.name`.
// Files that are empty paths or absent are skipped.
struct SiteNameSources {
  std::string site_file, site_config, truth_file;
  std::string recording;  // a bag's path: the last resort (its name less ".bag")
  std::string site_name;  // given as it is ("" = none)
};

// The site's name, and in *from where it was read ("site file '/x/site.yaml'");
// "" when nothing names it. Throws ConfigError for a file that cannot be read.
std::string SiteNameOf(const SiteNameSources& sources, std::string* from = nullptr);

// <home>/.ros/slope_monitor/<site name>.db; without a site name, the
// recording's: /data/event3.bag -> <home>/.ros/slope_monitor/event3.db.
// ConfigError when neither is known.
std::string DefaultHistory(const SiteNameSources& sources, const std::string& home);

// A node's `database` parameter: "auto" is DefaultHistory with $HOME, any
// other value (a path, or "" for no history) is returned as given.
std::string ResolveDatabase(const std::string& database, const SiteNameSources& sources);

}  // namespace ros_adapters
}  // namespace slope_monitor
