#include "slope_monitor/core/adjustment/initialization.h"

#include <map>
#include <vector>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

std::string InitializeScene(Scene* scene, const InitializationOptions& options) {
  scene->CheckIndices();
  for (ObjectPoint& p : scene->points) {
    if (!p.position_known && p.surveyed && (p.role == PointRole::kControl)) {
      p.position = *p.surveyed;
      p.position_known = true;
    }
  }
  std::vector<std::vector<int>> obs_of_image(scene->images.size()), obs_of_point(scene->points.size());
  for (size_t k = 0; k < scene->observations.size(); ++k) {
    const Observation& o = scene->observations[k];
    if (!o.pixel.allFinite()) continue;
    obs_of_image[o.image].push_back(static_cast<int>(k));
    obs_of_point[o.point].push_back(static_cast<int>(k));
  }
  std::string last_failure;
  for (int pass = 0; pass < options.max_passes; ++pass) {
    bool changed = false;
    for (size_t i = 0; i < scene->images.size(); ++i) {
      Image& im = scene->images[i];
      if (im.exterior_known) continue;
      std::vector<Eigen::Vector2d> px;
      std::vector<Eigen::Vector3d> xyz;
      for (int k : obs_of_image[i]) {
        const Observation& o = scene->observations[k];
        if (!scene->points[o.point].position_known) continue;
        px.push_back(o.pixel);
        xyz.push_back(scene->points[o.point].position);
      }
      const geometry::ResectionResult r =
          geometry::Resect(scene->cameras[im.camera].model, px, xyz, options.resection);
      if (r.success) {
        im.exterior = r.exterior;
        im.exterior_known = true;
        changed = true;
      } else {
        last_failure = Message("image '", im.name, "': resection failed: ", r.message);
      }
    }
    for (size_t j = 0; j < scene->points.size(); ++j) {
      ObjectPoint& p = scene->points[j];
      if (p.position_known) continue;
      std::vector<geometry::RayObservation> rays;
      for (int k : obs_of_point[j]) {
        const Observation& o = scene->observations[k];
        const Image& im = scene->images[o.image];
        if (!im.exterior_known) continue;
        geometry::RayObservation ray;
        ray.model = &scene->cameras[im.camera].model;
        ray.exterior = im.exterior;
        ray.pixel = o.pixel;
        ray.covariance = o.covariance;
        rays.push_back(ray);
      }
      if (rays.size() < 2) continue;
      const geometry::IntersectionResult x = geometry::Intersect(rays, options.intersection);
      if (x.success) {
        p.position = x.position;
        p.position_known = true;
        changed = true;
      }
    }
    if (!changed) break;
  }
  for (const Image& im : scene->images) {
    if (!im.exterior_known) return last_failure.empty() ? Message("image '", im.name, "' could not be oriented") : last_failure;
  }
  std::vector<std::string> unknown;
  for (size_t j = 0; j < scene->points.size(); ++j) {
    if (!scene->points[j].position_known && obs_of_point[j].size() >= 2) unknown.push_back(scene->points[j].id);
  }
  if (!unknown.empty()) {
    std::string list;
    for (size_t i = 0; i < unknown.size() && i < 5; ++i) list += (i ? ", " : "") + unknown[i];
    return Message(unknown.size(), " points could not be intersected (", list, unknown.size() > 5 ? ", ..." : "", ")");
  }
  return "";
}

}  // namespace adjustment
}  // namespace slope_monitor
