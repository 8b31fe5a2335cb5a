// Ground truth of a simulated slope survey (doc/simulator.md, "Truth schema").
//
// Everything the simulator knows and a crew would not: true camera models and
// poses per image, every target's true centre per epoch, the analytic
// displacement field of the landslide body, the occluding / low-texture parts
// where matching must fail, the radio network and its integer ambiguities,
// and the names of the true surface GeoTIFFs.
//
//   sim::SurveyTruth truth = sim::SurveyTruth::Load("demo.truth.yaml");
//   Eigen::Vector3d d = truth.DisplacementAt(x_ref_in_site, stamp);   // [m]
//   const sim::TargetTruth* t = truth.FindTarget("tag36h11/3");
//   Eigen::Vector3d x = t->positions[2];                               // epoch 2
//
// Conventions: site frame (x east, y north, z up) metres; times are bag
// stamps in seconds; angles radians; camera parameters in camera_model.h units.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace sim {

// ---------------------------------------------------------------------------
// The landslide body and its displacement field.
//
// The body is an ellipse in the horizontal (x, y) plane: centre, semi-axis
// `length` along the slope direction (azimuth of motion) and `width` across
// it. With u the horizontal coordinate along the motion azimuth and v across,
// rho = sqrt((u/length)^2 + (v/width)^2). The weight
//   w(rho) = 1                                  for rho <= 1 - taper
//          = smoothstep from 1 down to 0        for 1 - taper < rho < 1
//          = 0                                  for rho >= 1
// (smoothstep s = 3q^2 - 2q^3 with q = (1 - rho) / taper) gives the
// fraction of the body's motion a point takes part in.
//
// A point whose reference-epoch position is X moves by
//   d(X, t) = w(rho(X)) * s(t) * direction
// where direction is a unit vector (azimuth from +x counter-clockwise,
// plunge below the horizontal) and s(t) the travelled distance:
//   constant:      s(t) = v0 * (t - t0)
//   accelerating:  s(t) = v0 * (tf - t0) * ln((tf - t0) / (tf - t))   (t < tf)
// The accelerating law has velocity v(t) = v0 (tf - t0) / (tf - t), so the
// inverse velocity 1/v falls linearly to zero at the failure time tf
// (Fukuzono's alpha = 2): an inverse-velocity forecast must find tf.
// t0 is the reference epoch's stamp; s(t) = 0 for t <= t0.
// ---------------------------------------------------------------------------
struct LandslideModel {
  enum class Velocity { kConstant, kAccelerating };

  Eigen::Vector2d centre{100.0, 75.0};  // [m] site x, y of the ellipse centre
  double length = 40.0;                 // [m] semi-axis along the motion azimuth
  double width = 25.0;                  // [m] semi-axis across it
  double taper = 0.25;                  // [-] boundary zone as a fraction of rho, (0, 1]
  double azimuth = -M_PI / 2.0;  // [rad] motion azimuth from +x counter-clockwise (-pi/2: south)
  double plunge = 0.35;          // [rad] motion direction below the horizontal
  Velocity velocity = Velocity::kConstant;
  double velocity0 = 0.0;       // [m/s] v0 at t0
  double reference_time = 0.0;  // [s] t0 (stamp of the reference epoch)
  double failure_time = 0.0;    // [s] tf (accelerating only; > t0)

  Eigen::Vector3d Direction() const;                       // unit motion vector in site
  double Weight(const Eigen::Vector2d& xy_in_site) const;  // w in [0, 1]
  double Travel(double t) const;                           // s(t) [m]
  double VelocityAt(double t) const;                       // ds/dt [m/s]
  // d(X, t) for a point whose reference position is x_ref_in_site [m].
  Eigen::Vector3d DisplacementAt(const Eigen::Vector3d& x_ref_in_site, double t) const;
  // The reference position X of the material point that is at x_now at time t
  // (inverse of X -> X + d(X, t) in the horizontal plane, by fixed-point
  // iteration; exact to 1e-9 m for the smooth fields above). Only x, y of
  // x_now are used; the returned z is x_now.z - d_z.
  Eigen::Vector3d ReferencePositionOf(const Eigen::Vector3d& x_now_in_site, double t) const;
  // The same inverse for many points at one instant (the renderer: one per
  // ray): the travel, direction and azimuth terms computed once; the same
  // numbers as ReferencePositionOf, bit for bit.
  class InverseAt {
   public:
    InverseAt(const LandslideModel& model, double t);
    Eigen::Vector3d operator()(const Eigen::Vector3d& x_now_in_site) const;
    bool moved() const { return travel_ != 0.0; }

   private:
    double Weight(const Eigen::Vector2d& xy) const;
    const LandslideModel& model_;
    double travel_, cos_azimuth_, sin_azimuth_;
    Eigen::Vector3d direction_;
  };
  static std::string VelocityName(Velocity v);
  static Velocity VelocityFromName(const std::string& name);  // throws InvalidArgument
};

// A tree or boulder standing on the ground: occludes what is behind it, and
// matching on it fails (it moves with the wind / is not part of the surface).
// Trees: a vertical cylinder trunk topped by a cone crown; boulders: a sphere.
struct Obstacle {
  enum class Kind { kTree, kBoulder };
  Kind kind = Kind::kBoulder;
  Eigen::Vector3d base{0, 0, 0};  // [m] ground point under its centre (reference epoch)
  double radius = 1.0;            // [m] boulder sphere / tree crown radius
  double height = 1.0;  // [m] boulder: sphere centre height above base; tree: total height
  bool moves = false;   // true when it stands on the landslide body and moves with it
  // Tree crowns in the wind (SceneSpec::foliage_motion; Scene::AtTime fills
  // both, zero otherwise): the crown's horizontal displacement at the
  // instant [m] (moves its silhouette), and the foliage phase (0 = the static
  // foliage texture, else a leaf pattern that is new at every stamp).
  Eigen::Vector3d crown_offset{0, 0, 0};
  std::uint32_t foliage_phase = 0;
  static std::string KindName(Kind k);
  static Kind KindFromName(const std::string& name);
};

// The head scarp: a steep, low-texture step where the body has dropped.
// With u, v, rho of the landslide ellipse (u along the motion, i.e.
// downslope, so the head is at u = -length), inside the ellipse the
// reference surface is lowered by
//   depth * clamp((1 - rho) / band, 0, 1) * clamp((1 - u / length) / 2, 0, 1)^2
// so the drop is largest at the head and vanishes at the toe. Points with
// rho in [1 - band, 1] and -u / length > head_fraction are the scarp
// (unmatchable: steep, low texture).
struct Scarp {
  double depth = 3.0;          // [m]
  double band = 0.05;          // [-] width of the step as a fraction of rho
  double head_fraction = 0.0;  // [-] scarp where u / length exceeds this
};

struct EpochTruth {
  int index = 0;
  double stamp = 0.0;  // [s] bag time of the epoch start
};

struct ImageTruth {
  int epoch = 0;
  double stamp = 0.0;                    // [s] exposure time (image header stamp)
  camera::ExteriorOrientation exterior;  // true pose
  std::vector<std::string> visible;      // target keys fully in the image and not occluded
  std::optional<Eigen::Vector3d> gnss;   // [m] site: the noisy position the UAV recorded (uav only)
  double exposure = 1.0;                 // [-] exposure gain applied to this image
};

// A point of stable ground surveyed by the crew and picked by hand in a fixed
// camera's reference photo (resect_camera's input).
struct SurveyedPointTruth {
  std::string id;            // "s1", "s2", ...
  Eigen::Vector3d position;  // [m] true, site
  Eigen::Vector3d surveyed;  // [m] with the survey noise (targets.survey_sigma)
  Eigen::Vector2d picked;    // [px] true projection in the reference image + picking noise
};

struct CameraTruth {
  std::string name;                // the camera namespace in the bag (config: cameras[].name)
  std::string kind = "fixed";      // fixed | fixed_targetless | uav
  std::string encoding = "mono8";  // mono8 | bgr8
  camera::CameraModel model;       // true interior + distortion
  camera::CameraModel nominal;     // what camera_info says
  std::optional<camera::ExteriorOrientation>
      nominal_pose;  // fixed cameras: installed pose (tf_static)
  std::vector<ImageTruth> images;
  std::vector<SurveyedPointTruth> surveyed_points;  // fixed cameras: in the reference image
};

struct TargetTruth {
  std::string key;  // "tag36h11/3", "circle/12"
  int id = 0;
  std::string family = "tag36h11";  // tag36h11 | circle
  double size = 0.0;                // [m] tag: black border edge; circle: bright disc diameter
  io::TargetRole role = io::TargetRole::kControl;
  Eigen::Vector3d normal{0, 0, 1};         // unit plate normal in site (constant: plates translate)
  Eigen::Vector3d up_in_plate{0, 1, 0};    // unit in-plane direction of the tag's "up" (top row)
  std::vector<Eigen::Vector3d> positions;  // [m] true centre per epoch (index = epoch)
  std::optional<Eigen::Vector3d> surveyed;   // [m] noisy surveyed coordinates (control / check)
  Eigen::Vector2d survey_sigma{0.03, 0.01};  // [m] horizontal, vertical
};

struct RadioReceiverTruth {
  std::string id;                     // "rx1"
  Eigen::Vector3d position{0, 0, 0};  // [m] antenna phase centre in site (stable)
  double xi = 0.0;                    // [rad] channel delay xi_j
};

struct RadioTransmitterTruth {
  std::string id;                          // "tx1"
  double frequency = 0.0;                  // [Hz] carrier (each transmitter its own offset)
  double psi = 0.0;                        // [rad] phase offset psi_i
  std::vector<Eigen::Vector3d> positions;  // [m] true antenna position per epoch
};

// phi_ij = (2 pi / lambda) |x_i - X_j| + psi_i + xi_j + 2 pi N_ij  (doc/design.md).
// ambiguities[i][j] is N_ij of transmitter i and receiver j at the reference
// epoch, defined so that phi_ij (wrapped to (-pi, pi]) is exactly the sum.
struct RadioTruth {
  double wavelength = 0.125;        // [m]
  double center_frequency = 2.4e9;  // [Hz]
  std::vector<RadioReceiverTruth> receivers;
  std::vector<RadioTransmitterTruth> transmitters;
  std::vector<std::vector<int>> ambiguities;  // [transmitter][receiver]
  // Free-form description of injected faults ("blocked tx2->rx1 from t0 for 30 s").
  std::vector<std::string> faults;
  bool Empty() const { return receivers.empty() && transmitters.empty(); }
};

struct SurfaceTruth {
  int epoch = 0;
  std::string geotiff;  // file name, relative to the truth file's directory
};

struct SurveyTruth {
  std::string format = "slope_monitor_sim_truth/1";
  unsigned int seed = 0;
  std::string config;                      // path of the site config it was made from
  std::string site_name;                   // the simulated site's name ("" in older files)
  Eigen::Vector3d origin{0, 0, 0};         // [deg, deg, m] geodetic origin of site
  Eigen::Vector4d extent{0, 200, 0, 150};  // [m] xmin, xmax, ymin, ymax
  std::vector<EpochTruth> epochs;
  std::vector<CameraTruth> cameras;
  std::vector<TargetTruth> targets;
  LandslideModel landslide;
  Scarp scarp;
  std::vector<Obstacle> obstacles;
  RadioTruth radio;
  std::vector<SurfaceTruth> surfaces;

  // Throws IoError naming the file (and the key) when it cannot be read.
  static SurveyTruth Load(const std::string& path);
  static SurveyTruth FromYaml(const std::string& text, const std::string& context);
  void Save(const std::string& path) const;
  std::string ToYaml() const;

  // True displacement at time t of the ground point whose reference-epoch
  // position is x_ref_in_site [m] (zero off the body).
  Eigen::Vector3d DisplacementAt(const Eigen::Vector3d& x_ref_in_site, double t) const {
    return landslide.DisplacementAt(x_ref_in_site, t);
  }
  // True where area-based matching must fail: on (or within the radius of) a
  // tree or boulder, and on the head scarp. x_in_site is a reference-epoch
  // position; only x, y are used.
  bool Unmatchable(const Eigen::Vector3d& x_in_site) const;

  const TargetTruth* FindTarget(const std::string& key) const;
  const CameraTruth* FindCamera(const std::string& name) const;
  // Stamp of epoch k; throws InvalidArgument when k is out of range.
  double EpochStamp(int k) const;
  // Target positions of epoch k by key.
  std::map<std::string, Eigen::Vector3d> TargetPositions(int epoch) const;
};

}  // namespace sim
}  // namespace slope_monitor
