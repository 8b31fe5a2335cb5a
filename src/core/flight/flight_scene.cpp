#include "slope_monitor/core/flight/flight_scene.h"

#include <cstdint>
#include <map>
#include <unordered_map>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/sequence.h"

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
  // Per track, the scene observation of each of its observations.
  std::vector<std::vector<int>> observation_of;
};

// The pairs' tie points as the matcher gave them: a track starts at an
// interest point of photo a (observations[0]) and holds one observation per
// photo it was matched into, so (a, b) counts the tracks of a seen in b.
void CountPairs(SceneFlight* f) {
  std::map<std::pair<int, int>, int> shared;
  for (const FlightTrack& t : f->ties.tracks)
    for (size_t j = 1; j < t.observations.size(); ++j) {
      const int a = std::min(t.observations[0].first, t.observations[j].first);
      const int b = std::max(t.observations[0].first, t.observations[j].first);
      if (a != b) ++shared[{a, b}];
    }
  for (const auto& [ab, n] : shared) {
    f->ties.pairs.push_back({ab.first, ab.second, n, 0.0, ""});
    ++f->ties.pairs_tied;
    f->ties.tie_points += n;
  }
}

// Puts the observation a sequence track starts at first: its ID
// (matching::SequenceTrackId, "tie/<id>") holds row * width + col of the
// rounded interest point of photo a, and a is the earliest photo of the
// track (a photo is matched with earlier ones only).
void StartFirst(const std::string& id, int width, const std::vector<int>& image_of_photo,
                const adjustment::Scene& scene, FlightTrack* track,
                std::vector<int>* observations) {
  std::uint64_t key = 0;
  try {
    key = std::stoull(id.substr(4));
  } catch (const std::exception&) {
    return;  // not a sequence track: as collected
  }
  int start = -1;
  for (size_t k = 0; k < track->observations.size(); ++k) {
    const auto& [photo, x] = track->observations[k];
    if (!matching::SequenceTrackStartsAt(key, x, width)) continue;
    if (start < 0 || scene.images[image_of_photo[photo]].stamp <
                         scene.images[image_of_photo[track->observations[start].first]].stamp)
      start = static_cast<int>(k);
  }
  if (start <= 0) return;
  std::swap(track->observations[0], track->observations[start]);
  std::swap((*observations)[0], (*observations)[start]);
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
  std::vector<std::vector<int>> observations_of_point(scene.points.size());
  for (size_t k = 0; k < scene.observations.size(); ++k) {
    const adjustment::Observation& o = scene.observations[k];
    if (photo_of_image[o.image] < 0) continue;
    track_of_point[o.point].observations.emplace_back(photo_of_image[o.image], o.pixel);
    observations_of_point[o.point].push_back(static_cast<int>(k));
  }
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
      StartFirst(pt.id, f.photos.nominal.sensor().width, f.image_of_photo, scene,
                 &track_of_point[p], &observations_of_point[p]);
      f.ties.tracks.push_back(track_of_point[p]);
      f.point_of_track.push_back(static_cast<int>(p));
      f.observation_of.push_back(observations_of_point[p]);
    }
  }
  CountPairs(&f);
  return f;
}

// Joins the tracks as process_flight does (JoinTracks) and makes the scene
// say the same: the observations of a joined track move to its first
// track's point; those it does not keep (a second observation in one photo)
// and the points left without observations leave the scene.
void JoinAsTheFlight(adjustment::Scene* scene, SceneFlight* f) {
  const double radius = FlightMatchingOptions().join_radius_px;
  if (radius <= 0.0) return;
  const std::vector<std::vector<std::pair<int, int>>> origin = JoinTracks(radius, &f->ties.tracks);
  std::vector<char> drop(scene->observations.size(), 0);
  for (const std::vector<int>& obs : f->observation_of)
    for (int k : obs) drop[k] = 1;
  std::vector<int> point_of_track;
  for (const std::vector<std::pair<int, int>>& from : origin) {
    const int point = f->point_of_track[from.front().first];
    point_of_track.push_back(point);
    for (const auto& [t, k] : from) {
      const int obs = f->observation_of[t][k];
      drop[obs] = 0;
      scene->observations[obs].point = point;
    }
  }
  std::vector<adjustment::Observation> kept;
  std::vector<int> count(scene->points.size(), 0);
  for (size_t k = 0; k < scene->observations.size(); ++k)
    if (!drop[k]) {
      kept.push_back(scene->observations[k]);
      ++count[kept.back().point];
    }
  std::vector<int> renumber(scene->points.size(), -1);
  std::vector<adjustment::ObjectPoint> points;
  for (size_t p = 0; p < scene->points.size(); ++p) {
    const bool merged_away = count[p] == 0 && scene->points[p].role == adjustment::PointRole::kTie;
    if (merged_away) continue;
    renumber[p] = static_cast<int>(points.size());
    points.push_back(scene->points[p]);
  }
  for (adjustment::Observation& o : kept) o.point = renumber[o.point];
  for (int& p : point_of_track) p = renumber[p];
  scene->points.swap(points);
  scene->observations.swap(kept);
  f->point_of_track.swap(point_of_track);
  f->observation_of.clear();
}

int CameraIndex(const adjustment::Scene& scene, const std::string& camera) {
  for (size_t c = 0; c < scene.cameras.size(); ++c)
    if (scene.cameras[c].name == camera) return static_cast<int>(c);
  return -1;
}

}  // namespace

FlightSummary OrientSceneFromTiePoints(adjustment::Scene* scene, const std::string& camera,
                                       const FlightOrientationOptions& options) {
  const int cam = CameraIndex(*scene, camera);
  if (cam < 0)
    throw InvalidArgument(
        Message("OrientSceneFromTiePoints: the scene has no camera '", camera, "'"));
  FlightOrientationOptions o = options;
  o.leave_one_out = false;
  SceneFlight f = FromScene(*scene, cam, &o);
  // The growth's tracks as process_flight joins them (before JoinAsTheFlight
  // joins the adjustment's: JoinTracks needs each track at its start).
  const FlightMatchingOptions matching;
  if (matching.growth_join_radius > 0.0) {
    f.ties.growth_tracks = f.ties.tracks;
    JoinTracks(GrowthJoinRadiusPx(matching, f.photos.nominal.sensor().width,
                                  f.photos.nominal.sensor().height),
               &f.ties.growth_tracks);
  }
  adjustment::Scene joined = *scene;
  JoinAsTheFlight(&joined, &f);
  f.input.photos = &f.photos;
  f.input.ties = &f.ties;
  const FlightResult r = OrientFlight(f.input, o);
  if (!r.summary.success) return r.summary;
  *scene = std::move(joined);
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

FlightResult BlockOfCamera(const adjustment::Scene& scene, const adjustment::Summary& summary,
                           const std::string& camera) {
  const int cam = CameraIndex(scene, camera);
  if (cam < 0)
    throw InvalidArgument(Message("BlockOfCamera: the scene has no camera '", camera, "'"));
  FlightResult r;
  adjustment::Scene& b = r.scene;
  b.cameras = {scene.cameras[cam]};
  const adjustment::Precision& from = summary.precision;
  adjustment::Precision& to = r.bundle.precision;
  to.valid = from.valid;
  to.message = from.message;
  to.relative_to_control = from.relative_to_control;
  to.sigma0 = from.sigma0;
  if (from.interior_sigma.size() > static_cast<size_t>(cam))
    to.interior_sigma = {from.interior_sigma[cam]};
  std::vector<int> image(scene.images.size(), -1), point(scene.points.size(), -1);
  for (size_t i = 0; i < scene.images.size(); ++i) {
    if (scene.images[i].camera != cam) continue;
    image[i] = static_cast<int>(b.images.size());
    b.images.push_back(scene.images[i]);
    b.images.back().camera = 0;
    if (i < from.exterior_covariance.size())
      to.exterior_covariance.push_back(from.exterior_covariance[i]);
  }
  for (adjustment::Observation o : scene.observations) {
    if (image[o.image] < 0 || !scene.points[o.point].position_known) continue;
    if (point[o.point] < 0) {
      point[o.point] = static_cast<int>(b.points.size());
      b.points.push_back(scene.points[o.point]);
      if (static_cast<size_t>(o.point) < from.point_covariance.size())
        to.point_covariance.push_back(from.point_covariance[o.point]);
    }
    o.image = image[o.image];
    o.point = point[o.point];
    b.observations.push_back(o);
  }
  r.bundle.usable = summary.usable;
  r.bundle.reason = summary.reason;
  r.bundle.sigma0 = summary.sigma0;
  r.point_grey.assign(b.points.size(), 128);
  MeasureReprojection(&r);
  r.summary.success = summary.usable;
  r.summary.photos = r.summary.oriented = static_cast<int>(b.images.size());
  r.summary.sigma0 = summary.sigma0;
  return r;
}

}  // namespace flight
}  // namespace slope_monitor
