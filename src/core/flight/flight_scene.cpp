#include "slope_monitor/core/flight/flight_scene.h"

#include <map>
#include <unordered_map>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace flight {
namespace {

// What the flight orientation needs, taken from the scene.
struct SceneFlight {
  FlightPhotos photos;
  FlightTies ties;
  FlightInput input;
  std::vector<int> image_of_photo;  // photo -> scene image
  std::vector<int> point_of_track;  // track -> scene point
};

void CountPairs(SceneFlight* f) {
  std::map<std::pair<int, int>, int> shared;
  for (const FlightTrack& t : f->ties.tracks)
    for (size_t i = 0; i < t.observations.size(); ++i)
      for (size_t j = i + 1; j < t.observations.size(); ++j) {
        const int a = std::min(t.observations[i].first, t.observations[j].first);
        const int b = std::max(t.observations[i].first, t.observations[j].first);
        if (a != b) ++shared[{a, b}];
      }
  for (const auto& [ab, n] : shared) {
    f->ties.pairs.push_back({ab.first, ab.second, n, 0.0, ""});
    ++f->ties.pairs_tied;
    f->ties.tie_points += n;
  }
}

SceneFlight FromScene(const adjustment::Scene& scene, int cam, FlightOrientationOptions* options) {
  SceneFlight f;
  f.photos.nominal = scene.cameras[cam].model;
  std::vector<int> photo_of_image(scene.images.size(), -1);
  bool sigma_set = false;
  for (size_t i = 0; i < scene.images.size(); ++i) {
    const adjustment::Image& im = scene.images[i];
    if (im.camera != cam) continue;
    photo_of_image[i] = static_cast<int>(f.photos.photos.size());
    f.image_of_photo.push_back(static_cast<int>(i));
    FlightPhoto p;
    p.name = im.name;
    p.width = f.photos.nominal.sensor().width;
    p.height = f.photos.nominal.sensor().height;
    f.photos.photos.push_back(p);
    f.input.gnss_in_site.push_back(im.position_prior);
    if (im.position_prior && !sigma_set) {
      options->gnss_sigma_horizontal_m =
          std::sqrt(std::max(1e-6, im.position_prior_covariance(0, 0)));
      options->gnss_sigma_vertical_m =
          std::sqrt(std::max(1e-6, im.position_prior_covariance(2, 2)));
      sigma_set = true;
    }
  }
  std::vector<FlightTrack> track_of_point(scene.points.size());
  for (const adjustment::Observation& o : scene.observations)
    if (photo_of_image[o.image] >= 0)
      track_of_point[o.point].observations.emplace_back(photo_of_image[o.image], o.pixel);
  for (size_t p = 0; p < scene.points.size(); ++p) {
    const adjustment::ObjectPoint& pt = scene.points[p];
    if (track_of_point[p].observations.empty()) continue;
    if (pt.role == adjustment::PointRole::kControl && pt.surveyed) {
      FlightControlPoint cp;
      cp.name = pt.id;
      cp.site = *pt.surveyed;
      cp.covariance = pt.surveyed_covariance;
      cp.picks = track_of_point[p].observations;
      f.input.control.push_back(cp);
    } else if (pt.role == adjustment::PointRole::kTie &&
               track_of_point[p].observations.size() >= 2) {
      f.ties.tracks.push_back(track_of_point[p]);
      f.point_of_track.push_back(static_cast<int>(p));
    }
  }
  CountPairs(&f);
  return f;
}

}  // namespace

FlightSummary OrientSceneFromTiePoints(adjustment::Scene* scene, const std::string& camera,
                                       const FlightOrientationOptions& options) {
  int cam = -1;
  for (size_t c = 0; c < scene->cameras.size(); ++c)
    if (scene->cameras[c].name == camera) cam = static_cast<int>(c);
  if (cam < 0)
    throw InvalidArgument(
        Message("OrientSceneFromTiePoints: the scene has no camera '", camera, "'"));
  FlightOrientationOptions o = options;
  o.leave_one_out = false;
  SceneFlight f = FromScene(*scene, cam, &o);
  f.input.photos = &f.photos;
  f.input.ties = &f.ties;
  const FlightResult r = OrientFlight(f.input, o);
  if (!r.summary.success) return r.summary;
  for (size_t i = 0; i < r.scene.images.size(); ++i) {
    adjustment::Image& im = scene->images[f.image_of_photo[r.photo_of_image[i]]];
    im.exterior = r.scene.images[i].exterior;
    im.exterior_known = true;
    im.attitude_from_prior = false;
  }
  for (const adjustment::ObjectPoint& p : r.scene.points) {
    if (p.id.rfind("tie/", 0) != 0) continue;
    adjustment::ObjectPoint& target = scene->points[f.point_of_track[std::stoi(p.id.substr(4))]];
    target.position = p.position;
    target.position_known = true;
  }
  scene->cameras[cam].model = r.scene.cameras[0].model;
  return r.summary;
}

}  // namespace flight
}  // namespace slope_monitor
