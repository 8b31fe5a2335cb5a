#include "slope_monitor/core/adjustment/epoch_collector.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/rigid3.h"
#include "slope_monitor/core/common/state_text.h"

namespace slope_monitor {
namespace adjustment {

namespace {
constexpr int64_t kNsPerSecond = 1000000000;

std::string Seconds(double s) { return Message(static_cast<long long>(std::llround(s)), " s"); }
}  // namespace

StampNs MakeStamp(int64_t sec, int64_t nsec) { return sec * kNsPerSecond + nsec; }

double StampSeconds(StampNs stamp) {
  // Whole seconds (integer division on purpose), then the nanoseconds.
  return static_cast<double>(stamp / kNsPerSecond) +  // NOLINT(bugprone-integer-division)
         1e-9 * static_cast<double>(stamp % kNsPerSecond);
}

std::string ImageKey(const std::string& camera, StampNs stamp) {
  return camera + "@" + std::to_string(stamp / kNsPerSecond) + "." +
         std::to_string(stamp % kNsPerSecond);
}

bool IsUavCamera(const std::string& camera, const std::vector<std::string>& uav_cameras) {
  return std::find(uav_cameras.begin(), uav_cameras.end(), camera) != uav_cameras.end();
}

std::vector<std::string> DefaultUavCameras() {
  return io::CameraNames(io::DefaultCameras(), io::CameraKind::kUav);
}

PointRole RoleOf(const io::TargetSpec* spec) {
  if (spec == nullptr) return PointRole::kTie;
  switch (spec->role) {
    case io::TargetRole::kControl:
      return PointRole::kControl;
    case io::TargetRole::kCheck:
      return PointRole::kCheck;
    default:
      return PointRole::kMonitoring;
  }
}

void EpochCollectorOptions::Check() const {
  auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError(Message("epoch collector option '", key, "' ", what));
  };
  if (!(pixel_sigma > 0.0)) fail("pixel_sigma", Message("must be > 0, got ", pixel_sigma));
  if (!(pixel_sigma_floor >= 0.0))
    fail("pixel_sigma_floor", Message("must be >= 0, got ", pixel_sigma_floor));
  if (!(uav_pixel_sigma_floor >= 0.0))
    fail("uav_pixel_sigma_floor", Message("must be >= 0, got ", uav_pixel_sigma_floor));
  if (!(tie_pixel_sigma_floor >= 0.0))
    fail("tie_pixel_sigma_floor", Message("must be >= 0, got ", tie_pixel_sigma_floor));
  if (!(min_tie_quality >= 0.0 && min_tie_quality <= 1.0))
    fail("min_tie_quality", Message("must be in [0, 1], got ", min_tie_quality));
  if (!(max_pixel_sigma > 0.0))
    fail("max_pixel_sigma", Message("must be > 0, got ", max_pixel_sigma));
  if (!(epoch_gap >= 0.0)) fail("epoch_gap", Message("must be >= 0, got ", epoch_gap));
  if (!(epoch_wait >= 0.0)) fail("epoch_wait", Message("must be >= 0, got ", epoch_wait));
  if (!(tie_point_wait >= 0.0))
    fail("tie_point_wait", Message("must be >= 0, got ", tie_point_wait));
}

EpochCollector::EpochCollector(const EpochCollectorOptions& options, const io::TargetList* targets)
    : options_(options), targets_(targets) {
  options_.Check();
}

// ------------------------------------------------------------------ input

void EpochCollector::RememberImage(const std::string& key, const std::string& camera,
                                   const std::string& frame_id, StampNs stamp) {
  CollectedImage& im = images_[key];
  im.key = key;
  im.camera = camera;
  im.frame_id = frame_id.empty() ? camera + "_optical" : frame_id;
  im.stamp = stamp;
}

std::optional<Eigen::Matrix2d> EpochCollector::Covariance(const Eigen::Matrix2d& given,
                                                          double floor, std::string* why) const {
  Eigen::Matrix2d c = given;
  if (c.isZero()) {
    c = Eigen::Matrix2d::Identity() * options_.pixel_sigma * options_.pixel_sigma;
  } else if (!c.allFinite()) {
    *why = "covariance not finite";
    return std::nullopt;
  } else if (!(c(0, 0) > 0.0 && c(1, 1) > 0.0 && c.determinant() > 0.0)) {
    *why = Message("covariance not positive definite ([", c(0, 0), ", ", c(0, 1), "; ", c(1, 0),
                   ", ", c(1, 1), "] px^2)");
    return std::nullopt;
  } else if (std::max(c(0, 0), c(1, 1)) > options_.max_pixel_sigma * options_.max_pixel_sigma) {
    *why = Message("sigma ", std::sqrt(std::max(c(0, 0), c(1, 1))), " px above max_pixel_sigma ",
                   options_.max_pixel_sigma, " px");
    return std::nullopt;
  }
  // Image noise only; calibration and model errors come on top (quadrature).
  return Eigen::Matrix2d(c + Eigen::Matrix2d::Identity() * floor * floor);
}

std::vector<CollectedEpoch> EpochCollector::AddTargets(const ImageTargets& image, double now) {
  std::vector<CollectedEpoch> done;
  // Without end markers, an image far after the collected ones starts a new epoch.
  if (ends_.empty() && options_.epoch_gap > 0.0 && !observations_.empty()) {
    StampNs latest = 0;
    for (const auto& [key, im] : images_) latest = std::max(latest, im.stamp);
    if (StampSeconds(image.stamp) - StampSeconds(latest) > options_.epoch_gap)
      done.push_back(
          Take(Message("an image ", Seconds(StampSeconds(image.stamp) - StampSeconds(latest)),
                       " after the previous one (epoch_gap)"),
               {}, now));
  }
  // Each camera its own optical frame (one transform per frame is published):
  // a second camera in a frame already in use is refused, naming both.
  const std::string frame = image.frame_id.empty() ? image.camera + "_optical" : image.frame_id;
  const auto owner = frame_owner_.emplace(frame, image.camera).first;
  if (owner->second != image.camera) {
    const std::string line =
        Message("camera '", image.camera, "' sends its images in frame '", frame,
                "', the frame of camera '", owner->second,
                "': its images are refused (each camera its own frame: camera_capture.launch "
                "camera_name:=",
                image.camera, ")");
    if (std::find(ignored_.begin(), ignored_.end(), line) == ignored_.end())
      ignored_.push_back(line);
    return done;
  }
  const std::string key = ImageKey(image.camera, image.stamp);
  RememberImage(key, image.camera, image.frame_id, image.stamp);
  targets_in_.insert(key);
  StampNs& latest = latest_image_[image.camera];
  latest = std::max(latest, image.stamp);
  if (image.epoch != 0 && ends_.empty()) current_epoch_ = image.epoch;
  // A UAV camera flies with its nominal interior: its model error is far
  // above the centroid precision.
  const double floor = IsUavCamera(image.camera, options_.uav_cameras)
                           ? options_.uav_pixel_sigma_floor
                           : options_.pixel_sigma_floor;
  for (const TargetInput& t : image.targets) {
    CollectedObservation c;
    c.image_key = key;
    c.family = t.family;
    c.pixel = t.pixel;
    const std::string name =
        t.id < 0 ? "unidentified " + t.family : t.family + "/" + std::to_string(t.id);
    std::string why;
    std::optional<Eigen::Matrix2d> cov = Covariance(t.covariance, floor, &why);
    if (!t.pixel.allFinite()) why = "pixel not finite";
    if (!why.empty()) {
      dropped_.push_back({key, Message(key, ": ", name, ": ", why, " (dropped)")});
      ++observations_dropped_;
      continue;
    }
    c.covariance = *cov;
    if (t.id < 0) {  // unidentified (a circle the centroider could not name without a pose)
      ++unidentified_received_;
      unidentified_.push_back(c);
      continue;
    }
    c.point_id = name;
    c.role = RoleOf(targets_ == nullptr ? nullptr : targets_->Find(t.family, t.id));
    observations_.push_back(c);
  }
  last_input_at_ = now;
  for (CollectedEpoch& e : TakeReady(now)) done.push_back(std::move(e));
  return done;
}

std::vector<CollectedEpoch> EpochCollector::AddTies(const ImageTies& ties, double now) {
  const std::string kb = ImageKey(ties.camera_b, ties.stamp_b);
  const bool has_a = !ties.camera_a.empty();
  const std::string ka = has_a ? ImageKey(ties.camera_a, ties.stamp_a) : std::string();
  RememberImage(kb, ties.camera_b, ties.frame_b, ties.stamp_b);
  if (has_a) RememberImage(ka, ties.camera_a, ties.frame_a, ties.stamp_a);
  // A matcher in sequence mode says how many messages image b gets (pairs_b).
  if (ties.pairs_b > 0) {
    TieCount& count = tie_counts_[kb];
    ++count.received;
    count.expected = ties.pairs_b;
  }
  for (const TieInput& t : ties.points) {
    if (t.id == 0 || !has_a) continue;            // a match without a track ties this pair only
    if (t.quality <= options_.min_tie_quality) {  // flagged by the matcher's quality control
      ++tie_points_low_quality_;
      continue;
    }
    const std::string id = "tie/" + std::to_string(t.id);
    std::string why;
    // The matcher's covariance is that of xb given xa; xa carries the same.
    std::optional<Eigen::Matrix2d> cov =
        Covariance(t.covariance, options_.tie_pixel_sigma_floor, &why);
    if (!(t.a.allFinite() && t.b.allFinite())) why = "pixel not finite";
    if (!why.empty()) {
      dropped_.push_back({kb, Message(kb, ": ", id, " (with ", ka, "): ", why, " (dropped)")});
      ++observations_dropped_;
      continue;
    }
    observations_.push_back({ka, id, "tie", PointRole::kTie, t.a, *cov});
    observations_.push_back({kb, id, "tie", PointRole::kTie, t.b, *cov});
    ++tie_points_used_;
  }
  last_input_at_ = now;
  return TakeReady(now);
}

void EpochCollector::AddPrior(const PositionPrior& prior) { priors_.push_back(prior); }

std::vector<CollectedEpoch> EpochCollector::AddEnd(const EpochEnd& end, double now) {
  Route(end, now);
  return TakeReady(now);
}

void EpochCollector::Route(const EpochEnd& end, double now) {
  auto current = ends_.find(end.source);
  auto solved = solved_end_.find(end.source);
  const std::string what = Message("end marker of '", end.source, "' (epoch ", end.epoch,
                                   ", stamp ", StampSeconds(end.stamp), " s)");
  if (current != ends_.end() && end.stamp == current->second.stamp) {
    ignored_.push_back(what + ": duplicate, ignored");
  } else if (current != ends_.end() && end.stamp < current->second.stamp) {
    ignored_.push_back(what + ": older than the one being collected, ignored");
  } else if (solved != solved_end_.end() && end.stamp <= solved->second) {
    ignored_.push_back(what + ": of an epoch already solved, ignored");
  } else if (current != ends_.end() || (!ends_.empty() && cut_short_.count(end.source))) {
    // The NEXT epoch of a source while this one still waits (a slow matcher):
    // kept until this one is solved. Configured cameras that have not ended
    // this epoch by now never will: they are cut short.
    for (const EpochEnd& d : deferred_ends_)
      if (d.source == end.source && d.stamp == end.stamp) {
        ignored_.push_back(what + ": duplicate, ignored");
        return;
      }
    deferred_ends_.push_back(end);
    for (const std::string& c : options_.cameras)
      if (!ends_.count(c)) cut_short_.insert(c);
  } else {
    if (end.epoch != 0) current_epoch_ = end.epoch;
    ends_[end.source] = end;
    ended_at_ = now;
  }
}

// ------------------------------------------------------------------ completion

StampNs EpochCollector::Cutoff() const {
  StampNs cutoff = 0;
  for (const auto& [source, end] : ends_) cutoff = std::max(cutoff, end.stamp);
  return cutoff;
}

bool EpochCollector::InEpoch(const std::string& camera, StampNs stamp) const {
  if (ends_.empty()) return true;
  auto end = ends_.find(camera);
  return stamp <= (end != ends_.end() ? end->second.stamp : Cutoff());
}

bool EpochCollector::LeftOut(const std::string& camera) const {
  if (ends_.empty() || ends_.count(camera)) return false;
  return std::find(options_.cameras.begin(), options_.cameras.end(), camera) !=
         options_.cameras.end();
}

std::vector<std::string> EpochCollector::MissingEnds() const {
  std::vector<std::string> out;
  for (const std::string& c : options_.cameras)
    if (!ends_.count(c)) out.push_back(c);
  return out;
}

std::vector<std::string> EpochCollector::MissingImages(bool blocking_only) const {
  std::vector<std::string> out;
  for (const auto& [source, end] : ends_) {
    uint32_t have = 0;
    for (const auto& [key, im] : images_)
      have += im.camera == source && im.stamp <= end.stamp && targets_in_.count(key) ? 1 : 0;
    if (have >= end.count) continue;
    // A camera's images arrive in order: once a later one is in, the missing
    // one is not coming.
    auto latest = latest_image_.find(source);
    const bool moved_on = latest != latest_image_.end() && latest->second > end.stamp;
    if (blocking_only && moved_on) continue;
    out.push_back(Message(source, ": ", have, " of ", end.count, " announced images"));
  }
  return out;
}

std::vector<std::string> EpochCollector::MissingTies() const {
  std::vector<std::string> out;
  if (options_.tie_point_cameras.empty() || !tie_points_expected_) return out;
  for (const std::string& c : options_.tie_point_cameras) {
    auto end = ends_.find(c);
    if (end == ends_.end()) continue;
    uint32_t complete = 0;
    std::string first_short;
    for (const auto& [key, count] : tie_counts_) {
      auto im = images_.find(key);
      if (im == images_.end() || im->second.camera != c || im->second.stamp > end->second.stamp)
        continue;
      if (count.received >= count.expected) {
        ++complete;
      } else if (first_short.empty()) {
        first_short =
            Message(", e.g. '", key, "' ", count.received, " of ", count.expected, " messages");
      }
    }
    if (complete < end->second.count)
      out.push_back(Message("tie points of ", c, ": ", complete, " of ", end->second.count,
                            " images complete", first_short));
  }
  return out;
}

bool EpochCollector::Ready() const {
  if (ends_.empty()) return false;
  for (const std::string& c : options_.cameras)
    if (!ends_.count(c) && !cut_short_.count(c)) return false;
  return MissingTies().empty() && MissingImages(true).empty();
}

std::vector<CollectedEpoch> EpochCollector::TakeReady(double now) {
  std::vector<CollectedEpoch> done;
  while (Ready()) {
    std::vector<std::string> given_up = MissingImages(false);
    done.push_back(Take("end markers", given_up, now));
  }
  return done;
}

std::vector<CollectedEpoch> EpochCollector::Poll(double now) {
  std::vector<CollectedEpoch> done;
  if (ends_.empty()) {
    if (options_.epoch_gap > 0.0 && !observations_.empty() &&
        now - last_input_at_ > options_.epoch_gap)
      done.push_back(
          Take(Message("no input for ", Seconds(now - last_input_at_), " (epoch_gap)"), {}, now));
    return done;
  }
  done = TakeReady(now);
  if (!done.empty() || ends_.empty()) return done;
  const double waited = now - ended_at_;
  const bool ties = MissingTies().empty();
  if (waited > options_.epoch_wait &&
      (ties || waited > std::max(options_.epoch_wait, options_.tie_point_wait)))
    done.push_back(
        Take(Message("time-out ", Seconds(waited), " after the last end marker (epoch_wait ",
                     options_.epoch_wait, " s, tie_point_wait ", options_.tie_point_wait, " s)"),
             AllMissing(), now));
  return done;
}

std::vector<std::string> EpochCollector::AllMissing() const {
  std::vector<std::string> out;
  if (!ends_.empty())
    for (const std::string& c : MissingEnds()) out.push_back(c + ": no end marker");
  for (const std::string& s : MissingImages(false)) out.push_back(s);
  for (const std::string& s : MissingTies()) out.push_back(s);
  return out;
}

std::optional<CollectedEpoch> EpochCollector::Finish() {
  if (images_.empty() && deferred_ends_.empty()) return std::nullopt;
  return Take("end of input", AllMissing(), last_input_at_);
}

CollectedEpoch EpochCollector::TakeNow() { return Take("requested", AllMissing(), last_input_at_); }

CollectedEpoch EpochCollector::Take(const std::string& reason, std::vector<std::string> incomplete,
                                    double now) {
  CollectedEpoch out;
  out.epoch = current_epoch_;
  out.reason = reason;
  out.incomplete = std::move(incomplete);
  // This epoch's images; later ones (the next epoch, arriving while a slow
  // matcher finished this one) stay; those of a camera cut short are left out.
  std::map<std::string, CollectedImage> later;
  std::map<std::string, int> left_out;
  std::set<std::string> left_out_keys;
  for (auto& [key, im] : images_) {
    if (!InEpoch(im.camera, im.stamp)) {
      later[key] = im;
    } else if (LeftOut(im.camera)) {
      ++left_out[im.camera];
      left_out_keys.insert(key);
    } else {
      out.latest_stamp = std::max(out.latest_stamp, im.stamp);
      out.images[key] = im;
    }
  }
  for (const auto& [camera, n] : left_out) {
    const std::string line = Message(camera, ": no end marker (", n, " images left out)");
    const std::string prefix = camera + ": no end marker";
    auto same = std::find_if(out.incomplete.begin(), out.incomplete.end(),
                             [&prefix](const std::string& s) { return s.rfind(prefix, 0) == 0; });
    if (same != out.incomplete.end())
      *same = line;
    else
      out.incomplete.push_back(line);
  }
  if (!ends_.empty())
    for (const std::string& c : cut_short_)
      if (!left_out.count(c) && !ends_.count(c))
        if (std::find(out.incomplete.begin(), out.incomplete.end(), c + ": no end marker") ==
            out.incomplete.end())
          out.incomplete.push_back(c + ": no end marker");
  auto split = [&](std::vector<CollectedObservation>* all,
                   std::vector<CollectedObservation>* mine) {
    std::vector<CollectedObservation> rest;
    for (CollectedObservation& o : *all) {
      if (out.images.count(o.image_key))
        mine->push_back(std::move(o));
      else if (!left_out_keys.count(o.image_key))
        rest.push_back(std::move(o));
    }
    all->swap(rest);
  };
  split(&observations_, &out.observations);
  split(&unidentified_, &out.unidentified);
  std::vector<std::pair<std::string, std::string>> dropped_later;
  for (auto& [key, line] : dropped_) {
    if (later.count(key))
      dropped_later.push_back({key, line});
    else
      out.dropped.push_back(line);
  }
  dropped_.swap(dropped_later);
  const StampNs cutoff = Cutoff();
  std::vector<PositionPrior> later_priors;
  for (PositionPrior& p : priors_)
    (cutoff == 0 || p.stamp <= cutoff ? out.priors : later_priors).push_back(p);
  priors_.swap(later_priors);
  std::map<std::string, TieCount> later_ties;
  for (auto& [key, count] : tie_counts_)
    if (later.count(key)) later_ties[key] = count;
  tie_counts_.swap(later_ties);
  images_.swap(later);
  std::set<std::string> later_targets;
  for (const std::string& key : targets_in_)
    if (images_.count(key)) later_targets.insert(key);
  targets_in_.swap(later_targets);
  for (const auto& [source, end] : ends_) solved_end_[source] = end.stamp;
  ends_.clear();
  cut_short_.clear();
  // End markers of the next epoch that came while this one waited.
  std::vector<EpochEnd> deferred;
  deferred.swap(deferred_ends_);
  for (const EpochEnd& e : deferred) Route(e, now);
  return out;
}

// ------------------------------------------------------------------ scene

void BuildSceneOptions::Check() const {
  auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError(Message("scene option '", key, "' ", what));
  };
  if (!(position_prior_max_dt >= 0.0))
    fail("position_prior_max_dt", Message("must be >= 0, got ", position_prior_max_dt));
  if (!(position_prior_min_sigma > 0.0))
    fail("position_prior_min_sigma", Message("must be > 0, got ", position_prior_min_sigma));
  if (min_images < 1) fail("min_images", Message("must be >= 1, got ", min_images));
  if (!(attitude_prior_max_sigma >= 0.0 && attitude_prior_max_sigma < 3.2))
    fail("attitude_prior_max_sigma",
         Message("must be in [0, 3.2) rad (0..180 deg), got ", attitude_prior_max_sigma));
}

namespace {

// An attitude in the prior that a photo can start from: a unit quaternion,
// every variance in (0, max_sigma^2] (a zero covariance is ROS' "unknown").
bool UsableAttitude(const PositionPrior& prior, double max_sigma) {
  if (!(max_sigma > 0.0) || !prior.site_from_optical.coeffs().allFinite()) return false;
  if (std::abs(prior.site_from_optical.norm() - 1.0) > 1e-3) return false;
  for (int k = 0; k < 3; ++k) {
    const double v = prior.attitude_variance[k];
    if (!(std::isfinite(v) && v > 0.0 && v <= max_sigma * max_sigma)) return false;
  }
  return true;
}

ObjectPoint MakePoint(const CollectedObservation& c, const io::TargetList& targets) {
  ObjectPoint p;
  p.id = c.point_id;
  p.role = c.role;
  p.position_known = false;
  const size_t slash = c.point_id.find('/');
  const io::TargetSpec* spec =
      slash == std::string::npos || c.point_id.compare(0, 4, "tie/") == 0
          ? nullptr
          : targets.Find(c.point_id.substr(0, slash), std::stoi(c.point_id.substr(slash + 1)));
  if (spec == nullptr || !spec->position) return p;
  if (spec->role == io::TargetRole::kControl || spec->role == io::TargetRole::kCheck) {
    p.surveyed = *spec->position;
    p.surveyed_covariance =
        Eigen::Vector3d(spec->sigma(0) * spec->sigma(0), spec->sigma(0) * spec->sigma(0),
                        spec->sigma(1) * spec->sigma(1))
            .asDiagonal();
    // A check point starts at its survey but unknown: it must not help orient the images.
    if (spec->role == io::TargetRole::kCheck) p.position = *spec->position;
  }
  // A monitoring target's listed position is approximate (hand-held GNSS): it
  // may orient a UAV photo, never constrain the adjustment.
  if (spec->role == io::TargetRole::kMonitoring) p.approximate = *spec->position;
  return p;
}

}  // namespace

BuiltScene BuildScene(const CollectedEpoch& epoch,
                      const std::map<std::string, camera::CameraModel>& models,
                      const EpochStore& store, const io::TargetList& targets,
                      const BuildSceneOptions& options) {
  options.Check();
  BuiltScene out;
  Scene& scene = out.scene;
  std::map<std::string, int> camera_index, image_index, point_index;
  for (const auto& [key, im] : epoch.images) {
    auto model = models.find(im.camera);
    if (model == models.end()) {
      if (std::find(out.cameras_without_model.begin(), out.cameras_without_model.end(),
                    im.camera) == out.cameras_without_model.end())
        out.cameras_without_model.push_back(im.camera);
      continue;
    }
    if (!camera_index.count(im.camera)) {
      camera_index[im.camera] = static_cast<int>(scene.cameras.size());
      const camera::CameraModel* calibrated = store.Calibrated(im.camera);
      scene.cameras.push_back({im.camera, calibrated != nullptr ? *calibrated : model->second});
    }
    Image image;
    image.name = key;
    image.camera = camera_index[im.camera];
    image.stamp = StampSeconds(im.stamp);
    const camera::ExteriorOrientation* last = store.LastPose(im.camera);
    image.exterior_known = last != nullptr && !IsUavCamera(im.camera, options.uav_cameras);
    if (image.exterior_known) image.exterior = *last;
    for (const PositionPrior& prior : epoch.priors) {
      if (std::abs(StampSeconds(prior.stamp) - StampSeconds(im.stamp)) >
          options.position_prior_max_dt)
        continue;
      image.position_prior = prior.position;
      Eigen::Matrix3d c = prior.covariance;
      const double floor = options.position_prior_min_sigma * options.position_prior_min_sigma;
      for (int r = 0; r < 3; ++r) c(r, r) = std::max(c(r, r), floor);
      image.position_prior_covariance = c;
      if (UsableAttitude(prior, options.attitude_prior_max_sigma) &&
          IsUavCamera(im.camera, options.uav_cameras)) {
        // The flight log's attitude at the GNSS centre: the start values.
        image.exterior = camera::ExteriorOrientation::FromOpticalFromSite(
            Rigid3(prior.site_from_optical.normalized().toRotationMatrix(), prior.position)
                .Inverse());
        image.exterior_known = true;
        image.attitude_from_prior = true;
      }
    }
    image_index[key] = static_cast<int>(scene.images.size());
    scene.images.push_back(image);
  }
  if (static_cast<int>(scene.images.size()) < options.min_images) {
    throw InvalidArgument(Message("only ", scene.images.size(),
                                  " images with camera_info (min_images = ", options.min_images,
                                  ")",
                                  out.cameras_without_model.empty()
                                      ? ""
                                      : "; no camera_info for " + out.cameras_without_model[0]));
  }
  // In (image, point) order, the unidentified in image order (each image's as
  // its message gave them): the scene, and so the solution to the last bit,
  // does not depend on the order in which the messages arrived (the cameras'
  // targets, or a photo's targets and its tie points, which come from
  // different nodes; the screening adjustment of a UAV block flagged 8 or 761
  // tie observations depending on it).
  auto sorted = [](const std::vector<CollectedObservation>& all, bool by_point) {
    std::vector<const CollectedObservation*> out;
    out.reserve(all.size());
    for (const CollectedObservation& c : all) out.push_back(&c);
    std::stable_sort(out.begin(), out.end(),
                     [by_point](const CollectedObservation* a, const CollectedObservation* b) {
                       if (a->image_key != b->image_key) return a->image_key < b->image_key;
                       return by_point && a->point_id < b->point_id;
                     });
    return out;
  };
  for (const CollectedObservation* in : sorted(epoch.observations, true)) {
    const CollectedObservation& c = *in;
    auto ii = image_index.find(c.image_key);
    if (ii == image_index.end()) continue;
    if (!point_index.count(c.point_id)) {
      point_index[c.point_id] = static_cast<int>(scene.points.size());
      scene.points.push_back(MakePoint(c, targets));
    }
    Observation o;
    o.image = ii->second;
    o.point = point_index[c.point_id];
    o.pixel = c.pixel;
    o.covariance = c.covariance;
    scene.observations.push_back(o);
  }
  for (const CollectedObservation* in : sorted(epoch.unidentified, false)) {
    const CollectedObservation& c = *in;
    auto ii = image_index.find(c.image_key);
    if (ii == image_index.end()) continue;
    out.unidentified.push_back({ii->second, c.family, c.pixel, c.covariance});
  }
  return out;
}

std::vector<ListedTarget> ListedTargets(const io::TargetList& targets) {
  std::vector<ListedTarget> out;
  for (const io::TargetSpec& t : targets.targets()) {
    if (!t.position) continue;
    ListedTarget l;
    l.id = t.Key();
    l.name = t.Label();
    l.family = t.family;
    l.role = RoleOf(&t);
    l.position = *t.position;
    l.position_sigma = std::max({t.sigma(0), t.sigma(1), 1e-3});
    if (t.role != io::TargetRole::kMonitoring) {
      l.surveyed = *t.position;
      l.surveyed_covariance =
          Eigen::Vector3d(t.sigma(0) * t.sigma(0), t.sigma(0) * t.sigma(0), t.sigma(1) * t.sigma(1))
              .asDiagonal();
    }
    out.push_back(l);
  }
  return out;
}

// ------------------------------------------------------------------ store

const camera::CameraModel* EpochStore::Calibrated(const std::string& camera) const {
  auto it = calibrated_.find(camera);
  return it == calibrated_.end() ? nullptr : &it->second;
}

const camera::ExteriorOrientation* EpochStore::LastPose(const std::string& camera) const {
  auto it = last_pose_.find(camera);
  return it == last_pose_.end() ? nullptr : &it->second;
}

EpochPoints EpochStore::Accept(const Scene& scene, const Summary& summary, int epoch, double stamp,
                               bool datum_free) {
  EpochPoints points = EpochPointsFromSolution(scene, summary, epoch, stamp, datum_free);
  for (const Image& im : scene.images) last_pose_[scene.cameras[im.camera].name] = im.exterior;
  for (const Camera& c : scene.cameras) calibrated_[c.name] = c.model;
  epochs_[epoch] = points;
  if (reference_epoch_ < 0) reference_epoch_ = epoch;
  return points;
}

const EpochPoints* EpochStore::Reference() const {
  auto it = epochs_.find(reference_epoch_);
  return it == epochs_.end() ? nullptr : &it->second;
}

std::optional<EpochComparison> EpochStore::CompareWithReference(
    const EpochPoints& current, const DisplacementOptions& options) const {
  const EpochPoints* ref = Reference();
  if (ref == nullptr || ref->epoch == current.epoch) return std::nullopt;
  return CompareEpochs(*ref, current, options);
}

std::string EpochStore::SetReference(bool use_latest, int epoch, int* chosen) {
  if (epochs_.empty()) return "no accepted epoch yet";
  const int wanted = use_latest ? epochs_.rbegin()->first : epoch;
  if (!epochs_.count(wanted))
    return "epoch " + std::to_string(wanted) + " has no accepted solution";
  reference_epoch_ = wanted;
  *chosen = wanted;
  return "";
}

namespace {
constexpr char kStoreKind[] = "epoch_store";
constexpr int kStoreVersion = 1;
}  // namespace

std::string EpochStore::Save() const {
  StateWriter w(kStoreKind, kStoreVersion);
  const EpochPoints* ref = Reference();
  w.Put(ref != nullptr);
  if (ref) {
    w.Put(ref->epoch).Put(ref->stamp).Put(static_cast<int>(ref->points.size()));
    for (const auto& [id, p] : ref->points)
      w.Put(id).Put(static_cast<int>(p.role)).Put(p.position).Put(p.covariance);
  }
  return w.str();
}

void EpochStore::Load(const std::string& text) {
  StateReader r(text, kStoreKind, kStoreVersion);
  EpochStore loaded;
  if (r.Bool()) {
    EpochPoints ref;
    ref.epoch = r.Int();
    ref.stamp = r.Double();
    const int n = r.Int();
    for (int i = 0; i < n; ++i) {
      const std::string id = r.String();
      PointState& p = ref.points[id];
      p.role = static_cast<PointRole>(r.Int());
      r.Get(&p.position);
      r.Get(&p.covariance);
    }
    loaded.epochs_[ref.epoch] = ref;
    loaded.reference_epoch_ = ref.epoch;
  }
  *this = std::move(loaded);
}

}  // namespace adjustment
}  // namespace slope_monitor
