#include "slope_monitor/ros/hex_matcher_parameters.h"

#include <algorithm>
#include <vector>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_polygons.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/uav_topics.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

// The hexagonal matcher's keys (pair, track and the sequence mode's shift_hex method).
void ReadHexOptions(ParamReader& p, matching::HexMatcherOptions* o) {
  o->pyramid_levels = p.Int("pyramid_levels", o->pyramid_levels, 1, 6);
  const bool nearest = o->sampling == matching::HexSampling::kNearest;
  o->sampling = p.String("hex_sampling", nearest ? "nearest" : "interpolated",
                         {"nearest", "interpolated"}) == "nearest"
                    ? matching::HexSampling::kNearest
                    : matching::HexSampling::kInterpolated;
  o->profile_length = p.Int("profile_length", o->profile_length, 1, 16, "cells");
  o->min_score = p.Double("min_score", o->min_score, -1.0, 1.0);
  o->max_ratio = p.Double("max_ratio", o->max_ratio, 0.01, 1.0);
  o->mutual_tolerance = p.Double("mutual_tolerance", o->mutual_tolerance, 0.1, 100.0, "px");
  o->lsc_search_radius = p.Int("lsc_search_radius", o->lsc_search_radius, 0, 20, "px");
  o->lsc_prefilter_sigma = p.Double("lsc_prefilter_sigma", o->lsc_prefilter_sigma, 0.0, 5.0, "px");
  matching::InterestPointOptions& ip = o->interest;
  ip.log_sigma = p.Double("log_sigma", ip.log_sigma, 0.5, 10.0, "px");
  ip.max_points = p.Int("max_points", ip.max_points, 1, 100000);
  ip.min_distance = p.Int("min_distance", ip.min_distance, 1, 100, "px");
  ip.min_gradient = p.Double("min_gradient", ip.min_gradient, 0.0, 1e6, "grey/px");
  matching::LscOptions& l = o->lsc;
  l.model = matching::LscModelFromName(
      p.String("lsc_model", matching::LscModelName(l.model), {"affine", "shift"}));
  l.interpolation = matching::InterpolationFromName(p.String(
      "lsc_interpolation", matching::InterpolationName(l.interpolation), {"bilinear", "bicubic"}));
  l.gradient = matching::LscGradientFromName(
      p.String("lsc_gradient", matching::LscGradientName(l.gradient), {"template", "resampled"}));
  l.affine_min_f = p.Double("lsc_affine_min_f", l.affine_min_f, 0.0, 1e6);
  l.half_window = p.Int("lsc_half_window", l.half_window, 1, 50, "px");
  l.estimate_gain = p.Bool("lsc_estimate_gain", l.estimate_gain);
  l.min_correlation = p.Double("lsc_min_correlation", l.min_correlation, -1.0, 1.0);
  l.max_sigma = p.Double("lsc_max_sigma", l.max_sigma, 1e-6, 100.0, "px");
  l.min_eigen_ratio = p.Double("lsc_min_eigen_ratio", l.min_eigen_ratio, 0.0, 0.999);
  l.max_shift_affine_correlation =
      p.Double("lsc_max_shift_affine_correlation", l.max_shift_affine_correlation, 1e-6, 1.0);
  l.fallback_affine_precision =
      p.Bool("lsc_fallback_affine_precision", l.fallback_affine_precision);
  auto& q = o->quality;
  q.enabled = p.Bool("quality_control", q.enabled);
  q.min_correlation = p.Double("quality_min_correlation", q.min_correlation, -1.0, 1.0);
  q.max_residual_ratio = p.Double("quality_max_residual_ratio", q.max_residual_ratio, 1.0001, 1e6);
  q.two_way = p.Bool("quality_two_way", q.two_way);
  q.max_two_way = p.Double("quality_max_two_way", q.max_two_way, 1e-6, 100.0, "px");
  q.neighbour_radius = p.Double("quality_neighbour_radius", q.neighbour_radius, 1.0, 10000.0, "px");
  q.max_neighbour_deviation =
      p.Double("quality_max_neighbour_deviation", q.max_neighbour_deviation, 1e-6, 1000.0, "px");
  q.reject = p.Bool("quality_reject", q.reject);
}

// Search radii, prior shift, excluded boxes.
void ReadPrior(ParamReader& p, bool track, HexMatcherParameters* h) {
  matching::MatchPrior* prior = &h->prior;
  prior->radius = p.Double("search_radius", prior->radius, 1.0, 1000.0, "px");
  prior->moving_radius = p.Double("moving_radius", prior->moving_radius, 1.0, 1000.0, "px");
  const std::vector<double> shift =
      p.DoubleList("prior_shift", {prior->shift.x(), prior->shift.y()});
  if (shift.size() != 2) throw ConfigError(p.FullKey("prior_shift") + " must have 2 values [px]");
  prior->shift = Eigen::Vector2d(shift[0], shift[1]);
  // Default: on in track mode (the displacement prior from stable ground).
  prior->estimate_global_shift = p.Bool("estimate_global_shift", track);
  // Operator's outline of known obstacles in image a: rectangles
  // [x0, y0, x1, y1, ...] [px]; matches there are flagged low quality.
  h->exclude_boxes = p.DoubleList("exclude_boxes", h->exclude_boxes);
  const std::vector<double>& boxes = h->exclude_boxes;
  if (boxes.size() % 4 != 0) {
    throw ConfigError(p.FullKey("exclude_boxes") +
                      " must hold 4 values per box (x0, y0, x1, y1) [px], got " +
                      std::to_string(boxes.size()));
  }
  for (size_t i = 0; i < boxes.size(); i += 4) {
    if (!(boxes[i] < boxes[i + 2] && boxes[i + 1] < boxes[i + 3])) {
      throw ConfigError(p.FullKey("exclude_boxes") + ": box " + std::to_string(i / 4) +
                        " needs x0 < x1 and y0 < y1");
    }
  }
  // Track mode: the operator's stable area of the reference image (polygons
  // in pixels, io/image_polygons.h); the rest may move (moving_radius) and
  // only stable points give the global shift.
  h->stable_polygons = p.String("stable_polygons", h->stable_polygons);
  h->match_only_stable = p.Bool("match_only_stable", h->match_only_stable);
  const std::string& stable_file = h->stable_polygons;
  const bool only_stable = h->match_only_stable;
  if (!stable_file.empty()) {
    const auto stable = io::ReadImagePolygons(stable_file, p.FullKey("stable_polygons"));
    prior->moving = [stable](const Eigen::Vector2d& x) { return !io::InsideAny(stable, x); };
    if (only_stable)
      prior->within = [stable](const Eigen::Vector2d& x) { return io::InsideAny(stable, x); };
  } else if (only_stable) {
    throw ConfigError(p.FullKey("match_only_stable") + " needs stable_polygons");
  }
  if (!boxes.empty()) {
    prior->excluded = [boxes](const Eigen::Vector2d& x) {
      for (size_t i = 0; i < boxes.size(); i += 4) {
        if (x.x() >= boxes[i] && x.y() >= boxes[i + 1] && x.x() <= boxes[i + 2] &&
            x.y() <= boxes[i + 3])
          return true;
      }
      return false;
    };
  }
}

void ReadSequenceOptions(ParamReader& p, matching::SequenceMatcherOptions* s) {
  s->method = matching::SequencePairMethodFromName(
      p.String("pair_method", matching::SequencePairMethodName(s->method), {"photo", "shift_hex"}));
  s->fallback_shift_hex = p.Bool("photo_fallback_shift_hex", s->fallback_shift_hex);
  s->max_gap = p.Double("sequence_max_gap", s->max_gap, 0.0, 1e6, "s");
  s->pairing.min_overlap = p.Double("min_footprint_overlap", s->pairing.min_overlap, 0.001, 1.0);
  s->pairing.max_pair_distance =
      p.Double("max_pair_distance", s->pairing.max_pair_distance, 0.01, 1e5, "m");
  s->pairing.max_pairs_per_image =
      p.Int("max_pairs_per_image", s->pairing.max_pairs_per_image, 1, 100);
  s->pairing.sequence_depth = p.Int("sequence_depth", s->pairing.sequence_depth, 1, 100);
  s->pairing.exhaustive_max_photos =
      p.Int("exhaustive_max_photos", s->pairing.exhaustive_max_photos, 0, 1000);
  s->pairing.exhaustive_footprint_scale =
      p.Double("exhaustive_footprint_scale", s->pairing.exhaustive_footprint_scale, 0.0, 100.0);
  s->min_pair_tie_points = p.Int("min_pair_tie_points", s->min_pair_tie_points, 0, 100000);
  s->position_prior_max_dt =
      p.Double("position_prior_max_dt", s->position_prior_max_dt, 0.0, 60.0, "s");
  s->prior_wait = p.Double("prior_wait", s->prior_wait, 0.0, 600.0, "s");
  s->max_images = p.Int("sequence_max_images", s->max_images, 1, 100000);
  s->max_memory_mb = p.Double("max_memory_mb", s->max_memory_mb, 1.0, 1e6, "MB");
  s->threads = p.Int("sequence_threads", s->threads, 0, 64);
  s->border = p.Double("sequence_border", s->border, 0.0, 1000.0, "px");
  matching::GlobalShiftOptions& g = s->shift;
  g.max_size = p.Int("shift_max_size", g.max_size, 32, 4096, "px");
  g.min_response = p.Double("shift_min_response", g.min_response, 0.0, 1.0);
  g.min_overlap_correlation =
      p.Double("shift_min_overlap_correlation", g.min_overlap_correlation, -1.0, 1.0);
  g.min_overlap = p.Int("shift_min_overlap", g.min_overlap, 8, 100000, "px");
  g.min_overlap_fraction =
      p.Double("shift_min_overlap_fraction", g.min_overlap_fraction, 0.0, 0.99);
  g.candidates = p.Int("shift_candidates", g.candidates, 1, 100);
  g.taper = p.Double("shift_taper", g.taper, 0.01, 0.5);
  g.refine = p.Bool("shift_refine", g.refine);
  g.refine_factor = p.Int("shift_refine_factor", g.refine_factor, 1, 16);
  // Photo method: features per photo, pair matching.
  s->photo.coarse_max_side =
      p.Int("photo_coarse_max_side", s->photo.coarse_max_side, 200, 10000, "px");
  s->photo.coarse_sift_max_side =
      p.Int("photo_coarse_sift_max_side", s->photo.coarse_sift_max_side, 100, 10000, "px");
  s->photo.coarse_max_features =
      p.Int("photo_coarse_max_features", s->photo.coarse_max_features, 10, 1000000);
  s->photo.coarse_contrast_threshold =
      p.Double("photo_coarse_contrast_threshold", s->photo.coarse_contrast_threshold, 1e-6, 0.999);
  s->photo.interest.max_points =
      p.Int("photo_max_points", s->photo.interest.max_points, 1, 1000000);
  s->photo.interest.cells = p.Int("photo_interest_cells", s->photo.interest.cells, 0, 100);
  s->photo_pair.min_coarse_inliers =
      p.Int("photo_min_coarse_inliers", s->photo_pair.min_coarse_inliers, 8, 100000);
  s->photo_pair.screen_threshold =
      p.Double("photo_screen_threshold", s->photo_pair.screen_threshold, 1e-3, 100.0, "px");
}

// Sequence mode with a site file that lists cameras (or, graph_cameras, the
// graph's default ones; `source` names them): their camera of kind uav and
// that camera's topics (the kind is the site's field, never the name).
void UseUavCamera(const std::vector<io::SiteCamera>& cameras, const std::string& source,
                  ParamReader& p, HexMatcherParameters* h) {
  const std::vector<std::string> uav = io::CameraNames(cameras, io::CameraKind::kUav);
  if (uav.empty())
    throw ConfigError("parameter '" + p.FullKey("site_file") + "': " + source +
                      " lists no camera of kind uav (mode sequence ties a UAV camera's photos)");
  if (std::find(uav.begin(), uav.end(), h->camera) == uav.end()) {
    if (uav.size() > 1) {
      std::string names;
      for (const std::string& n : uav) names += (names.empty() ? "" : ", ") + n;
      throw ConfigError("parameter '" + p.FullKey("camera") + "': '" + h->camera +
                        "' is not a camera of kind uav of " + source + " (" + names +
                        "); one hex_matcher per UAV camera, each with its camera");
    }
    h->camera = uav.front();
  }
  const UavTopics topics = UavCameraTopics(h->camera);
  h->image_topic = topics.image;
  h->prior_topic = topics.prior;
  h->tie_topic = topics.tie_points;
}

}  // namespace

HexMatcherParameters ReadHexMatcherParameters(ParamReader& p) {
  HexMatcherParameters h;
  h.mode = p.String("mode", h.mode, {"pair", "track", "sequence"});
  h.max_pair_dt = p.Double("max_pair_dt", h.max_pair_dt, 0.0, 3600.0, "s");
  h.camera_a = p.String("camera_a", h.camera_a);
  h.camera_b = p.String("camera_b", h.camera_b);
  ReadHexOptions(p, &h.hex);
  ReadPrior(p, h.mode == "track", &h);
  h.camera = p.String("camera", h.camera);
  h.site_file = p.String("site_file", h.site_file);
  h.only_without_targets = p.Bool("only_without_targets", h.only_without_targets);
  h.target_list = p.String("target_list", h.target_list);
  h.graph_cameras = p.Bool("graph_cameras", h.graph_cameras);
  bool site_cameras = false;  // a site file that lists cameras decided the camera
  if (h.mode == "sequence" && !h.site_file.empty()) {
    const io::SiteFile site = io::LoadSiteFile(h.site_file);
    site_cameras = !site.cameras.empty();
    if (h.only_without_targets && !io::SiteWithoutDetectableTargets(site, h.target_list))
      h.idle =
          "site '" + site.name +
          "' has targets: its UAV photos are tied by them (uav_tie_points:=true ties them too)";
    else if (h.only_without_targets && io::CameraNames(site.cameras, io::CameraKind::kUav).empty())
      h.idle = "site '" + site.name + "' lists no camera of kind uav";
    else if (site_cameras)
      UseUavCamera(site.cameras, "site file '" + site.path + "'", p, &h);
  }
  if (h.mode == "sequence" && h.graph_cameras && !site_cameras && h.idle.empty())
    UseUavCamera(io::DefaultCameras(), "the graph's default cameras (no site file lists cameras)",
                 p, &h);
  h.site_frame = p.String("site_frame", h.site_frame);
  h.image_queue = p.Int("image_queue", h.image_queue, 1, 100000);
  ReadSequenceOptions(p, &h.sequence);
  // The sequence's hexagonal matcher: the keys above, with its own number of
  // interest points per image a (0: max_points).
  const int max_points = h.sequence.hex.interest.max_points;
  h.sequence.hex = h.hex;
  const int sequence_max_points = p.Int("sequence_max_points", max_points, 0, 100000);
  if (sequence_max_points > 0) h.sequence.hex.interest.max_points = sequence_max_points;
  h.sequence.hex_prior = h.prior;
  p.CheckNoUnknownKeys();
  h.hex.Check();
  h.sequence.Check();
  return h;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
