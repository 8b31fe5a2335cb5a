#include "slope_monitor/core/flight/flight_orientation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <set>
#include <unordered_map>

#include "slope_monitor/core/adjustment/leave_one_out.h"
#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/common/rigid3.h"
#include "slope_monitor/core/geometry/similarity.h"

namespace slope_monitor {
namespace flight {
namespace {

using Clock = std::chrono::steady_clock;
// The state of the block while it grows.
struct Block {
  camera::CameraModel model;
  std::vector<camera::ExteriorOrientation> exterior;  // per photo
  std::vector<char> oriented;
  std::vector<int> failed_at;  // known points seen at the last failed resection
  std::vector<FlightTrack> tracks;
  std::vector<Eigen::Vector3d> position;  // per track
  std::vector<char> known;
  std::vector<std::vector<int>> tracks_of_photo;
  int seed_a = -1, seed_b = -1;
  bool site = false;  // false: model frame (datum: the start pair held)
  int Oriented() const { return static_cast<int>(std::count(oriented.begin(), oriented.end(), 1)); }
};

camera::ExteriorOrientation FromCamFromSite(const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  const Eigen::Matrix3d d = camera::OpticalFromPhotogrammetric();
  return camera::ExteriorOrientation::FromOpticalFromSite(
      Rigid3(Eigen::Matrix3d(d * r), Eigen::Vector3d(d * t)));
}

// Intersects a track from its observations in oriented photos; keeps it when
// every ray reprojects within max_px and the point lies in front of them.
bool IntersectTrack(Block* block, int t, const FlightOrientationOptions& options, double max_px) {
  std::vector<geometry::RayObservation> rays;
  for (const auto& [photo, px] : block->tracks[t].observations) {
    if (!block->oriented[photo]) continue;
    geometry::RayObservation r;
    r.model = &block->model;
    r.exterior = block->exterior[photo];
    r.pixel = px;
    rays.push_back(r);
  }
  if (rays.size() < 2) return false;
  const geometry::IntersectionResult res = geometry::Intersect(rays, options.intersection);
  if (!res.success) return false;
  for (const auto& r : rays) {
    Eigen::Vector2d p;
    if (!block->model.Project(r.exterior, res.position, &p) || (p - r.pixel).norm() > max_px)
      return false;
  }
  block->position[t] = res.position;
  block->known[t] = 1;
  return true;
}

void IntersectNewTracks(Block* block, const FlightOrientationOptions& options, int photo) {
  const std::vector<int>& ts = block->tracks_of_photo[photo];
  for (int t : ts)
    if (!block->known[t]) IntersectTrack(block, t, options, options.max_reprojection_px);
}

// Start pair: among the 20 pairs with the most tie points, the one whose
// relative orientation keeps the most inliers with a median ray angle of at
// least min_start_parallax_deg.
bool StartBlock(Block* block, const FlightTies& ties, const FlightOrientationOptions& options,
                std::string* why) {
  std::vector<FlightPairStats> cand = ties.pairs;
  std::sort(cand.begin(), cand.end(),
            [](const auto& x, const auto& y) { return x.tie_points > y.tie_points; });
  if (cand.size() > 20) cand.resize(20);
  int best_inliers = 0;
  Eigen::Matrix3d best_r;
  Eigen::Vector3d best_t;
  *why = "no photo pair has tie points";
  for (const FlightPairStats& p : cand) {
    if (p.tie_points < 30) break;
    std::vector<Eigen::Vector2d> xa, xb;
    for (int t : block->tracks_of_photo[p.a]) {
      const auto& obs = block->tracks[t].observations;
      Eigen::Vector2d pa, pb;
      bool ha = false, hb = false;
      for (const auto& [ph, px] : obs) {
        if (ph == p.a) pa = px, ha = true;
        if (ph == p.b) pb = px, hb = true;
      }
      if (ha && hb) xa.push_back(pa), xb.push_back(pb);
    }
    const geometry::RelativeOrientationResult ro =
        geometry::RelativeOrientation(block->model, xa, block->model, xb, options.relative);
    if (!ro.success || ro.num_inliers <= best_inliers) continue;
    std::vector<double> angles;
    for (size_t k = 0; k < xa.size(); ++k) {
      if (!ro.inliers[k]) continue;
      const Eigen::Vector3d ua = geometry::BearingOfPixel(block->model, xa[k]);
      const Eigen::Vector3d ub =
          ro.rotation.transpose() * geometry::BearingOfPixel(block->model, xb[k]);
      angles.push_back(std::acos(std::clamp(ua.normalized().dot(ub.normalized()), -1.0, 1.0)) *
                       180.0 / M_PI);
    }
    const double parallax = UpperMedian(angles);
    if (parallax < options.min_start_parallax_deg) {
      *why = Message("the pairs with most tie points have too little parallax (",
                     block->tracks.empty() ? 0 : parallax, " deg)");
      continue;
    }
    best_inliers = ro.num_inliers;
    block->seed_a = p.a;
    block->seed_b = p.b;
    best_r = ro.rotation;
    best_t = ro.translation;
  }
  if (block->seed_a < 0) return false;
  block->exterior[block->seed_a] =
      FromCamFromSite(Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero());
  block->exterior[block->seed_b] = FromCamFromSite(best_r, best_t);
  block->oriented[block->seed_a] = block->oriented[block->seed_b] = 1;
  IntersectNewTracks(block, options, block->seed_b);
  return true;
}

// The photo not yet oriented that sees most known points; -1 when none sees
// min_resection_points (or more than at its last failure).
int NextPhoto(const Block& block, const FlightOrientationOptions& options, std::vector<int>* seen) {
  int best = -1, best_n = options.min_resection_points - 1;
  seen->assign(block.oriented.size(), 0);
  for (size_t i = 0; i < block.oriented.size(); ++i) {
    if (block.oriented[i]) continue;
    int n = 0;
    for (int t : block.tracks_of_photo[i]) n += block.known[t];
    (*seen)[i] = n;
    if (n > best_n && n > block.failed_at[i] * 5 / 4) best = static_cast<int>(i), best_n = n;
  }
  return best;
}

bool ResectPhoto(Block* block, int photo, const FlightOrientationOptions& options) {
  std::vector<Eigen::Vector2d> px;
  std::vector<Eigen::Vector3d> xyz;
  for (int t : block->tracks_of_photo[photo]) {
    if (!block->known[t]) continue;
    for (const auto& [ph, p] : block->tracks[t].observations)
      if (ph == photo) px.push_back(p), xyz.push_back(block->position[t]);
  }
  const geometry::ResectionResult r = geometry::Resect(block->model, px, xyz, options.resection);
  if (!r.success || r.num_inliers < options.min_resection_points) {
    block->failed_at[photo] = static_cast<int>(px.size());
    return false;
  }
  block->exterior[photo] = r.exterior;
  block->oriented[photo] = 1;
  return true;
}

// ---------------------------------------------------------------------------
// Adjustment of the block
// ---------------------------------------------------------------------------

struct SceneMaps {
  std::vector<int> photo_of_image;
  std::vector<int> track_of_point;             // -1 for control points
  std::vector<int> control_of_point;           // -1 for tie points
  std::vector<std::pair<int, int>> track_obs;  // per observation: (track or -1, index in track)
};

struct StageSetup {
  const FlightInput* input = nullptr;
  const FlightOrientationOptions* options = nullptr;
  bool use_gnss = false;
  bool use_control = false;
  int leave_out = -1;               // control point left out (leave one out)
  bool final = false;               // full self-calibration, covariance
  bool without_covariance = false;  // the covariance failed once: solve without it
};

std::vector<int> FreeInterior(const Block& block, const StageSetup& s) {
  if (block.Oriented() < 3) return {};
  // While growing, c stays at the EXIF value: on a nadir block over gentle
  // relief c trades off against the depth of the ground (measured: c drifted
  // from 10 to 13 mm on the synthetic block), and the start pair held fixed
  // would carry that into every photo added. A prior (no focal-plane
  // resolution in EXIF) may be far off (1.2 x the larger side: 65 % on the
  // caliterra camera): c is free from the start.
  if (!s.final) {
    if (!s.input->photos->focal_prior.empty()) return {camera::kC, camera::kK1};
    return {camera::kK1};
  }
  if (block.Oriented() < s.options->min_photos_full_calibration)
    return {camera::kC, camera::kK1, camera::kK2};
  return {camera::kC, camera::kX0, camera::kY0, camera::kK1, camera::kK2, camera::kK3};
}

void AddControlPoints(const Block& block, const StageSetup& s, adjustment::Scene* scene,
                      SceneMaps* maps, const std::vector<int>& image_of_photo) {
  const auto& control = s.input->control;
  for (size_t c = 0; c < control.size(); ++c) {
    const FlightControlPoint& cp = control[c];
    if (cp.check || static_cast<int>(c) == s.leave_out) continue;
    std::vector<std::pair<int, Eigen::Vector2d>> picks;
    for (const auto& [ph, px] : cp.picks)
      if (block.oriented[ph]) picks.emplace_back(ph, px);
    if (picks.empty()) continue;
    adjustment::ObjectPoint p;
    p.id = "gcp/" + cp.name;
    p.role = adjustment::PointRole::kControl;
    p.position = cp.site;
    p.surveyed = cp.site;
    p.surveyed_covariance = cp.covariance;
    const int index = static_cast<int>(scene->points.size());
    scene->points.push_back(p);
    maps->track_of_point.push_back(-1);
    maps->control_of_point.push_back(static_cast<int>(c));
    for (const auto& [ph, px] : picks) {
      adjustment::Observation o;
      o.image = image_of_photo[ph];
      o.point = index;
      o.pixel = px;
      o.covariance =
          Eigen::Matrix2d::Identity() * s.options->pick_sigma_px * s.options->pick_sigma_px;
      scene->observations.push_back(o);
      maps->track_obs.emplace_back(-1, -1);
    }
  }
}

adjustment::Scene BuildScene(const Block& block, const StageSetup& s, SceneMaps* maps) {
  adjustment::Scene scene;
  adjustment::Camera cam;
  cam.name = "camera";
  cam.model = block.model;
  scene.cameras.push_back(cam);
  std::vector<int> image_of_photo(block.oriented.size(), -1);
  const auto& gnss = s.input->gnss_in_site;
  const double sh = s.options->gnss_sigma_horizontal_m, sv = s.options->gnss_sigma_vertical_m;
  for (size_t i = 0; i < block.oriented.size(); ++i) {
    if (!block.oriented[i]) continue;
    adjustment::Image im;
    im.name = s.input->photos->photos[i].name;
    im.exterior = block.exterior[i];
    if (s.use_gnss && i < gnss.size() && gnss[i]) {
      im.position_prior = *gnss[i];
      im.position_prior_covariance = Eigen::Vector3d(sh * sh, sh * sh, sv * sv).asDiagonal();
    }
    image_of_photo[i] = static_cast<int>(scene.images.size());
    maps->photo_of_image.push_back(static_cast<int>(i));
    scene.images.push_back(im);
  }
  const Eigen::Matrix2d tie_cov =
      Eigen::Matrix2d::Identity() * s.options->tie_sigma_px * s.options->tie_sigma_px;
  for (size_t t = 0; t < block.tracks.size(); ++t) {
    if (!block.known[t]) continue;
    const auto& obs = block.tracks[t].observations;
    int n = 0;
    for (const auto& o : obs) n += block.oriented[o.first];
    if (n < 2) continue;
    adjustment::ObjectPoint p;
    p.id = Message("tie/", t);
    p.position = block.position[t];
    const int index = static_cast<int>(scene.points.size());
    scene.points.push_back(p);
    maps->track_of_point.push_back(static_cast<int>(t));
    maps->control_of_point.push_back(-1);
    for (size_t k = 0; k < obs.size(); ++k) {
      if (!block.oriented[obs[k].first]) continue;
      scene.observations.push_back({image_of_photo[obs[k].first], index, obs[k].second, tie_cov});
      maps->track_obs.emplace_back(static_cast<int>(t), static_cast<int>(k));
    }
  }
  if (s.use_control) AddControlPoints(block, s, &scene, maps, image_of_photo);
  return scene;
}

adjustment::Config StageConfig(const Block& block, const StageSetup& s, const SceneMaps& maps) {
  adjustment::Config config;
  const std::vector<int> free = FreeInterior(block, s);
  if (!free.empty()) config.free_interior[0] = free;
  const bool datum_free = !s.use_gnss && !s.use_control;
  if (datum_free) {
    for (size_t i = 0; i < maps.photo_of_image.size(); ++i)
      if (maps.photo_of_image[i] == block.seed_a || maps.photo_of_image[i] == block.seed_b)
        config.fixed_images.insert(static_cast<int>(i));
  }
  return config;
}

adjustment::Options StageOptions(const StageSetup& s, bool datum_free) {
  adjustment::Options o = s.options->bundle;
  o.compute_covariance = s.final && s.leave_out < 0 && !s.without_covariance;
  // With control points: a datum only the held control fixes (no heights)
  // still gets a covariance, relative to the control (as in the graph).
  o.compute_datum_free_covariance = o.compute_covariance && s.use_control;
  // Leave one out starts from the final solution: a few steps reach the new minimum.
  if (!s.final || s.leave_out >= 0) o.max_iterations = s.options->intermediate_iterations;
  o.write_back_unconverged = !s.final;
  o.fixed_images_define_datum = datum_free;
  if (s.use_gnss) o.min_position_priors = 3;
  return o;
}

// Writes the adjusted scene back into the block; drops observations whose
// reprojection error exceeds max_px (and forgets points left with < 2).
int WriteBack(const adjustment::Scene& scene, const SceneMaps& maps, double max_px, Block* block) {
  block->model = scene.cameras[0].model;
  for (size_t i = 0; i < scene.images.size(); ++i)
    block->exterior[maps.photo_of_image[i]] = scene.images[i].exterior;
  for (size_t p = 0; p < scene.points.size(); ++p)
    if (maps.track_of_point[p] >= 0)
      block->position[maps.track_of_point[p]] = scene.points[p].position;
  std::set<std::pair<int, int>> drop;
  for (size_t k = 0; k < scene.observations.size(); ++k) {
    const auto [t, j] = maps.track_obs[k];
    if (t < 0) continue;
    const adjustment::Observation& o = scene.observations[k];
    Eigen::Vector2d px;
    const bool front = scene.cameras[0].model.Project(scene.images[o.image].exterior,
                                                      scene.points[o.point].position, &px);
    if (!front || (px - o.pixel).norm() > max_px) drop.emplace(t, j);
  }
  for (auto it = drop.rbegin(); it != drop.rend(); ++it) {
    auto& obs = block->tracks[it->first].observations;
    obs.erase(obs.begin() + it->second);
  }
  for (const auto& [t, j] : drop) {
    int n = 0;
    for (const auto& o : block->tracks[t].observations) n += block->oriented[o.first];
    if (n < 2) block->known[t] = 0;
  }
  return static_cast<int>(drop.size());
}

struct StageResult {
  adjustment::Summary summary;
  adjustment::Scene scene;
  SceneMaps maps;
};

StageResult Adjust(Block* block, const StageSetup& s) {
  StageResult r;
  r.scene = BuildScene(*block, s, &r.maps);
  const bool datum_free = !s.use_gnss && !s.use_control;
  const adjustment::BundleAdjuster adjuster(StageOptions(s, datum_free),
                                            StageConfig(*block, s, r.maps));
  r.summary = adjuster.Solve(&r.scene);
  // While the block grows the interior is still settling: only gross errors go.
  const double max_px = s.options->max_reprojection_px * (s.final ? 1.0 : 2.0);
  if (r.summary.IsSolutionUsable() || !s.final) WriteBack(r.scene, r.maps, max_px, block);
  return r;
}

// ---------------------------------------------------------------------------
// Georeferencing
// ---------------------------------------------------------------------------

// Intersects a control point from its picks in the oriented photos.
PointResidual MeasurePoint(const Block& block, const FlightControlPoint& cp,
                           const FlightOrientationOptions& options, Eigen::Vector3d* position) {
  PointResidual r;
  r.name = cp.name;
  r.check = cp.check;
  std::vector<geometry::RayObservation> rays;
  for (const auto& [ph, px] : cp.picks) {
    if (!block.oriented[ph]) continue;
    geometry::RayObservation ray;
    ray.model = &block.model;
    ray.exterior = block.exterior[ph];
    ray.pixel = px;
    ray.covariance = Eigen::Matrix2d::Identity() * options.pick_sigma_px * options.pick_sigma_px;
    rays.push_back(ray);
  }
  r.picks = static_cast<int>(rays.size());
  if (rays.size() < 2) {
    r.message = Message("picked in ", rays.size(), " oriented photo", rays.size() == 1 ? "" : "s",
                        " (2 needed)");
    return r;
  }
  geometry::IntersectionOptions io = options.intersection;
  io.min_angle_deg = 0.5;
  const geometry::IntersectionResult res = geometry::Intersect(rays, io);
  if (!res.success) {
    r.message = res.message;
    return r;
  }
  r.measured = true;
  r.residual = res.position - cp.site;
  if (!cp.has_height) r.residual.z() = 0.0;
  if (position) *position = res.position;
  return r;
}

void TransformBlock(const geometry::Similarity3& t, Block* block) {
  for (size_t i = 0; i < block->exterior.size(); ++i)
    if (block->oriented[i]) block->exterior[i] = geometry::TransformExterior(t, block->exterior[i]);
  for (size_t k = 0; k < block->position.size(); ++k)
    if (block->known[k]) block->position[k] = t * block->position[k];
  block->site = true;
}

// Model -> site from control points (>= 3 intersected) or GNSS (>= 3 photos
// off one line); "" and *datum set on success, else why not.
std::string Georeference(const FlightInput& input, const FlightOrientationOptions& options,
                         Block* block, std::string* datum, bool* use_gnss, bool* use_control) {
  std::vector<Eigen::Vector3d> model, site;
  for (const FlightControlPoint& cp : input.control) {
    Eigen::Vector3d x;
    if (cp.check || !MeasurePoint(*block, cp, options, &x).measured) continue;
    model.push_back(x);
    site.push_back(cp.site);
  }
  std::string why;
  if (model.size() >= 3 && !geometry::AreCollinear(site)) {
    *use_control = true;
    *datum = Message(model.size(), " control points");
  } else {
    if (!input.control.empty())
      why = Message(model.size(),
                    " control points intersected from their picks (3 needed off one line); ");
    model.clear();
    site.clear();
    for (size_t i = 0; i < block->oriented.size(); ++i) {
      if (!block->oriented[i] || i >= input.gnss_in_site.size() || !input.gnss_in_site[i]) continue;
      model.push_back(block->exterior[i].position);
      site.push_back(*input.gnss_in_site[i]);
    }
    if (model.size() < 3 || geometry::AreCollinear(site, 0.02))
      return why + Message(model.size(), " oriented photos with GNSS",
                           model.size() >= 3 ? ", all on one line" : "",
                           ": the block stays in its model frame");
    *datum = Message("GNSS of ", model.size(), " photos");
  }
  *use_gnss = input.gnss_in_site.size() > 0 &&
              std::any_of(input.gnss_in_site.begin(), input.gnss_in_site.end(),
                          [](const auto& g) { return g.has_value(); });
  TransformBlock(geometry::FitSimilarity(model, site, true), block);
  if (*use_gnss && *use_control) *datum += " and GNSS";
  return "";
}

// ---------------------------------------------------------------------------
// The stages
// ---------------------------------------------------------------------------

void SetTracks(const std::vector<FlightTrack>& tracks, Block* b) {
  b->tracks = tracks;
  b->position.assign(tracks.size(), Eigen::Vector3d::Zero());
  b->known.assign(tracks.size(), 0);
  b->tracks_of_photo.assign(b->oriented.size(), {});
  for (size_t t = 0; t < tracks.size(); ++t)
    for (const auto& o : tracks[t].observations)
      b->tracks_of_photo[o.first].push_back(static_cast<int>(t));
}

Block MakeBlock(const FlightInput& input) {
  Block b;
  const size_t n = input.photos->photos.size();
  const camera::CameraModel& nominal = input.photos->nominal;
  // A camera from EXIF (no distortion yet) is self-calibrated with radial
  // terms; a calibrated camera keeps its model and terms.
  b.model = nominal.model() == camera::DistortionModel::kNone
                ? camera::CameraModel(nominal.sensor(), camera::DistortionModel::kRadial,
                                      nominal.interior())
                : nominal;
  b.exterior.resize(n);
  b.oriented.assign(n, 0);
  b.failed_at.assign(n, 0);
  SetTracks(input.ties->growth_tracks.empty() ? input.ties->tracks : input.ties->growth_tracks, &b);
  return b;
}

// The adjustment's tracks (the ties' own, not joined) in place of the
// growth's: each intersected from the oriented photos.
void UseAdjustmentTracks(const FlightInput& input, const FlightOrientationOptions& options,
                         Block* block) {
  if (input.ties->growth_tracks.empty()) return;
  SetTracks(input.ties->tracks, block);
  for (size_t t = 0; t < block->tracks.size(); ++t)
    IntersectTrack(block, static_cast<int>(t), options, options.max_reprojection_px);
}

// Resection / intersection, with an adjustment each time the oriented photos
// grew by growth_for_adjustment.
void Grow(Block* block, const FlightInput& input, const FlightOrientationOptions& options,
          const StageProgress& progress) {
  StageSetup s;
  s.input = &input;
  s.options = &options;
  int adjusted_at = 2;
  std::vector<int> seen;
  for (;;) {
    const int next = NextPhoto(*block, options, &seen);
    if (next < 0) break;
    if (!ResectPhoto(block, next, options)) continue;
    if (progress) progress("oriented", block->Oriented(), static_cast<int>(block->oriented.size()));
    IntersectNewTracks(block, options, next);
    if (block->Oriented() >= adjusted_at * options.growth_for_adjustment) {
      Adjust(block, s);
      for (size_t t = 0; t < block->tracks.size(); ++t)
        if (!block->known[t])
          IntersectTrack(block, static_cast<int>(t), options, options.max_reprojection_px);
      adjusted_at = block->Oriented();
    }
  }
  Adjust(block, s);
}

std::vector<std::string> NotOriented(const Block& block, const FlightInput& input,
                                     const FlightOrientationOptions& options) {
  std::vector<std::string> out;
  std::vector<int> seen;
  NextPhoto(block, options, &seen);
  for (size_t i = 0; i < block.oriented.size(); ++i) {
    if (block.oriented[i]) continue;
    const std::string& name = input.photos->photos[i].name;
    if (block.tracks_of_photo[i].empty())
      out.push_back(name + ": no tie points with any other photo");
    else
      out.push_back(Message(name, ": ", block.tracks_of_photo[i].size(), " tie points, ", seen[i],
                            " of them on oriented points; resection failed"));
  }
  return out;
}

double Rms3(const std::vector<PointResidual>& v) {
  double s = 0.0;
  int n = 0;
  for (const PointResidual& r : v)
    if (r.measured) s += r.residual.squaredNorm(), ++n;
  return n ? std::sqrt(s / n) : 0.0;
}

// Control points' residuals: the adjusted control points against their
// survey, check points intersected from their picks.
void ControlReport(const Block& block, const StageResult& stage, const FlightInput& input,
                   const FlightOrientationOptions& options, FlightSummary* summary) {
  for (size_t c = 0; c < input.control.size(); ++c) {
    const FlightControlPoint& cp = input.control[c];
    PointResidual r = MeasurePoint(block, cp, options, nullptr);
    if (!cp.check) {
      for (size_t p = 0; p < stage.scene.points.size(); ++p) {
        if (stage.maps.control_of_point[p] != static_cast<int>(c)) continue;
        r.measured = true;
        r.message.clear();
        r.residual = stage.scene.points[p].position - cp.site;
        if (!cp.has_height) r.residual.z() = 0.0;
      }
    }
    (cp.check ? summary->check : summary->control).push_back(r);
  }
  summary->control_rms = Rms3(summary->control);
  summary->check_rms = Rms3(summary->check);
}

// The block placed on the control points but `left_out`, as the adjustment
// without it starts (adjustment::PlacementOnControl).
void PlaceOnTheOthers(const FlightInput& input, const FlightOrientationOptions& options,
                      size_t left_out, Block* block) {
  std::vector<Eigen::Vector3d> from, to;
  std::vector<double> weights;
  bool heights = false;
  for (size_t c = 0; c < input.control.size(); ++c) {
    const FlightControlPoint& cp = input.control[c];
    Eigen::Vector3d x;
    if (cp.check || c == left_out || !MeasurePoint(*block, cp, options, &x).measured) continue;
    from.push_back(x);
    to.push_back(cp.site);
    weights.push_back(1.0 / std::max(cp.covariance(0, 0), 1e-12));
    heights = heights || cp.has_height;
  }
  if (const auto t = adjustment::PlacementOnControl(from, to, weights, heights))
    TransformBlock(*t, block);
}

void LeaveOneOut(const Block& block, const StageSetup& final_setup, const FlightInput& input,
                 const FlightOrientationOptions& options, FlightSummary* summary) {
  const auto t0 = Clock::now();
  int usable = 0;
  for (const FlightControlPoint& cp : input.control) usable += !cp.check;
  for (size_t c = 0; c < input.control.size(); ++c) {
    if (input.control[c].check) continue;
    Block b = block;
    StageSetup s = final_setup;
    s.leave_out = static_cast<int>(c);
    PointResidual r;
    r.name = input.control[c].name;
    if (usable - 1 < 3 && !s.use_gnss) {
      r.message = "too few other control points for a datum";
    } else {
      PlaceOnTheOthers(input, options, c, &b);
      const StageResult st = Adjust(&b, s);
      r = MeasurePoint(b, input.control[c], options, nullptr);
      if (!st.summary.IsSolutionUsable()) r.measured = false, r.message = st.summary.reason;
    }
    summary->leave_one_out.push_back(r);
  }
  summary->leave_one_out_rms = Rms3(summary->leave_one_out);
  summary->seconds["leave_one_out"] = SecondsSince(t0);
}

}  // namespace

void MeasureReprojection(FlightResult* result) {
  const adjustment::Scene& sc = result->scene;
  result->observation_error_px.assign(sc.observations.size(), 0.0);
  result->point_error_px.assign(sc.points.size(), 0.0);
  std::vector<int> count(sc.points.size(), 0);
  double sum = 0.0, sum_sq = 0.0;
  for (size_t k = 0; k < sc.observations.size(); ++k) {
    const adjustment::Observation& o = sc.observations[k];
    Eigen::Vector2d px;
    sc.cameras[0].model.Project(sc.images[o.image].exterior, sc.points[o.point].position, &px);
    const double e = (px - o.pixel).norm();
    result->observation_error_px[k] = e;
    result->point_error_px[o.point] += e;
    ++count[o.point];
    sum += e;
    sum_sq += e * e;
  }
  for (size_t p = 0; p < sc.points.size(); ++p)
    if (count[p]) result->point_error_px[p] /= count[p];
  const double n = std::max<size_t>(1, sc.observations.size());
  result->summary.observations = static_cast<int>(sc.observations.size());
  result->summary.points = static_cast<int>(sc.points.size());
  result->summary.mean_px = sum / n;
  result->summary.rms_px = std::sqrt(sum_sq / n);
}

namespace {

// The control points' pick residuals into the summary; then the control
// points leave the result's scene (it holds the photos and tie points).
void SeparateControl(const Block& block, const StageResult& stage, FlightResult* result) {
  const adjustment::Scene& sc = stage.scene;
  std::vector<double> sum(sc.points.size(), 0.0);
  std::vector<int> n(sc.points.size(), 0);
  for (const adjustment::Observation& o : sc.observations) {
    if (stage.maps.control_of_point[o.point] < 0) continue;
    Eigen::Vector2d px;
    sc.cameras[0].model.Project(sc.images[o.image].exterior, sc.points[o.point].position, &px);
    sum[o.point] += (px - o.pixel).squaredNorm();
    ++n[o.point];
  }
  for (size_t p = 0; p < sc.points.size(); ++p)
    for (PointResidual& r : result->summary.control)
      if (n[p] && "gcp/" + r.name == sc.points[p].id) r.pick_rms_px = std::sqrt(sum[p] / n[p]);
  adjustment::Scene ties;
  ties.cameras = sc.cameras;
  ties.images = sc.images;
  std::vector<int> index(sc.points.size(), -1);
  result->point_grey.clear();
  for (size_t p = 0; p < sc.points.size(); ++p) {
    const int t = stage.maps.track_of_point[p];
    if (t < 0) continue;
    index[p] = static_cast<int>(ties.points.size());
    ties.points.push_back(sc.points[p]);
    result->point_grey.push_back(block.tracks[t].grey);
  }
  for (adjustment::Observation o : sc.observations) {
    if (index[o.point] < 0) continue;
    o.point = index[o.point];
    ties.observations.push_back(o);
  }
  result->scene = std::move(ties);
}

void FillResult(const Block& block, StageResult&& stage, FlightResult* result) {
  SeparateControl(block, stage, result);
  result->bundle = std::move(stage.summary);
  result->photo_of_image = stage.maps.photo_of_image;
  result->summary.oriented = static_cast<int>(result->scene.images.size());
  result->summary.sigma0 = result->bundle.sigma0;
  if (result->bundle.precision.valid && !result->bundle.precision.interior_sigma.empty())
    result->summary.interior_sigma = result->bundle.precision.interior_sigma[0];
  MeasureReprojection(result);
}

}  // namespace

void FlightOrientationOptions::Check() const {
  relative.Check();
  resection.Check();
  intersection.Check();
  bundle.Check();
  const char* o = "flight orientation";
  RequireOption(o, min_start_parallax_deg > 0.0, "min_start_parallax_deg", "must be > 0");
  RequireOption(o, min_resection_points >= 6, "min_resection_points", "must be >= 6");
  RequireOption(o, growth_for_adjustment > 1.0, "growth_for_adjustment", "must be > 1");
  RequireOption(o, max_reprojection_px > 0.0, "max_reprojection_px", "must be > 0");
  RequireOption(o, tie_sigma_px > 0.0, "tie_sigma_px", "must be > 0");
  RequireOption(o, pick_sigma_px > 0.0, "pick_sigma_px", "must be > 0");
  RequireOption(o, gnss_sigma_horizontal_m > 0.0, "gnss_sigma_horizontal_m", "must be > 0");
  RequireOption(o, gnss_sigma_vertical_m > 0.0, "gnss_sigma_vertical_m", "must be > 0");
  RequireOption(o, min_photos_full_calibration >= 3, "min_photos_full_calibration", "must be >= 3");
  RequireOption(o, intermediate_iterations > 0, "intermediate_iterations", "must be > 0");
}

FlightResult OrientFlight(const FlightInput& input, const FlightOrientationOptions& options,
                          const StageProgress& progress) {
  options.Check();
  if (!input.photos || !input.ties)
    throw InvalidArgument("OrientFlight: photos and ties are required");
  FlightResult result;
  FlightSummary& sum = result.summary;
  sum.photos = static_cast<int>(input.photos->photos.size());
  Block block = MakeBlock(input);
  auto t0 = Clock::now();
  std::string why;
  if (!StartBlock(&block, *input.ties, options, &why)) {
    sum.message = "no start pair: " + why;
    sum.not_oriented = NotOriented(block, input, options);
    return result;
  }
  sum.seconds["start"] = SecondsSince(t0);
  t0 = Clock::now();
  if (progress) progress("oriented", 2, sum.photos);
  Grow(&block, input, options, progress);
  UseAdjustmentTracks(input, options, &block);
  sum.seconds["growth"] = SecondsSince(t0);
  t0 = Clock::now();
  StageSetup s;
  s.input = &input;
  s.options = &options;
  s.final = true;
  const std::string geo =
      Georeference(input, options, &block, &sum.datum, &s.use_gnss, &s.use_control);
  sum.georeferenced = geo.empty();
  if (!geo.empty())
    sum.datum = "model frame (no datum: arbitrary scale and orientation; " + geo + ")";
  sum.seconds["georeference"] = SecondsSince(t0);
  t0 = Clock::now();
  Adjust(&block, s);  // drops the observations the site frame's datum shows as blunders
  StageResult final_stage = Adjust(&block, s);
  if (final_stage.summary.precision.relative_to_control)
    sum.covariance_note =
        "sigmas relative to the control points held (the absolute covariance is singular)";
  if (!final_stage.summary.IsSolutionUsable() &&
      final_stage.summary.reason.find("covariance") != std::string::npos) {
    // A weak datum (control points known to metres, heights not given) can
    // leave the covariance unobtainable while the solution itself is sound:
    // keep the solution and say that it has no sigma.
    sum.covariance_note = "no covariance: " + final_stage.summary.reason;
    s.without_covariance = true;
    final_stage = Adjust(&block, s);
  }
  sum.seconds["adjustment"] = SecondsSince(t0);
  sum.not_oriented = NotOriented(block, input, options);
  if (!final_stage.summary.IsSolutionUsable()) {
    sum.message = "the final adjustment is not usable: " + final_stage.summary.reason;
    return result;
  }
  ControlReport(block, final_stage, input, options, &sum);
  if (options.leave_one_out && s.use_control) LeaveOneOut(block, s, input, options, &sum);
  FillResult(block, std::move(final_stage), &result);
  sum.success = sum.oriented >= 2;
  return result;
}

}  // namespace flight
}  // namespace slope_monitor
