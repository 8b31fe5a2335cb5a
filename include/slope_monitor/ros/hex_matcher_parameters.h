// The hex_matcher node's parameters, read once into typed options: used by
// the nodelet (parameter server) and by process_bag --uav-tie-points (the
// same config/defaults/hex_matcher.yaml), so both match with the same
// settings. Keys, units and ranges: config/defaults/hex_matcher.yaml; the
// defaults of the reader are the options' in-class values (one place).
// Throws ConfigError naming the key (CheckNoUnknownKeys is called).
#pragma once

#include <string>
#include <vector>

#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/matching/sequence_matcher.h"
#include "slope_monitor/ros/parameters.h"

namespace slope_monitor {
namespace ros_adapters {

struct HexMatcherParameters {
  std::string mode = "pair";  // pair | track | sequence
  // Pair mode: largest stamp difference of a and b [s]; camera names written
  // into the messages.
  double max_pair_dt = 0.5;
  std::string camera_a = "cam_a", camera_b = "cam_b";
  matching::HexMatcherOptions hex;  // pair and track modes
  matching::MatchPrior prior;       // pair and track modes
  // Into `prior`: rectangles [x0, y0, x1, y1, ...] of image a [px] whose
  // matches are flagged low quality; the operator's stable area of the
  // reference image (polygons file, "" = none) and whether to match only there.
  std::vector<double> exclude_boxes;
  std::string stable_polygons;
  bool match_only_stable = false;
  std::string site_file;  // sequence mode: the site's camera of kind uav ("" = `camera`)
  // Sequence mode. With a site file (key site_file) that lists cameras:
  // `camera` is its camera of kind uav (the key picks one when it lists
  // several) and the topics are that camera's, /<camera>/camera/image_raw,
  // /<camera>/camera/position_prior and /<camera>/tie_points; without one,
  // graph_cameras (set by launch/include/processing_graph.xml) does the same
  // with the graph's default cameras (io::DefaultCameras()), else the
  // relative names below (remapped by the launch file).
  bool graph_cameras = false;
  // Sequence mode with a site file, started by the graph for every site
  // (launch/include/processing_graph.xml): only_without_targets makes the
  // matcher idle unless the site has no targets (io::SiteWithoutTargets with
  // target_list: the list the replay looks for beside the bag); idle says
  // why it idles ("" = it matches).
  bool only_without_targets = false;
  std::string target_list;
  std::string idle;
  std::string camera = "uav";  // written into camera_a and camera_b
  std::string image_topic = "image", prior_topic = "position_prior", tie_topic = "tie_points";
  std::string site_frame = "site";  // frame of position_prior (others ignored)
  int image_queue = 200;            // subscriber queues (a fast replay must lose none)
  matching::SequenceMatcherOptions sequence;
};

// `p` reads the node's private namespace.
HexMatcherParameters ReadHexMatcherParameters(ParamReader& p);

}  // namespace ros_adapters
}  // namespace slope_monitor
