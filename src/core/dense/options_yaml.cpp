#include "slope_monitor/core/dense/options_yaml.h"

#include "slope_monitor/core/io/yaml_map.h"

namespace slope_monitor {
namespace dense {

void ReadCorrelationOptions(const std::string& path, CorrelationOptions* o) {
  io::YamlMap p = io::YamlMap::Load(path);
  o->levels = p.Int("levels", o->levels, 1, 5);
  o->peak_frequency = p.Double("peak_frequency", o->peak_frequency, 0.01, 3.0, "rad/px");
  o->grid_spacing = p.Int("grid_spacing", o->grid_spacing, 1, 64, "px");
  o->final_grid_spacing = p.Int("final_grid_spacing", o->final_grid_spacing, 1, 64, "px");
  o->window = p.Int("window", o->window, 3, 51, "px");
  o->final_window = p.Int("final_window", o->final_window, 0, 51, "px");
  o->edge_window = p.Int("edge_window", o->edge_window, 0, 51, "px");
  o->edge_parallax_step = p.Double("edge_parallax_step", o->edge_parallax_step, 0.01, 100.0, "px");
  o->search_radius = p.Int("search_radius", o->search_radius, 1, 16, "px");
  o->final_search_radius = p.Int("final_search_radius", o->final_search_radius, 0, 16, "px");
  o->min_correlation = p.Double("min_correlation", o->min_correlation, -1.0, 0.999);
  o->lr_tolerance = p.Double("lr_tolerance", o->lr_tolerance, 0.01, 10.0, "px");
  o->order_tolerance = p.Double("order_tolerance", o->order_tolerance, 0.0, 10.0, "px");
  o->median_filter = p.Bool("median_filter", o->median_filter);
  o->order_check = p.Bool("order_check", o->order_check);
  o->two_way = p.Bool("two_way", o->two_way);
  o->full_right_search = p.Bool("full_right_search", o->full_right_search);
  o->lsc_iterations = p.Int("lsc_iterations", o->lsc_iterations, 0, 20);
  o->Check();
}

}  // namespace dense
}  // namespace slope_monitor
