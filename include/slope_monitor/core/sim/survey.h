// A whole simulated survey: the site configuration (config/sim/*.yaml), the
// scene, the camera flights / fixed cameras across the epochs, the radio
// network, and the ground truth.
//
//   sim::SurveyConfig config = sim::SurveyConfig::Load("config/sim/demo_site.yaml");  //
//   ConfigError names the key sim::SurveyGenerator gen(config);          // checks cameras see the
//   slope and control points sim::Survey survey = gen.Generate();       // images, truth, target
//   list, surfaces sim::WriteSurveyFiles(survey, "demo");     // demo.truth.yaml,
//   demo.targets.yaml, demo.surface_eNN.tif, demo.site.yaml
//
// The ROS side (src/ros/sim_bag_writer.cpp) turns a Survey into a bag.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/core/sim/radio_sim.h"
#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/scene.h"
#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace sim {

struct StripSpec {
  Eigen::Vector2d start{0, 0};     // [m] site x, y of the first exposure
  Eigen::Vector2d end{0, 0};       // [m] of the last
  double altitude = 60.0;          // [m] above the ground at the strip's midpoint
  double overlap = 0.7;            // [-] forward overlap of consecutive images
  double tilt = 0.0;               // [rad] off-nadir tilt (0: nadir)
  double tilt_azimuth = M_PI / 2;  // [rad] horizontal direction the tilted camera looks to
};

struct CameraSpec {
  std::string name;            // the camera namespace in the bag (config: cameras[].name)
  std::string kind = "fixed";  // fixed | fixed_targetless (no control point needed in view) | uav
  std::string encoding = "mono8";  // mono8 | bgr8
  std::string key;                 // config path for messages ("cameras[0]")
  camera::CameraModel model;       // true
  camera::CameraModel nominal;     // camera_info
  ExposureOptions exposure;
  double exposure_jitter = 0.03;         // [-] relative sigma of the per-image exposure
  std::map<int, double> exposure_jumps;  // epoch -> exposure factor from that epoch on
  // fixed
  camera::ExteriorOrientation pose;  // nominal installed pose
  double jitter_position = 0.002;    // [m] sigma per epoch
  double jitter_angle = 2e-4;        // [rad] sigma per epoch
  // The mast turns between consecutive epochs by a random angle, uniform in
  // [min, max], about a random axis (replaces jitter_angle after the
  // reference epoch); max 0: off.
  double mast_rotation_min = 0.0, mast_rotation_max = 0.0;  // [rad]
  // Surveyed stable-ground points in the truth (the crew's GNSS points picked
  // in the reference photo): how many, and the picking noise.
  int surveyed_points = 0;
  double picked_pixel_sigma = 0.5;  // [px]
  // uav
  std::vector<StripSpec> strips;
  double image_interval = 2.0;             // [s]
  double start_offset = 300.0;             // [s] after the epoch start
  Eigen::Vector2d gnss_sigma{0.03, 0.05};  // [m] horizontal, vertical
  double attitude_sigma = 0.01;            // [rad] deviation of the true attitude from the plan
  double track_sigma = 0.3;                // [m] deviation of the true position from the plan
  // The flight log's attitude written with each photo's position_prior: the
  // true attitude rotated by this sigma about each axis; 0 = the log has no
  // attitude (the prior's orientation variance is 1e6).
  double imu_sigma = 0.0;  // [rad]
  // A real flight (all 0 = the ideal plan): the heading off the track into a
  // constant cross wind (its sign flips on strips flown the other way), the
  // height wandering within +-altitude_variation of the strip's altitude
  // (barometer, terrain follow), and photos taken in the turns between strips
  // (on a half circle, banked kTurnBankDeg toward its centre).
  double crab = 0.0;                // [rad]
  double altitude_variation = 0.0;  // [-] of the strip altitude
  int turn_images = 0;              // per turn
  static constexpr double kTurnBankDeg = 15.0;
};

struct RadioNetworkSpec {
  bool enabled = false;
  RadioSimConfig
      sim;  // receivers / transmitters positions are filled in (transmitter position functions too)
  std::vector<Eigen::Vector2d> receiver_xy;
  std::vector<double> receiver_mast;  // [m] antenna above ground
  std::vector<Eigen::Vector2d> transmitter_xy;
  std::vector<double> transmitter_mast;
  double tail = 3600.0;  // [s] radio keeps recording after the last epoch
};

struct SurveyConfig {
  std::string path;  // the file it was loaded from
  // The simulated site's name (site.name; default: the config file's name
  // without .yaml): its history is ~/.ros/slope_monitor/<name>.db.
  std::string name;
  unsigned int seed = 7;
  Eigen::Vector3d origin{46.5, 8.0, 1200.0};  // [deg, deg, m]
  SceneSpec scene;
  int num_epochs = 4;
  double start_time = 1700000000.0;          // [s]
  double epoch_interval = 21600.0;           // [s]
  Eigen::Vector2d survey_sigma{0.03, 0.01};  // [m] horizontal, vertical
  // Monitoring targets: the approximate position a crew notes when placing
  // them (hand-held GNSS), written to the target list with this std so the
  // centroider can identify circles; 0 = monitoring targets have no position.
  double monitoring_approx_sigma = 0.0;            // [m]
  std::vector<std::string> target_keys_for_error;  // "targets.list[i]" per target
  std::vector<CameraSpec> cameras;
  RadioNetworkSpec radio;
  RenderOptions render;
  double surface_cell = 0.5;  // [m] GeoTIFF cell (resampled from the mesh)

  // Throws ConfigError naming the file and key (unknown key, bad value, ...).
  static SurveyConfig Load(const std::string& path);
  static SurveyConfig Parse(const std::string& yaml_text, const std::string& context);
};

struct SurveyImage {
  int camera = 0;  // index into config.cameras / truth.cameras
  int image = 0;   // index into truth.cameras[camera].images
  int epoch = 0;
  double stamp = 0.0;  // [s]
  cv::Mat pixels;      // CV_8UC1 (mono8) or CV_8UC3 (bgr8)
};

struct Survey {
  SurveyConfig config;
  SurveyTruth truth;
  io::TargetList target_list;
  std::vector<SurveyImage> images;         // in stamp order
  std::vector<io::GeoRaster> surfaces;     // per epoch
  std::shared_ptr<RadioSimulator> radio;   // null when the site has no radio
  std::vector<double> radio_block_starts;  // [s] start of every radio block (all receivers)
};

// A camera pose looking from `position` at `look_at` with the image's up
// direction as close as possible to `up_hint` (site), then rolled by `roll`.
camera::ExteriorOrientation LookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& look_at,
                                   const Eigen::Vector3d& up_hint, double roll = 0.0);

// Whether a camera images the point `x` (site): in front, inside the image
// by `margin_px`, and not folded back into it by the lens distortion (the
// radial polynomial of a far-off-axis point turns over: the ideal image
// coordinates must lie near the image too). *pixel: where.
bool ImagedAt(const camera::CameraModel& model, const camera::ExteriorOrientation& pose,
              const Eigen::Vector3d& x, double margin_px, Eigen::Vector2d* pixel);

// The attitude a UAV's flight log records for a photo: the true optical
// frame in site (pose.SiteFromOptical()) turned by a small rotation whose
// components about site x, y, z are N(0, sigma) [rad]. Deterministic: drawn
// from its own generator seeded by (seed, camera, image), so the survey's
// other random draws do not change with it.
Eigen::Quaterniond FlightLogAttitude(const camera::ExteriorOrientation& pose, double sigma,
                                     unsigned int seed, int camera, int image);

// Plates fully visible in an image: every outline point (and the centre)
// inside the image by `margin_px`, in front, the plate facing the camera, and
// no ground (up to `tolerance` before the point) or obstacle on the way.
std::vector<int> VisiblePlates(const Scene::State& state, const camera::CameraModel& model,
                               const camera::ExteriorOrientation& pose, double margin_px = 2.0,
                               double tolerance = 0.3);

class SurveyGenerator {
 public:
  // Builds the scene and checks the configuration; throws ConfigError naming
  // the key (camera looking away from the slope, no control point in view of
  // a camera, control point on the moving body, receiver on the body, ...).
  explicit SurveyGenerator(const SurveyConfig& config);

  // Renders everything. progress(i, n) is called after each image.
  Survey Generate(const std::function<void(int, int)>& progress = nullptr) const;

  const Scene& scene() const { return *scene_; }
  // The truth without images (poses, targets, epochs, radio); Generate() fills visibility.
  const SurveyTruth& planned_truth() const { return truth_; }

 private:
  SurveyConfig config_;
  std::unique_ptr<Scene> scene_;
  SurveyTruth truth_;
  std::shared_ptr<RadioSimulator> radio_;
};

// Writes <stem>.truth.yaml, <stem>.targets.yaml and <stem>.surface_eNN.tif;
// fills survey->truth.surfaces with the file names. Throws IoError.
void WriteSurveyFiles(Survey* survey, const std::string& stem);  // also <stem>.site.yaml

// Radio transmitters standing within max_distance [m] (horizontally) of a
// monitoring target: (transmitter id, target key) pairs, nearest target each.
std::vector<std::pair<std::string, std::string>> ColocatedPoints(const SurveyTruth& truth,
                                                                 double max_distance);
// The deformation_estimator overlay of a simulated site: geodetic_origin and
// aliases "tx1 = tag36h11/10" for co-located transmitters and targets.
void WriteSiteOverlay(const SurveyTruth& truth, const std::string& path);

}  // namespace sim
}  // namespace slope_monitor
