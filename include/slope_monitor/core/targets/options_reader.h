// One reader of the target_centroider keys for every key-value source: the
// nodelet passes ros_adapters::ParamReader, the centroid_targets tool
// io::YamlMap. Both have the same interface (Double/Int/Bool/String with
// ranges, naming the bad key); only the string-list getter differs in name
// (StringList / Strings) and is picked by overload. Keys, units, defaults and
// ranges: config/defaults/target_centroider.yaml.
//
//   ros_adapters::ParamReader p(pnh);          io::YamlMap m = io::YamlMap::Load(path);
//   targets::Options o = targets::ReadOptions(p);   // or (m)
//   targets::NodeOptions n = targets::ReadNodeOptions(p);
//   p.CheckNoUnknownKeys();
#pragma once

#include <string>
#include <vector>

#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {

// The node's own keys (inputs, queue); the tool reads them too so the one
// defaults file serves both.
struct NodeOptions {
  std::string target_list;  // path of the target list; "" = none (every target unknown)
  std::string camera_name;  // "" = the parent namespace of the node
  std::string site_frame = "site";
  bool use_tf_pose = true;
  double pixel_size = 1.0;  // [mm/px]
  int queue_size = 100;     // [images]
  std::string site_file;    // the node: one camera per site camera of kind fixed/uav ("" = one)
  // The node without a site file that lists cameras: true, one camera per
  // default camera of the graph (io::DefaultCameras(), kind fixed or uav;
  // launch/include/processing_graph.xml); false, one camera on relative topics.
  bool graph_cameras = false;
};

namespace detail {
template <typename R>
auto ReadStrings(R& r, const std::string& key, const std::vector<std::string>& d, int)
    -> decltype(r.StringList(key, d)) {
  return r.StringList(key, d);
}
template <typename R>
auto ReadStrings(R& r, const std::string& key, const std::vector<std::string>& d, long)
    -> decltype(r.Strings(key, d)) {
  return r.Strings(key, d);
}
}  // namespace detail

template <typename Reader>
Options ReadOptions(Reader& r) {
  Options o;
  o.families = detail::ReadStrings(r, "families", o.families, 0);
  o.quad_decimate = r.Double("quad_decimate", o.quad_decimate, 1.0, 8.0);
  o.quad_sigma = r.Double("quad_sigma", o.quad_sigma, 0.0, 10.0, "px");
  o.refine_edges = r.Bool("refine_edges", o.refine_edges);
  o.decode_sharpening = r.Double("decode_sharpening", o.decode_sharpening, 0.0, 10.0);
  o.threads = r.Int("threads", o.threads, 1, 64);
  o.max_hamming = r.Int("max_hamming", o.max_hamming, 0, 3, "bits");
  o.min_decision_margin = r.Double("min_decision_margin", o.min_decision_margin, 0.0, 1000.0);
  o.refine_tags = r.Bool("refine_tags", o.refine_tags);
  o.tag_refine_max_residual =
      r.Double("tag_refine_max_residual", o.tag_refine_max_residual, 1e-6, 1.0);
  o.tag_refine_max_sigma =
      r.Double("tag_refine_max_sigma", o.tag_refine_max_sigma, 1e-6, 10.0, "px");
  o.detect_circles = r.Bool("detect_circles", o.detect_circles);
  o.circle_design =
      ParseCircleDesign(r.String("circle_design", CircleDesignName(o.circle_design),
                                 {"auto", "disc_in_ring", "dot", "ring", "concentric"}));
  o.circle_min_diameter = r.Double("circle_min_diameter", o.circle_min_diameter, 4.0, 2000.0, "px");
  o.circle_max_diameter = r.Double("circle_max_diameter", o.circle_max_diameter, 4.0, 2000.0, "px");
  o.circle_max_eccentricity =
      r.Double("circle_max_eccentricity", o.circle_max_eccentricity, 0.01, 0.99);
  o.circle_id_gate = r.Double("circle_id_gate", o.circle_id_gate, 0.01, 5.0);
  o.circle_ring_ratio = r.Double("circle_ring_ratio", o.circle_ring_ratio, 1.01, 10.0);
  o.circle_ring_ratio_tolerance =
      r.Double("circle_ring_ratio_tolerance", o.circle_ring_ratio_tolerance, 0.01, 1.0);
  o.circle_max_residual = r.Double("circle_max_residual", o.circle_max_residual, 0.01, 1.0);
  o.circle_size_tolerance = r.Double("circle_size_tolerance", o.circle_size_tolerance, 0.01, 1.0);
  o.refine_circles = r.Bool("refine_circles", o.refine_circles);
  o.correct_perspective = r.Bool("correct_perspective", o.correct_perspective);
  o.min_contrast = r.Double("min_contrast", o.min_contrast, 0.1, 254.0, "DN");
  o.border_margin = r.Double("border_margin", o.border_margin, 0.0, 100.0, "px");
  o.saturation_level = r.Double("saturation_level", o.saturation_level, 1.0, 255.0, "DN");
  o.max_saturated_fraction = r.Double("max_saturated_fraction", o.max_saturated_fraction, 0.0, 1.0);
  o.max_edge_blur = r.Double("max_edge_blur", o.max_edge_blur, 0.01, 20.0, "px");
  o.max_residual = r.Double("max_residual", o.max_residual, 0.01, 1.0);
  o.max_dark_surround = r.Double("max_dark_surround", o.max_dark_surround, 0.001, 1.0);
  o.noise_floor = r.Double("noise_floor", o.noise_floor, 0.0, 50.0, "DN");
  return o;
}

template <typename Reader>
NodeOptions ReadNodeOptions(Reader& r) {
  NodeOptions n;
  n.target_list = r.String("target_list", n.target_list);
  n.camera_name = r.String("camera_name", n.camera_name);
  n.site_frame = r.String("site_frame", n.site_frame);
  n.use_tf_pose = r.Bool("use_tf_pose", n.use_tf_pose);
  n.pixel_size = r.Double("pixel_size", n.pixel_size, 1e-6, 1.0, "mm");
  n.queue_size = r.Int("queue_size", n.queue_size, 1, 10000, "images");
  n.site_file = r.String("site_file", n.site_file);
  n.graph_cameras = r.Bool("graph_cameras", n.graph_cameras);
  return n;
}

}  // namespace targets
}  // namespace slope_monitor
