#include "slope_monitor/core/adjustment/initialization.h"

#include <map>
#include <vector>

#include <Eigen/SVD>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/rigid3.h"

namespace slope_monitor {
namespace adjustment {
namespace {

// An image with a GNSS projection centre but too few control points to
// resect: the attitude that turns the image rays onto the directions from the
// centre to the known points (Wahba's problem, solved by SVD), accepted when
// every point reprojects within max_px. Needs >= 2 points.
bool OrientFromPositionPrior(const camera::CameraModel& model, const Eigen::Vector3d& centre,
                             const std::vector<Eigen::Vector2d>& px,
                             const std::vector<Eigen::Vector3d>& xyz, double max_px,
                             camera::ExteriorOrientation* exterior) {
  if (px.size() < 2) return false;
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (size_t k = 0; k < px.size(); ++k) {
    const Eigen::Vector3d d = model.PixelToOpticalDirection(px[k]).normalized();
    const Eigen::Vector3d u = (xyz[k] - centre).normalized();
    h += d * u.transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d fix = Eigen::Matrix3d::Identity();
  fix(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0 ? -1.0 : 1.0;
  const Eigen::Matrix3d site_from_optical = svd.matrixV() * fix * svd.matrixU().transpose();
  const camera::ExteriorOrientation e =
      camera::ExteriorOrientation::FromOpticalFromSite(Rigid3(site_from_optical, centre).Inverse());
  for (size_t k = 0; k < px.size(); ++k) {
    Eigen::Vector2d p;
    if (!model.Project(e, xyz[k], &p) || (p - px[k]).norm() > max_px) return false;
  }
  *exterior = e;
  return true;
}

}  // namespace

std::string InitializeScene(Scene* scene, const InitializationOptions& options) {
  scene->CheckIndices();
  for (ObjectPoint& p : scene->points) {
    if (!p.position_known && p.surveyed && (p.role == PointRole::kControl)) {
      p.position = *p.surveyed;
      p.position_known = true;
    }
  }
  std::vector<std::vector<int>> obs_of_image(scene->images.size()),
      obs_of_point(scene->points.size());
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
      } else if (im.position_prior && options.prior_attitude_max_px > 0.0 &&
                 OrientFromPositionPrior(scene->cameras[im.camera].model, *im.position_prior, px,
                                         xyz, options.prior_attitude_max_px, &im.exterior)) {
        im.exterior_known = true;  // GNSS centre + attitude from the known points
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
    if (!im.exterior_known)
      return last_failure.empty() ? Message("image '", im.name, "' could not be oriented")
                                  : last_failure;
  }
  std::vector<std::string> unknown;
  for (size_t j = 0; j < scene->points.size(); ++j) {
    if (!scene->points[j].position_known && obs_of_point[j].size() >= 2)
      unknown.push_back(scene->points[j].id);
  }
  if (!unknown.empty()) {
    std::string list;
    for (size_t i = 0; i < unknown.size() && i < 5; ++i) list += (i ? ", " : "") + unknown[i];
    return Message(unknown.size(), " points could not be intersected (", list,
                   unknown.size() > 5 ? ", ..." : "", ")");
  }
  return "";
}

std::string PruneReport::Summary() const {
  std::string out = Message("dropped ", dropped_images.size(), " image(s), ", dropped_points.size(),
                            " point(s), ", dropped_cameras.size(), " camera(s)");
  int shown = 0;
  for (const auto* list : {&dropped_images, &dropped_cameras, &dropped_points}) {
    for (const std::string& r : *list) {
      if (shown++ >= 3) break;
      out += (shown == 1 ? ": " : "; ") + r;
    }
  }
  return out;
}

Scene PruneScene(const Scene& scene, int min_observations_per_image, PruneReport* report,
                 int min_observations_with_prior) {
  if (min_observations_with_prior < 0) min_observations_with_prior = min_observations_per_image;
  scene.CheckIndices();
  PruneReport local;
  PruneReport& rep = report ? *report : local;
  std::vector<bool> keep_image(scene.images.size(), true), keep_point(scene.points.size(), true);
  for (size_t j = 0; j < scene.points.size(); ++j) {
    if (!scene.points[j].position_known) {
      keep_point[j] = false;
      rep.dropped_points.push_back(
          Message("point '", scene.points[j].id, "': no initial position"));
    }
  }
  for (size_t i = 0; i < scene.images.size(); ++i) {
    if (!scene.images[i].exterior_known) {
      keep_image[i] = false;
      rep.dropped_images.push_back(Message("image '", scene.images[i].name, "': not oriented"));
    }
  }
  for (bool changed = true; changed;) {
    changed = false;
    std::vector<int> per_image(scene.images.size(), 0), per_point(scene.points.size(), 0);
    for (const Observation& o : scene.observations) {
      if (!keep_image[o.image] || !keep_point[o.point] || !o.pixel.allFinite()) continue;
      ++per_image[o.image];
      ++per_point[o.point];
    }
    for (size_t i = 0; i < scene.images.size(); ++i) {
      const int min_obs =
          scene.images[i].position_prior ? min_observations_with_prior : min_observations_per_image;
      if (keep_image[i] && per_image[i] < min_obs) {
        keep_image[i] = false;
        changed = true;
        rep.dropped_images.push_back(Message("image '", scene.images[i].name, "': ", per_image[i],
                                             " observations of initialised points (min ", min_obs,
                                             ")"));
      }
    }
    for (size_t j = 0; j < scene.points.size(); ++j) {
      if (keep_point[j] && per_point[j] == 0) {
        keep_point[j] = false;
        changed = true;
        rep.dropped_points.push_back(
            Message("point '", scene.points[j].id, "': no image left that sees it"));
      }
    }
  }
  Scene out;
  std::vector<int> camera_map(scene.cameras.size(), -1), image_map(scene.images.size(), -1),
      point_map(scene.points.size(), -1);
  for (size_t i = 0; i < scene.images.size(); ++i) {
    if (!keep_image[i]) continue;
    const int c = scene.images[i].camera;
    if (camera_map[c] < 0) {
      camera_map[c] = static_cast<int>(out.cameras.size());
      out.cameras.push_back(scene.cameras[c]);
    }
    image_map[i] = static_cast<int>(out.images.size());
    out.images.push_back(scene.images[i]);
    out.images.back().camera = camera_map[c];
  }
  for (size_t c = 0; c < scene.cameras.size(); ++c) {
    if (camera_map[c] < 0)
      rep.dropped_cameras.push_back(Message("camera '", scene.cameras[c].name, "': no image left"));
  }
  for (size_t j = 0; j < scene.points.size(); ++j) {
    if (!keep_point[j]) continue;
    point_map[j] = static_cast<int>(out.points.size());
    out.points.push_back(scene.points[j]);
  }
  for (const Observation& o : scene.observations) {
    if (image_map[o.image] < 0 || point_map[o.point] < 0) continue;
    Observation c = o;
    c.image = image_map[o.image];
    c.point = point_map[o.point];
    out.observations.push_back(c);
  }
  return out;
}

}  // namespace adjustment
}  // namespace slope_monitor
