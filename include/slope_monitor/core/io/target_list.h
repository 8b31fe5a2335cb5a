// The target list: every target of a site with its family, size, role and
// (for control and check points) surveyed site coordinates. It is the format
// crews use for real surveys; the simulator writes the same format.
//
// File schema (YAML):
//   frame: site                  # frame of the positions (only "site")
//   targets:                     # list of maps:
//     - id: 3                    # int >= 0, unique within its family
//       family: tag36h11         # tag36h11 | tag25h9 | tag16h5 | tagStandard41h12 | circle
//       size: 0.60               # [m] tag: edge of the black border square; circle: bright disc
//       diameter role: control            # control | monitoring | check position: [x, y, z]      #
//       [m] site frame; required for control and check,
//                                #     optional (approximate) for monitoring
//       sigma: [0.03, 0.01]      # [m] survey std (horizontal, vertical); control/check; default
//       [0.01, 0.01] normal: [nx, ny, nz]     # optional unit normal of the target plane (site),
//       for the
//                                #     perspective correction of circle centres
//       rings: [45, 55, 65, 78, 88, 100]  # optional, circles that are ring markers:
//                                #     the radii of the rings' edges (any unit,
//                                #     inner to outer); the ID is read from them
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace io {

enum class TargetRole { kControl, kMonitoring, kCheck };
TargetRole TargetRoleFromName(const std::string& name);  // throws ConfigError naming the value
std::string TargetRoleName(TargetRole role);

struct TargetSpec {
  int id = 0;
  std::string family = "tag36h11";
  double size = 0.0;  // [m]
  TargetRole role = TargetRole::kMonitoring;
  std::optional<Eigen::Vector3d> position;  // [m] site
  Eigen::Vector2d sigma{0.01, 0.01};        // [m] horizontal, vertical
  std::optional<Eigen::Vector3d> normal;    // unit, site
  std::string name;  // the survey's own name ("gcp03" of a gcp list); "": none
  // Circles that are ring markers (three or more dark rings): the radii of
  // the rings' edges, inner to outer, over the outer edge's (the last is 1;
  // two per dark ring). The marker's ID is read from them in the image (no
  // pose needed); empty: not a ring marker.
  std::vector<double> rings;

  // "tag36h11/3", "circle/12": the key used across the package.
  std::string Key() const { return family + "/" + std::to_string(id); }
  // What a crew calls it in messages: its name, else its key.
  std::string Label() const { return name.empty() ? Key() : name; }
};

class TargetList {
 public:
  // Throws ConfigError naming the file and the key (duplicate ID, missing
  // position for a control point, unknown family, ...).
  static TargetList Load(const std::string& path);
  static TargetList FromYaml(const std::string& text, const std::string& context);
  void Save(const std::string& path) const;
  std::string ToYaml() const;

  // Adds a target; throws InvalidArgument on a duplicate (family, id).
  void Add(const TargetSpec& spec);
  const TargetSpec* Find(const std::string& family, int id) const;
  const std::vector<TargetSpec>& targets() const { return targets_; }
  std::vector<std::string> Families() const;
  // Whether the list holds targets and all of them are points picked by hand
  // in the photos (family "gcp", gcp_list.h): nothing to look for.
  bool OnlyPicked() const;

 private:
  std::vector<TargetSpec> targets_;
  std::map<std::string, size_t> index_;
};

bool IsTagFamily(const std::string& family);

}  // namespace io
}  // namespace slope_monitor
