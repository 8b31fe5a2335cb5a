// The photos of a dense epoch, collected by message, with no ROS in it: the
// dense_epoch nodelet and process_bag feed the same EpochPhotoCollector.
//
//   dense::EpochPhotoCollector photos(options);
//   photos.SetCamera("uav", model);                     // from camera_info
//   photos.AddPhoto({"uav", stamp_ns, image}, now);     // every photo, as it comes
//   for (dense::PhotoEpoch& e : photos.AddSolution(orientations, now)) Measure(e.input);
//   ... photos.Poll(now) (live time-out), photos.Finish() (end of input)
//
// Completion is decided by the messages: an adjustment solution names the
// photos it oriented (camera + stamp); its epoch is ready when every named
// photo of a camera the surface uses (uav_cameras, the cameras of
// stereo_pairs) has come, in whichever order the solution and its photos
// arrive. A named photo that will not come is given up on without waiting
// when the camera has already delivered a later photo (a camera's photos
// arrive in order) or when it was dropped at the memory limit. Poll(now) is
// the only place time counts: a solution still waiting photo_wait seconds
// (the caller's clock) after it came is measured with the photos it has.
// Every photo given up on is named in PhotoEpoch::missing.
//
// Memory: a photo is held until the solution that uses it is complete and
// released then; photos of a camera that are older than a photo a solution
// used are released too (a later epoch never orients them). When more than
// max_photos photos or max_megabytes of pixels are held, the oldest photo
// that no waiting solution names is dropped first (then the oldest), and the
// drop is named (TakeDropped).
#pragma once

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/dense/epoch_surface.h"
#include "slope_monitor/core/io/site_file.h"

namespace slope_monitor {
namespace dense {

// A photo as it arrived (image_raw).
struct Photo {
  std::string camera;
  int64_t stamp_ns = 0;  // header stamp [ns]
  cv::Mat image;         // BGR (colours the cloud) or grey
};

// What the adjustment solved for one photo (CameraEstimate).
struct PhotoOrientation {
  std::string camera;
  int64_t stamp_ns = 0;
  double principal_distance = 0.0, x0 = 0.0, y0 = 0.0;  // [mm]
  std::vector<double> distortion;  // model terms after c, x0, y0 (as camera::CameraModel)
  camera::ExteriorOrientation pose;
};

// One usable adjustment solution.
struct EpochOrientations {
  int epoch = 0;
  int64_t stamp_ns = 0;  // the solution's stamp (the outputs carry it)
  std::vector<PhotoOrientation> photos;
  std::vector<Eigen::Vector3d> adjusted_points;  // [m] site
};

struct PhotoCollectorOptions {
  // Paired by overlap: kind uav (site file, or io::DefaultCameras()).
  std::vector<std::string> uav_cameras =
      io::CameraNames(io::DefaultCameras(), io::CameraKind::kUav);
  std::vector<std::pair<std::string, std::string>> stereo_pairs;  // fixed cameras (left, right)
  int max_photos = 64;            // [-] photos held, all cameras; [1, 10000]
  double max_megabytes = 1024.0;  // [MB] pixels held; (0, 1e5]
  double photo_wait = 60.0;       // [s] live: a solution waits this long for its photos; >= 0
  void Check() const;             // throws ConfigError naming the field
};

// An epoch ready to measure.
struct PhotoEpoch {
  int64_t stamp_ns = 0;  // the solution's
  EpochSurfaceInput input;
  // Named photos given up on: "uav@1700000012.000: not received (a later photo of 'uav' came)".
  std::vector<std::string> missing;
  std::string reason;      // "all photos", "time-out after 60 s", "end of input"
  std::string no_surface;  // non-empty: nothing to measure (fewer than two UAV photos, no stereo)
};

// "uav@1700000012.000" (the photo's name in messages and pair errors).
std::string PhotoName(const std::string& camera, int64_t stamp_ns);

// The photo with the adjusted interior and exterior orientation. Throws
// InvalidArgument naming the photo when the distortion terms do not fit the model.
EpochImage OrientPhoto(const Photo& photo, const camera::CameraModel& nominal,
                       const PhotoOrientation& orientation, ImageKind kind);

class EpochPhotoCollector {
 public:
  explicit EpochPhotoCollector(const PhotoCollectorOptions& options);  // ConfigError

  // The camera's model from its camera_info (sensor, distortion model).
  void SetCamera(const std::string& camera, const camera::CameraModel& model);
  // Each input returns the epochs it completed. `now` [s]: the caller's clock.
  std::vector<PhotoEpoch> AddPhoto(Photo photo, double now);
  std::vector<PhotoEpoch> AddSolution(EpochOrientations solution, double now);
  std::vector<PhotoEpoch> Poll(double now);
  // End of input: every waiting solution with the photos it has.
  std::vector<PhotoEpoch> Finish();

  // Photos dropped at the memory limit since the last call, one line each.
  std::vector<std::string> TakeDropped();
  bool Uses(const std::string& camera) const;  // a surface camera: its photos are kept
  int photos_held() const { return static_cast<int>(held_count_); }
  double megabytes_held() const { return held_bytes_ / 1e6; }
  int solutions_waiting() const { return static_cast<int>(waiting_.size()); }

 private:
  struct Waiting {
    EpochOrientations solution;
    double received = 0.0;
  };
  bool Complete(const Waiting& w) const;
  PhotoEpoch Build(const Waiting& w, const std::string& reason);
  std::vector<PhotoEpoch> TakeComplete();
  void Enforce();
  // Why a named photo that is not held will not come ("" = it may still come).
  std::string GivenUp(const PhotoOrientation& o) const;

  PhotoCollectorOptions options_;
  std::set<std::string> surface_cameras_;
  std::map<std::string, camera::CameraModel> models_;
  std::map<std::string, std::map<int64_t, Photo>> photos_;  // camera -> stamp -> photo
  std::map<std::string, int64_t> latest_;                   // latest stamp seen per camera
  std::map<std::string, std::set<int64_t>> dropped_;        // dropped at the limit
  std::vector<Waiting> waiting_;                            // in arrival order
  std::vector<std::string> dropped_lines_;
  size_t held_count_ = 0;
  double held_bytes_ = 0.0;
};

}  // namespace dense
}  // namespace slope_monitor
