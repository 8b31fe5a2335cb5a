#include "slope_monitor/core/adjustment/epoch_adjustment.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>

#include <Eigen/Geometry>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/rigid3.h"
#include "slope_monitor/core/io/gcp_list.h"

namespace slope_monitor {
namespace adjustment {

void NamingOptions::Check() const {
  auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError(Message("naming option '", key, "' ", what));
  };
  if (!(gate_sigma > 0.0)) fail("gate_sigma", Message("must be > 0, got ", gate_sigma));
  if (!(gate_extra_px >= 0.0)) fail("gate_extra_px", Message("must be >= 0, got ", gate_extra_px));
  if (!(min_gate_px > 0.0)) fail("min_gate_px", Message("must be > 0, got ", min_gate_px));
  if (!(ambiguity_factor >= 1.0))
    fail("ambiguity_factor", Message("must be >= 1, got ", ambiguity_factor));
  if (!(coarse_extra_px >= 0.0))
    fail("coarse_extra_px", Message("must be >= 0, got ", coarse_extra_px));
}

void EpochAdjustmentOptions::Check() const {
  adjustment.Check();
  naming.Check();
  if (!(max_tie_outlier_share > 0.0 && max_tie_outlier_share <= 1.0))
    throw ConfigError(
        Message("option 'max_tie_outlier_share' must be in (0, 1], got ", max_tie_outlier_share));
}

std::string NamingReport::Brief() const {
  return Message("named ", named, " of ", considered, " unidentified (", ambiguous, " ambiguous, ",
                 unmatched, " unmatched, ", not_oriented, " more in unoriented images)");
}

std::string PhotoStats::Brief() const {
  return Message("UAV photos: ", kept, " of ", total, " kept (", not_oriented, " not oriented, ",
                 too_few_observations, " too few observations)");
}

namespace {

// Each point's index by name. Scene::FindPoint is a linear search: a lookup
// per tie point of a block (10^5 of them) was quadratic (4 % of a 150-photo
// epoch's CPU in perf).
std::unordered_map<std::string, int> PointIndexByName(const Scene& scene) {
  std::unordered_map<std::string, int> index;
  index.reserve(scene.points.size());
  for (size_t j = 0; j < scene.points.size(); ++j)
    index.emplace(scene.points[j].id, static_cast<int>(j));
  return index;
}

int PointAt(const std::unordered_map<std::string, int>& index, const std::string& id) {
  const auto it = index.find(id);
  return it == index.end() ? -1 : it->second;
}

}  // namespace

NamingReport NameUnidentified(Scene* scene,
                              const std::vector<UnidentifiedObservation>& unidentified,
                              const std::vector<ListedTarget>& targets,
                              const NamingOptions& options, const std::vector<bool>* coarse) {
  options.Check();
  scene->CheckIndices();
  NamingReport report;
  std::vector<std::vector<int>> per_image(scene->images.size());
  for (size_t k = 0; k < unidentified.size(); ++k) {
    const int i = unidentified[k].image;
    if (i < 0 || i >= static_cast<int>(scene->images.size()))
      throw InvalidArgument(Message("unidentified observation ", k, " refers to image ", i, " of ",
                                    scene->images.size()));
    if (!unidentified[k].pixel.allFinite()) continue;
    per_image[i].push_back(static_cast<int>(k));
  }
  std::vector<std::set<int>> observed(scene->images.size());
  for (const Observation& o : scene->observations) observed[o.image].insert(o.point);
  std::unordered_map<std::string, int> point_index = PointIndexByName(*scene);

  struct Projection {
    int target;
    Eigen::Vector2d px;
    double gate;  // [px]
  };
  for (size_t i = 0; i < scene->images.size(); ++i) {
    if (per_image[i].empty()) continue;
    const Image& im = scene->images[i];
    if (!im.exterior_known) {
      report.not_oriented += static_cast<int>(per_image[i].size());
      continue;
    }
    const camera::CameraModel& model = scene->cameras[im.camera].model;
    const double c_px = model.interior()[camera::kC] / model.sensor().pixel_size;
    const bool is_coarse = coarse != nullptr && i < coarse->size() && (*coarse)[i];
    const double extra = is_coarse ? options.coarse_extra_px : options.gate_extra_px;
    std::vector<Projection> proj;
    for (size_t t = 0; t < targets.size(); ++t) {
      const int existing = PointAt(point_index, targets[t].id);
      const Eigen::Vector3d x = existing >= 0 && scene->points[existing].position_known
                                    ? scene->points[existing].position
                                    : targets[t].position;
      Eigen::Vector2d px;
      if (!x.allFinite() || !model.Project(im.exterior, x, &px)) continue;
      const double distance = (x - im.exterior.position).norm();
      const double sigma_px = targets[t].position_sigma * c_px / std::max(distance, 1e-6);
      const double gate = std::max(options.min_gate_px, options.gate_sigma * sigma_px + extra);
      const double margin = options.ambiguity_factor * gate;
      if (px.x() < -margin || px.y() < -margin || px.x() > model.sensor().width + margin ||
          px.y() > model.sensor().height + margin)
        continue;
      proj.push_back({static_cast<int>(t), px, gate});
    }
    for (int k : per_image[i]) {
      const UnidentifiedObservation& u = unidentified[k];
      ++report.considered;
      std::vector<const Projection*> inside, near;
      for (const Projection& p : proj) {
        if (targets[p.target].family != u.family) continue;
        const double d = (p.px - u.pixel).norm();
        if (d <= p.gate) inside.push_back(&p);
        if (d <= options.ambiguity_factor * p.gate) near.push_back(&p);
      }
      if (inside.empty()) {
        ++report.unmatched;
        continue;
      }
      const Projection& p = *inside.front();
      const ListedTarget& t = targets[p.target];
      std::string why;
      if (inside.size() > 1 || near.size() > 1) {
        why = Message(near.size(), " listed targets project near it");
      } else {
        int others = 0;
        for (int k2 : per_image[i]) {
          if (k2 != k && unidentified[k2].family == u.family &&
              (unidentified[k2].pixel - p.px).norm() <= options.ambiguity_factor * p.gate)
            ++others;
        }
        const int existing = PointAt(point_index, t.id);
        if (others > 0) {
          why = Message(others + 1, " unidentified observations near the projection of ", t.id);
        } else if (existing >= 0 && observed[i].count(existing)) {
          why = Message(t.id, " is already observed in this image");
        }
      }
      if (!why.empty()) {
        ++report.ambiguous;
        report.notes.push_back(Message(u.family, " at (", u.pixel.x(), ", ", u.pixel.y(), ") in '",
                                       im.name, "': ambiguous, ", why));
        continue;
      }
      int j = PointAt(point_index, t.id);
      if (j < 0) {
        ObjectPoint np;
        np.id = t.id;
        np.role = t.role;
        np.position = t.position;
        np.position_known = false;
        if (t.surveyed && (t.role == PointRole::kControl || t.role == PointRole::kCheck)) {
          np.surveyed = t.surveyed;
          np.surveyed_covariance = t.surveyed_covariance;
        }
        if (t.role != PointRole::kControl) np.approximate = t.position;
        j = static_cast<int>(scene->points.size());
        scene->points.push_back(np);
        point_index.emplace(np.id, j);
      }
      Observation o;
      o.image = static_cast<int>(i);
      o.point = j;
      o.pixel = u.pixel;
      o.covariance = u.covariance;
      report.named_observations.push_back(static_cast<int>(scene->observations.size()));
      report.named_inputs.push_back(k);
      scene->observations.push_back(o);
      observed[i].insert(j);
      ++report.named;
    }
  }
  return report;
}

int OrientFromApproximatePoints(Scene* scene, const InitializationOptions& options,
                                std::vector<bool>* flags) {
  scene->CheckIndices();
  if (flags) flags->resize(scene->images.size(), false);
  std::vector<int> wanted;
  for (size_t i = 0; i < scene->images.size(); ++i)
    if (!scene->images[i].exterior_known && scene->images[i].position_prior)
      wanted.push_back(static_cast<int>(i));
  if (wanted.empty()) return 0;
  Scene copy = *scene;
  bool any = false;
  for (ObjectPoint& p : copy.points) {
    if (!p.position_known && p.approximate && p.approximate->allFinite()) {
      p.position = *p.approximate;
      p.position_known = true;
      any = true;
    }
  }
  if (any) InitializeScene(&copy, options);
  // Photos seeing a single known or approximate point: the attitude of the
  // photo of the same camera nearest in time, tilted so that the point's ray
  // goes through the point (the heading stays the neighbour's).
  std::vector<std::vector<int>> obs_of_image(copy.images.size());
  for (size_t k = 0; k < copy.observations.size(); ++k) {
    const Observation& o = copy.observations[k];
    if (o.pixel.allFinite() && copy.points[o.point].position_known)
      obs_of_image[o.image].push_back(static_cast<int>(k));
  }
  std::vector<bool> oriented_before(copy.images.size());
  for (size_t i = 0; i < copy.images.size(); ++i)
    oriented_before[i] = copy.images[i].exterior_known;
  for (int i : wanted) {
    Image& im = copy.images[i];
    if (im.exterior_known) continue;
    int best = -1;
    for (size_t n = 0; n < copy.images.size(); ++n) {
      if (!oriented_before[n] || copy.images[n].camera != im.camera || static_cast<int>(n) == i)
        continue;
      if (best < 0 ||
          std::abs(copy.images[n].stamp - im.stamp) < std::abs(copy.images[best].stamp - im.stamp))
        best = static_cast<int>(n);
    }
    if (best < 0) continue;
    const Rigid3 neighbour = copy.images[best].exterior.SiteFromOptical();
    if (obs_of_image[i].empty()) {
      // No known point at all (a photo tied to the block by tie points only):
      // the neighbour's attitude (a strip is flown at a steady attitude) at
      // the photo's own GNSS position; the tie points do the rest.
      im.exterior = camera::ExteriorOrientation::FromOpticalFromSite(
          Rigid3(neighbour.rotation.toRotationMatrix(), *im.position_prior).Inverse());
      im.exterior_known = true;
      continue;
    }
    const camera::CameraModel& model = copy.cameras[im.camera].model;
    const Observation& o = copy.observations[obs_of_image[i].front()];
    const Eigen::Vector3d ray =
        neighbour.rotation * model.PixelToOpticalDirection(o.pixel).normalized();
    const Eigen::Vector3d want = (copy.points[o.point].position - *im.position_prior).normalized();
    const Eigen::Matrix3d tilt = Eigen::Quaterniond::FromTwoVectors(ray, want).toRotationMatrix();
    im.exterior = camera::ExteriorOrientation::FromOpticalFromSite(
        Rigid3(tilt * neighbour.rotation.toRotationMatrix(), *im.position_prior).Inverse());
    im.exterior_known = true;
  }
  int oriented = 0;
  for (int i : wanted) {
    if (!copy.images[i].exterior_known) continue;
    scene->images[i].exterior = copy.images[i].exterior;
    scene->images[i].exterior_known = true;
    if (flags) (*flags)[i] = true;
    ++oriented;
  }
  return oriented;
}

namespace {

using ObservationKey = std::pair<std::string, std::string>;  // image name, point id

ObservationKey KeyOf(const Scene& s, const Observation& o) {
  return {s.images[o.image].name, s.points[o.point].id};
}

// Points that intersection left unknown (rays of coarsely oriented photos
// miss each other) but that >= 2 oriented images see start from their
// approximate coordinates; they stay free unknowns of the adjustment.
void SeedFromApproximate(Scene* s) {
  std::vector<std::set<int>> seen(s->points.size());
  for (const Observation& o : s->observations)
    if (s->images[o.image].exterior_known && o.pixel.allFinite()) seen[o.point].insert(o.image);
  for (size_t j = 0; j < s->points.size(); ++j) {
    ObjectPoint& p = s->points[j];
    if (p.position_known || !p.approximate || seen[j].size() < 2) continue;
    p.position = *p.approximate;
    p.position_known = true;
  }
}

// The start values of `to` from the adjusted `from` (a subset of it, matched
// by camera, image and point name): interiors, exteriors, point positions.
void StartFrom(const Scene& from, Scene* to) {
  for (const Camera& c : from.cameras)
    for (Camera& d : to->cameras)
      if (d.name == c.name) d.model = c.model;
  for (const Image& im : from.images) {
    const int i = to->FindImage(im.name);
    if (i >= 0) to->images[i].exterior = im.exterior;
  }
  const std::unordered_map<std::string, int> index = PointIndexByName(*to);
  for (const ObjectPoint& p : from.points) {
    const int j = PointAt(index, p.id);
    if (j < 0 || !p.position.allFinite()) continue;
    to->points[j].position = p.position;
    to->points[j].position_known = true;
  }
}

// The tie-point screening: an adjustment without the usability limits (at
// most 50 iterations) whose tie observations beyond the outlier threshold are
// mismatches, and so are the picks of points picked by hand in the photos
// (a gcp list: a pick in the wrong photo or on the wrong mark, as copr's
// gcp04 in IMG_0031, 3 563 px off). Applied only when it lowered the cost and flags at most
// max_share of the tie observations (more: the fit failed, not the points).
// A converged screening is also the final adjustment's start: from a flight
// log's attitude the raw start left the 20-photo block of
// config/sim/uav_block_20 in a valley of 5x the cost (control 7 cm off). An
// unconverged one (creeping in the robust loss's linear range) is not: from it
// the self-calibration of uav_block_replay stopped 9 sigma off in c.
struct TieScreening {
  bool applied = false;
  bool converged = false;
  std::set<ObservationKey> mismatches;  // with the wrong picks
  int wrong_picks = 0;                  // picks of points picked by hand among them
  Scene solution;
  std::string refused;  // why nothing was removed although the fit flagged
};

TieScreening ScreenTiePoints(const Scene& pruned, const Options& ao, const Config& config,
                             double max_share) {
  TieScreening t;
  bool any_tie = false;
  for (const Observation& o : pruned.observations)
    any_tie = any_tie || pruned.points[o.point].role == PointRole::kTie;
  if (!any_tie) return t;
  Options so = ao;
  so.max_sigma0 = 1e12;
  so.max_outlier_fraction = 1.0;
  so.compute_covariance = false;
  so.max_iterations = std::min(ao.max_iterations, 50);
  so.write_back_unconverged =
      true;  // a block creeping in the robust loss's linear range is still fitted
  t.solution = pruned;
  const Summary ts = BundleAdjuster(so, config).Solve(&t.solution);
  if (!(std::isfinite(ts.final_cost) && ts.final_cost < ts.initial_cost)) return t;
  int ties = 0;
  std::set<ObservationKey> picks;  // of points picked by hand: screened alike
  for (const Observation& o : t.solution.observations) {
    const bool picked =
        t.solution.points[o.point].id.rfind(io::kGcpFamily + std::string("/"), 0) == 0;
    if (t.solution.points[o.point].role != PointRole::kTie && !picked) continue;
    ties += !picked;
    const Image& im = t.solution.images[o.image];
    Eigen::Vector2d px;
    bool out = !t.solution.cameras[im.camera].model.Project(
        im.exterior, t.solution.points[o.point].position, &px);
    if (!out) {
      const Eigen::Vector2d e = px - o.pixel;
      out = !(std::sqrt(e.dot(o.covariance.inverse() * e)) <= ao.outlier_threshold);
    }
    if (out) (picked ? picks : t.mismatches).insert(KeyOf(t.solution, o));
  }
  t.wrong_picks = static_cast<int>(picks.size());
  if (static_cast<double>(t.mismatches.size()) > max_share * ties) {
    t.refused = Message("the screening adjustment flagged ", t.mismatches.size(), " of ", ties,
                        " tie-point observations (more than max_tie_outlier_share ", max_share,
                        "): none removed");
    t.mismatches.clear();
    t.wrong_picks = 0;
    return t;
  }
  t.mismatches.insert(picks.begin(), picks.end());
  t.applied = true;
  t.converged = ts.termination.rfind("CONVERGENCE", 0) == 0;
  return t;
}

// The epoch's scene without the images too few observations keep and the
// points only one kept image sees (unless a surveyed control point): they
// tie nothing. Pruned again until nothing changes (at most 10 passes).
Scene PruneForAdjustment(const Scene& s, const Options& ao, PruneReport* report) {
  *report = PruneReport();
  Scene pruned =
      PruneScene(s, ao.min_observations_per_image, report,
                 std::min(ao.min_observations_with_prior, ao.min_observations_per_image));
  for (int pass = 0; pass < 10; ++pass) {
    std::vector<std::set<int>> seen(pruned.points.size());
    for (const Observation& o : pruned.observations) seen[o.point].insert(o.image);
    std::vector<Observation> kept;
    for (const Observation& o : pruned.observations) {
      const ObjectPoint& p = pruned.points[o.point];
      if (seen[o.point].size() >= 2 || (p.role == PointRole::kControl && p.surveyed))
        kept.push_back(o);
    }
    if (kept.size() == pruned.observations.size()) break;
    for (size_t j = 0; j < pruned.points.size(); ++j)
      if (seen[j].size() == 1)
        report->dropped_points.push_back(
            Message("point '", pruned.points[j].id, "': seen by one image only"));
    pruned.observations.swap(kept);
    PruneReport more;
    pruned = PruneScene(pruned, ao.min_observations_per_image, &more,
                        std::min(ao.min_observations_with_prior, ao.min_observations_per_image));
    for (auto& d : more.dropped_images) report->dropped_images.push_back(d);
    for (auto& d : more.dropped_cameras) report->dropped_cameras.push_back(d);
  }
  return pruned;
}

// The named observation with the largest whitened residual in the adjusted
// `trial` (sigmas 0 when none projects).
struct WorstName {
  double sigmas = 0.0, px = 0.0;
  ObservationKey key;
};

WorstName WorstNamedObservation(const Scene& trial, const std::set<ObservationKey>& named) {
  double worst = 0.0, worst_px = 0.0;
  ObservationKey worst_key;
  for (const Observation& o : trial.observations) {
    const ObservationKey key = KeyOf(trial, o);
    if (!named.count(key)) continue;
    const Image& im = trial.images[o.image];
    Eigen::Vector2d px;
    if (!trial.cameras[im.camera].model.Project(im.exterior, trial.points[o.point].position, &px))
      continue;
    const Eigen::Vector2d e = px - o.pixel;
    const double w = std::sqrt(e.dot(o.covariance.inverse() * e));
    if (w > worst) {
      worst = w;
      worst_px = e.norm();
      worst_key = key;
    }
  }
  return {worst, worst_px, worst_key};
}

// The adjusted orientations and point positions of `pruned` into `s` (its
// photos no longer coarse).
void TakeAdjusted(const Scene& pruned, Scene* s_out, std::vector<bool>* coarse) {
  Scene& s = *s_out;
  for (const Image& im : pruned.images) {
    const int i = s.FindImage(im.name);
    s.images[i].exterior = im.exterior;
    (*coarse)[i] = false;
  }
  const std::unordered_map<std::string, int> index = PointIndexByName(s);
  for (const ObjectPoint& p : pruned.points) {
    const int j = PointAt(index, p.id);
    s.points[j].position = p.position;
    s.points[j].position_known = true;
  }
}

// The photos' fate (GNSS-tagged photos kept, not oriented, too few
// observations) and the notes on names rejected, tie points removed, the
// screening refused and the retry without names, in r->summary.reason.
void FinishEpochReport(const Scene& s, const Options& ao, const std::string& named_failure,
                       EpochAdjustmentResult* r_out) {
  EpochAdjustmentResult& r = *r_out;
  const Scene& pruned = r.scene;
  for (const Image& im : s.images) {
    if (!im.position_prior) continue;
    ++r.photos.total;
    if (pruned.FindImage(im.name) >= 0)
      ++r.photos.kept;
    else if (!im.exterior_known)
      ++r.photos.not_oriented;
    else
      ++r.photos.too_few_observations;
  }
  if (!r.rejected_names.empty()) {
    std::string list;
    for (size_t i = 0; i < r.rejected_names.size() && i < 3; ++i)
      list += (i ? "; " : "") + r.rejected_names[i];
    r.summary.reason += Message("; ", r.rejected_names.size(),
                                " target name(s) given by projection rejected by the "
                                "residual test and removed: ",
                                list, r.rejected_names.size() > 3 ? "; ..." : "");
  }
  if (r.tie_outliers_removed > 0)
    r.summary.reason += Message("; ", r.tie_outliers_removed,
                                " tie-point observation(s) removed as mismatches (residual above ",
                                ao.outlier_threshold, " sigma in a screening adjustment)");
  if (r.wrong_picks_removed > 0)
    r.summary.reason += Message("; ", r.wrong_picks_removed,
                                " pick(s) of points picked in the photos removed (residual above ",
                                ao.outlier_threshold, " sigma in a screening adjustment)");
  if (!r.tie_screening_refused.empty()) r.summary.reason += "; " + r.tie_screening_refused;
  if (r.retried_without_names)
    r.summary.reason += "; not usable with the targets named by projection (" + named_failure +
                        "), adjusted without them";
}

}  // namespace

// What the adjustment holds: the interior parameters free for every camera
// (free_interior), or a camera's own list (free_interior_by_camera; empty:
// none free).
Config ConfigFor(const Scene& pruned, const EpochAdjustmentOptions& options) {
  Config config;
  if (!options.free_interior.empty())
    config.FreeInteriorOfAll(static_cast<int>(pruned.cameras.size()), options.free_interior);
  for (size_t c = 0; c < pruned.cameras.size(); ++c) {
    auto own = options.free_interior_by_camera.find(pruned.cameras[c].name);
    if (own == options.free_interior_by_camera.end()) continue;
    if (own->second.empty())
      config.free_interior.erase(static_cast<int>(c));
    else
      config.free_interior[static_cast<int>(c)] = own->second;
  }
  return config;
}

EpochAdjustmentResult AdjustEpoch(const Scene& scene,
                                  const std::vector<UnidentifiedObservation>& unidentified,
                                  const std::vector<ListedTarget>& targets,
                                  const EpochAdjustmentOptions& options) {
  options.Check();
  scene.CheckIndices();
  EpochAdjustmentResult r;
  Scene s = scene;
  const InitializationOptions& io = options.initialization;
  r.initialization = InitializeScene(&s, io);
  // Photos started from the flight log's attitude are coarse (naming gates).
  std::vector<bool> coarse(s.images.size(), false);
  for (size_t i = 0; i < s.images.size(); ++i) coarse[i] = s.images[i].attitude_from_prior;
  if (options.orient_from_approximate) {
    r.oriented_from_approximate = OrientFromApproximatePoints(&s, io, &coarse);
    if (r.oriented_from_approximate > 0) r.initialization = InitializeScene(&s, io);
  }
  std::set<ObservationKey> named;
  std::vector<bool> input_named(unidentified.size(), false);
  auto name = [&](bool first) {
    std::vector<UnidentifiedObservation> rest;
    std::vector<int> rest_index;
    for (size_t k = 0; k < unidentified.size(); ++k) {
      if (input_named[k]) continue;
      rest.push_back(unidentified[k]);
      rest_index.push_back(static_cast<int>(k));
    }
    const NamingReport n = NameUnidentified(&s, rest, targets, options.naming, &coarse);
    for (int k : n.named_observations) named.insert(KeyOf(s, s.observations[k]));
    for (int k : n.named_inputs) input_named[rest_index[k]] = true;
    if (first) {
      r.naming = n;
    } else {  // the second pass counts what the first left
      r.naming.named += n.named;
      r.naming.ambiguous = n.ambiguous;
      r.naming.unmatched = n.unmatched;
      r.naming.not_oriented = n.not_oriented;
      r.naming.notes = n.notes;
    }
    for (int k : n.named_inputs) r.naming.named_inputs.push_back(rest_index[k]);
    if (n.named > 0) {
      r.initialization = InitializeScene(&s, io);
      // A photo that could not be oriented before may be now.
      if (options.orient_from_approximate && OrientFromApproximatePoints(&s, io, &coarse) > 0)
        r.initialization = InitializeScene(&s, io);
    }
    return n.named;
  };
  const bool naming = options.name_unidentified && !unidentified.empty();
  if (naming) name(true);
  if (options.orient_from_approximate) SeedFromApproximate(&s);

  const Options& ao = options.adjustment;
  Scene pruned;
  std::string named_failure;
  bool ties_screened = false;
  auto solve = [&]() {
    for (int round = 0; round < 20; ++round) {
      pruned = PruneForAdjustment(s, ao, &r.pruned);
      if (pruned.images.empty()) {
        r.summary = Summary();
        r.summary.reason =
            Message("no image of the epoch could be oriented (", r.pruned.Summary(), ")");
        return;
      }
      const Config config = ConfigFor(pruned, options);
      // Tie points: one screening adjustment removes the mismatches.
      if (!ties_screened) {
        ties_screened = true;
        const TieScreening t = ScreenTiePoints(pruned, ao, config, options.max_tie_outlier_share);
        if (!t.refused.empty()) r.tie_screening_refused = t.refused;
        if (t.applied) {
          if (t.converged) StartFrom(t.solution, &s);
          std::vector<Observation> kept;
          for (const Observation& o : s.observations)
            if (!t.mismatches.count(KeyOf(s, o))) kept.push_back(o);
          r.tie_outliers_removed +=
              static_cast<int>(s.observations.size() - kept.size()) - t.wrong_picks;
          r.wrong_picks_removed += t.wrong_picks;
          s.observations.swap(kept);
          continue;
        }
      }
      // Screening: adjust without the usability limits and test the named
      // observations' residuals; the worst one above the outlier threshold
      // is a wrong name: removed, reported, adjusted again.
      if (!named.empty()) {
        Options so = ao;
        so.max_sigma0 = 1e12;
        so.max_outlier_fraction = 1.0;
        so.compute_covariance = false;
        Scene trial = pruned;
        const Summary ts = BundleAdjuster(so, config).Solve(&trial);
        if (ts.IsSolutionUsable()) {
          const WorstName worst_name = WorstNamedObservation(trial, named);
          const double worst = worst_name.sigmas, worst_px = worst_name.px;
          const ObservationKey& worst_key = worst_name.key;
          if (worst > ao.outlier_threshold) {
            r.rejected_names.push_back(Message(worst_key.second, " in '", worst_key.first,
                                               "' (residual ", worst, " sigma, ", worst_px,
                                               " px)"));
            std::vector<Observation> kept;
            for (const Observation& o : s.observations)
              if (KeyOf(s, o) != worst_key) kept.push_back(o);
            s.observations.swap(kept);
            named.erase(worst_key);
            continue;
          }
        }
      }
      const BundleAdjuster adjuster(ao, config);
      r.summary = adjuster.Solve(&pruned);
      if (!r.summary.IsSolutionUsable() && !named.empty() && !r.retried_without_names) {
        // Not usable with the named observations: once more without any.
        std::vector<Observation> kept;
        for (const Observation& o : s.observations)
          if (!named.count(KeyOf(s, o))) kept.push_back(o);
        s.observations.swap(kept);
        named.clear();
        r.retried_without_names = true;
        named_failure = r.summary.reason;
        continue;
      }
      return;
    }
  };
  solve();
  if (naming && r.summary.IsSolutionUsable() && !r.retried_without_names &&
      std::count(input_named.begin(), input_named.end(), false) > 0) {
    // Second pass: the adjusted orientations and points name what is left.
    TakeAdjusted(pruned, &s, &coarse);
    const EpochAdjustmentResult first = r;
    const Scene first_scene = pruned;
    if (name(false) > 0) {
      if (options.orient_from_approximate) SeedFromApproximate(&s);
      solve();
      if (!r.summary.IsSolutionUsable()) {  // keep the first solution
        r.summary = first.summary;
        r.pruned = first.pruned;
        pruned = first_scene;
      }
    }
  }
  r.scene = pruned;
  FinishEpochReport(s, ao, named_failure, &r);
  return r;
}

}  // namespace adjustment
}  // namespace slope_monitor
