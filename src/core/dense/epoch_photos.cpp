#include "slope_monitor/core/dense/epoch_photos.h"

#include <algorithm>
#include <cstdio>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {

namespace {

double Bytes(const cv::Mat& m) { return static_cast<double>(m.total() * m.elemSize()); }

}  // namespace

void PhotoCollectorOptions::Check() const {
  if (max_photos < 1 || max_photos > 10000)
    throw ConfigError(
        Message("photo collector option 'max_photos' must be in [1, 10000], is ", max_photos));
  if (!(max_megabytes > 0.0 && max_megabytes <= 1e5))
    throw ConfigError(
        Message("photo collector option 'max_megabytes' must be in (0, 1e5], is ", max_megabytes));
  if (!(photo_wait >= 0.0))
    throw ConfigError(
        Message("photo collector option 'photo_wait' must be >= 0 s, is ", photo_wait));
}

std::string PhotoName(const std::string& camera, int64_t stamp_ns) {
  char stamp[40];
  std::snprintf(stamp, sizeof stamp, "%.3f", stamp_ns * 1e-9);
  return camera + "@" + stamp;
}

EpochImage OrientPhoto(const Photo& photo, const camera::CameraModel& nominal,
                       const PhotoOrientation& o, ImageKind kind) {
  std::array<double, camera::kNumInterior> interior = nominal.interior();
  if (o.distortion.size() > camera::kNumInterior - 3)
    throw InvalidArgument(Message(PhotoName(o.camera, o.stamp_ns), ": ", o.distortion.size(),
                                  " distortion terms in the solution, at most ",
                                  camera::kNumInterior - 3));
  interior[camera::kC] = o.principal_distance;
  interior[camera::kX0] = o.x0;
  interior[camera::kY0] = o.y0;
  for (size_t i = 0; i < o.distortion.size(); ++i) interior[camera::kK1 + i] = o.distortion[i];
  EpochImage out;
  out.kind = kind;
  out.camera = o.camera;
  out.image.name = PhotoName(o.camera, o.stamp_ns);
  out.image.image = photo.image;
  // The solution's terms decide the model when it holds more than the
  // nominal one (a UAV camera from EXIF is "none" until self-calibrated).
  camera::DistortionModel model = nominal.model();
  for (size_t i = 0; i < o.distortion.size(); ++i) {
    if (o.distortion[i] == 0.0) continue;
    const camera::DistortionModel needed = i < 3   ? camera::DistortionModel::kRadial
                                           : i < 5 ? camera::DistortionModel::kBrown
                                                   : camera::DistortionModel::kBrownAffinity;
    if (static_cast<int>(needed) > static_cast<int>(model)) model = needed;
  }
  out.image.camera = camera::CameraModel(nominal.sensor(), model, interior);
  out.image.pose = o.pose;
  out.image.oriented = true;
  return out;
}

EpochPhotoCollector::EpochPhotoCollector(const PhotoCollectorOptions& options) : options_(options) {
  options_.Check();
  surface_cameras_.insert(options_.uav_cameras.begin(), options_.uav_cameras.end());
  for (const auto& [left, right] : options_.stereo_pairs) {
    surface_cameras_.insert(left);
    surface_cameras_.insert(right);
  }
}

bool EpochPhotoCollector::Uses(const std::string& camera) const {
  return surface_cameras_.count(camera) > 0;
}

void EpochPhotoCollector::SetCamera(const std::string& camera, const camera::CameraModel& model) {
  models_[camera] = model;
}

std::vector<PhotoEpoch> EpochPhotoCollector::AddPhoto(Photo photo, double /*now*/) {
  if (!Uses(photo.camera)) return {};
  int64_t& latest = latest_[photo.camera];
  latest = std::max(latest, photo.stamp_ns);
  auto& held = photos_[photo.camera];
  const auto it = held.find(photo.stamp_ns);
  if (it != held.end()) {  // the same photo again: the newer copy replaces it
    held_bytes_ -= Bytes(it->second.image);
    --held_count_;
    held.erase(it);
  }
  held_bytes_ += Bytes(photo.image);
  ++held_count_;
  held.emplace(photo.stamp_ns, std::move(photo));
  Enforce();  // a drop may also give up a photo a waiting solution names
  return TakeComplete();
}

std::vector<PhotoEpoch> EpochPhotoCollector::AddSolution(EpochOrientations solution, double now) {
  // Only the photos of surface cameras are waited for.
  auto& photos = solution.photos;
  photos.erase(std::remove_if(photos.begin(), photos.end(),
                              [this](const PhotoOrientation& o) { return !Uses(o.camera); }),
               photos.end());
  waiting_.push_back({std::move(solution), now});
  return TakeComplete();
}

std::vector<PhotoEpoch> EpochPhotoCollector::Poll(double now) {
  std::vector<PhotoEpoch> done = TakeComplete();
  // In arrival order: an epoch is never measured before an earlier one.
  while (!waiting_.empty() && now - waiting_.front().received >= options_.photo_wait) {
    char reason[64];
    std::snprintf(reason, sizeof reason, "time-out after %g s", options_.photo_wait);
    done.push_back(Build(waiting_.front(), reason));
    waiting_.erase(waiting_.begin());
  }
  return done;
}

std::vector<PhotoEpoch> EpochPhotoCollector::Finish() {
  std::vector<PhotoEpoch> done = TakeComplete();
  for (const Waiting& w : waiting_) done.push_back(Build(w, "end of input"));
  waiting_.clear();
  return done;
}

std::vector<std::string> EpochPhotoCollector::TakeDropped() {
  std::vector<std::string> out;
  out.swap(dropped_lines_);
  return out;
}

std::string EpochPhotoCollector::GivenUp(const PhotoOrientation& o) const {
  const auto d = dropped_.find(o.camera);
  if (d != dropped_.end() && d->second.count(o.stamp_ns)) return "dropped at the memory limit";
  const auto l = latest_.find(o.camera);
  if (l != latest_.end() && l->second > o.stamp_ns)
    return "not received (a later photo of '" + o.camera + "' came)";
  return "";
}

bool EpochPhotoCollector::Complete(const Waiting& w) const {
  for (const PhotoOrientation& o : w.solution.photos) {
    const auto held = photos_.find(o.camera);
    if (held != photos_.end() && held->second.count(o.stamp_ns)) continue;
    if (GivenUp(o).empty()) return false;
  }
  return true;
}

std::vector<PhotoEpoch> EpochPhotoCollector::TakeComplete() {
  std::vector<PhotoEpoch> done;
  // In arrival order (the reference epoch first).
  while (!waiting_.empty() && Complete(waiting_.front())) {
    done.push_back(Build(waiting_.front(), "all photos"));
    waiting_.erase(waiting_.begin());
  }
  return done;
}

PhotoEpoch EpochPhotoCollector::Build(const Waiting& w, const std::string& reason) {
  const EpochOrientations& s = w.solution;
  PhotoEpoch out;
  out.stamp_ns = s.stamp_ns;
  out.reason = reason;
  out.input.epoch = s.epoch;
  out.input.stereo_pairs = options_.stereo_pairs;
  out.input.adjusted_points = s.adjusted_points;
  std::map<std::string, int64_t> newest_used;
  for (const PhotoOrientation& o : s.photos) {
    const std::string name = PhotoName(o.camera, o.stamp_ns);
    auto& held = photos_[o.camera];
    const auto photo = held.find(o.stamp_ns);
    if (photo == held.end()) {
      const std::string why = GivenUp(o);
      out.missing.push_back(name + ": " + (why.empty() ? "not received (" + reason + ")" : why));
      continue;
    }
    const auto model = models_.find(o.camera);
    const bool uav = std::find(options_.uav_cameras.begin(), options_.uav_cameras.end(),
                               o.camera) != options_.uav_cameras.end();
    if (model == models_.end()) {
      out.missing.push_back(name + ": no camera_info of '" + o.camera + "' received");
    } else {
      try {
        out.input.images.push_back(OrientPhoto(photo->second, model->second, o,
                                               uav ? ImageKind::kUav : ImageKind::kFixed));
      } catch (const Error& e) {
        out.missing.push_back(e.what());
      }
    }
    int64_t& newest = newest_used[o.camera];
    newest = std::max(newest, o.stamp_ns);
  }
  // Release the photos used and every older photo of their cameras.
  for (const auto& [camera, newest] : newest_used) {
    auto& held = photos_[camera];
    for (auto it = held.begin(); it != held.end() && it->first <= newest;) {
      held_bytes_ -= Bytes(it->second.image);
      --held_count_;
      it = held.erase(it);
    }
    auto& dropped = dropped_[camera];
    dropped.erase(dropped.begin(), dropped.upper_bound(newest));
  }
  const auto uav_images =
      std::count_if(out.input.images.begin(), out.input.images.end(),
                    [](const EpochImage& i) { return i.kind == ImageKind::kUav; });
  if (uav_images < 2 && options_.stereo_pairs.empty())
    out.no_surface = Message("epoch ", s.epoch, ": no surface (", uav_images,
                             " UAV photo(s), no stereo pair configured)");
  return out;
}

void EpochPhotoCollector::Enforce() {
  while (static_cast<int>(held_count_) > options_.max_photos ||
         held_bytes_ > options_.max_megabytes * 1e6) {
    std::set<std::pair<std::string, int64_t>> named;
    for (const Waiting& w : waiting_)
      for (const PhotoOrientation& o : w.solution.photos) named.insert({o.camera, o.stamp_ns});
    // The oldest photo no waiting solution names; else the oldest.
    const Photo* victim = nullptr;
    bool victim_named = true;
    for (const auto& [camera, held] : photos_)
      for (const auto& [stamp, photo] : held) {
        const bool is_named = named.count({camera, stamp}) > 0;
        if (!victim || (victim_named && !is_named) ||
            (victim_named == is_named && stamp < victim->stamp_ns)) {
          victim = &photo;
          victim_named = is_named;
        }
      }
    char line[256];
    std::snprintf(line, sizeof line,
                  "dropped photo %s (%.1f MB%s): %zu photos / %.1f MB held, limits max_photos %d, "
                  "max_megabytes %g",
                  PhotoName(victim->camera, victim->stamp_ns).c_str(), Bytes(victim->image) / 1e6,
                  victim_named ? ", named by a waiting solution" : "", held_count_,
                  held_bytes_ / 1e6, options_.max_photos, options_.max_megabytes);
    dropped_lines_.push_back(line);
    dropped_[victim->camera].insert(victim->stamp_ns);
    held_bytes_ -= Bytes(victim->image);
    --held_count_;
    const std::string camera = victim->camera;
    const int64_t stamp = victim->stamp_ns;
    photos_[camera].erase(stamp);
  }
}

}  // namespace dense
}  // namespace slope_monitor
