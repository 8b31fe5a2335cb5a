// Collinearity bundle adjustment of one survey epoch (Ceres).
//
//   adjustment::Scene scene = ...;            // cameras, images, points, observations
//   adjustment::Options options;              // how to solve
//   adjustment::Config config;                // what is free / fixed
//   adjustment::BundleAdjuster adjuster(options, config);
//   adjustment::Summary summary = adjuster.Solve(&scene);
//   if (summary.IsSolutionUsable()) { ... scene holds the solution, summary.precision the
//   covariances } else { ... summary.reason says why; scene is left exactly as it was }
//
// Unknowns: per image the exterior orientation (X0 Y0 Z0 [m], theta phi kappa
// [rad], camera_model.h), per camera (a group of images sharing a lens and
// sensor) the interior orientation (c x0 y0 k1 k2 k3 p1 p2 b1 b2, camera_model.h
// units; each parameter free or fixed by Config), per object point X Y Z [m]
// in site. Observations: target / tie point pixels with their covariance,
// control point surveys with theirs (priors), optional GNSS camera positions
// (priors). The datum comes from the control points (and GNSS priors).
#pragma once

#include <algorithm>
#include <array>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/camera/camera_model.h"

namespace ceres {
class Problem;
}

namespace slope_monitor {
namespace adjustment {

enum class PointRole { kTie = 0, kControl = 1, kMonitoring = 2, kCheck = 3 };
std::string PointRoleName(PointRole role);

// A camera: one interior orientation block shared by all its images.
struct Camera {
  std::string name;
  camera::CameraModel model;  // initial value / solution
};

// One image (exposure): its exterior orientation.
struct Image {
  std::string name;                      // e.g. camera name + stamp
  int camera = 0;                        // index into Scene::cameras
  double stamp = 0.0;                    // [s]
  camera::ExteriorOrientation exterior;  // initial value / solution
  bool exterior_known = true;            // false: InitializeScene() resects it first
  bool attitude_from_prior =
      false;  // exterior is the flight log's attitude at the GNSS centre (coarse)
  std::optional<Eigen::Vector3d> position_prior;  // [m] GNSS projection centre in site
  Eigen::Matrix3d position_prior_covariance = Eigen::Matrix3d::Identity();  // [m^2]
};

struct ObjectPoint {
  std::string id;  // "tag36h11/3", "tie/17"
  PointRole role = PointRole::kTie;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // [m] initial value / solution, site
  bool position_known = true;  // false: InitializeScene() intersects it first
  // Survey of a control (or check) point; used as a prior for control points
  // only (check points stay unconstrained so they can check the result).
  std::optional<Eigen::Vector3d> surveyed;                                   // [m] site
  Eigen::Matrix3d surveyed_covariance = Eigen::Matrix3d::Identity() * 1e-4;  // [m^2]
  // Approximate coordinates (a monitoring target's hand-held GNSS position in
  // the target list): only for orienting GNSS-prior images that see no known
  // point (OrientFromApproximatePoints), never a prior of the adjustment.
  std::optional<Eigen::Vector3d> approximate;  // [m] site
};

struct Observation {
  int image = 0;                                                    // index into Scene::images
  int point = 0;                                                    // index into Scene::points
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();                  // [px] OpenCV convention
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity() * 0.01;  // [px^2]
};

struct Scene {
  std::vector<Camera> cameras;
  std::vector<Image> images;
  std::vector<ObjectPoint> points;
  std::vector<Observation> observations;

  int FindPoint(const std::string& id) const;    // -1 when absent
  int FindImage(const std::string& name) const;  // -1 when absent
  // Throws InvalidArgument naming the first index that points nowhere.
  void CheckIndices() const;
};

// How to solve.
struct Options {
  // Robust loss on the whitened image residuals: "none" | "huber" | "cauchy".
  std::string loss = "huber";
  double loss_scale = 3.0;  // [sigma] where the loss turns robust, > 0
  double outlier_threshold =
      5.0;  // [sigma] whitened residual norm above which an observation is reported as outlier
  // "auto" (dense_schur for <= dense_schur_max_images images, else sparse_schur:
  // measured on UAV blocks of 150 / 300 photos, doc/uav_block_scaling.md)
  // | "dense_schur" | "sparse_schur" | "iterative_schur" | "dense_qr" | "sparse_normal_cholesky".
  std::string linear_solver = "auto";
  int dense_schur_max_images = 200;
  int max_iterations = 100;          // [-] > 0
  double function_tolerance = 1e-8;  // [-] relative cost change (1e-10 never ended a UAV block with
                                     // 10^4 tie-point residuals: it crept on by 2e-9 a step)
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-10;
  // Ceres threads (solve, Jacobians, covariance). 1 keeps every run's numbers
  // bit-identical (with more, Ceres sums per-thread partial costs and
  // gradients in scheduling order); HardwareThreads() for big blocks.
  int num_threads = 1;
  static int HardwareThreads() {
    return static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  }
  bool compute_covariance = true;
  // Covariances are scaled by sigma0^2 (a posteriori) when true, else a priori.
  bool scale_covariance_by_sigma0 = true;
  // ... by max(sigma0^2, min_variance_factor): 1 keeps a sigma0 < 1 (image
  // weights pessimistic) from shrinking the part of the covariance that comes
  // from the survey and GNSS priors, which are not better than stated. The
  // datum-free covariance below is always scaled by sigma0^2 alone.
  double min_variance_factor = 0.0;  // [-] >= 0
  // Also the point covariance with the surveyed control points held at their
  // adjusted values (Precision::point_covariance_datum_free): the precision
  // of the points relative to the control, without the survey's own error,
  // which is the same in every epoch and cancels in displacements. When the
  // absolute covariance is singular but this one is not, it is the only one
  // (Precision::relative_to_control) and the solution stays usable.
  bool compute_datum_free_covariance = false;
  // Datum and sanity limits for IsSolutionUsable().
  int min_control_points = 3;  // control points observed in >= 2 images (or GNSS images, see below)
  int min_position_priors = 3;  // images with GNSS priors that can replace control points
  int min_observations_per_image = 4;
  // Images with a GNSS position prior (used): the prior fixes the centre, two
  // points the attitude; this many observations are enough (>= 2).
  int min_observations_with_prior = 3;
  double max_sigma0 = 5.0;            // [-] a posteriori sigma0 above this: not usable
  double max_outlier_fraction = 0.2;  // [-]
  bool minimizer_progress = false;
  // Screening adjustments: when the iterations run out, the parameters
  // reached are still written back to the scene (the Summary still says not
  // usable, and nothing else is filled in).
  bool write_back_unconverged = false;
  // A relative block in a model frame (flight orientation while it grows):
  // the datum is the images the Config holds fixed (two or more), not
  // control points or GNSS priors.
  bool fixed_images_define_datum = false;

  // Throws ConfigError naming the first bad field.
  void Check() const;
};

// What is free and what is fixed.
struct Config {
  // Interior parameters (InteriorIndex) left free per camera index; a camera
  // absent from the map has its whole interior fixed.
  std::map<int, std::vector<int>> free_interior;
  std::set<int> fixed_images;       // exterior orientation held at its initial value
  std::set<int> fixed_points;       // point coordinates held
  bool use_control_priors = true;   // false: control points are held at their survey
  bool use_position_priors = true;  // GNSS priors of images (when present)

  // Frees `indices` for every camera of the scene.
  void FreeInteriorOfAll(int num_cameras, const std::vector<int>& indices);
};

// Precision of the solution.
struct Precision {
  bool valid = false;
  std::string message;
  // The absolute covariance was singular (a datum the control fixes only when
  // held, e.g. control without heights): every covariance below is relative
  // to the control points held (needs compute_datum_free_covariance).
  bool relative_to_control = false;
  double sigma0 = 0.0;                            // [-] a posteriori
  std::vector<Eigen::Matrix3d> point_covariance;  // [m^2] per point (zero when fixed)
  std::vector<Eigen::Matrix3d>
      point_covariance_datum_free;  // [m^2] control held (Options); empty when not computed
  std::vector<Eigen::Matrix<double, 6, 6>> exterior_covariance;          // [m^2, rad^2] per image
  std::vector<std::array<double, camera::kNumInterior>> interior_sigma;  // per camera (0 = fixed)
};

// An error ellipsoid of a 3x3 covariance: semi-axes (ascending) scaled by k
// (k = 1: one-sigma; 2.796: 95 % in 3-D) and their unit directions (columns).
struct ErrorEllipsoid {
  Eigen::Vector3d semi_axes;
  Eigen::Matrix3d axes;
};
ErrorEllipsoid ErrorEllipsoidOf(const Eigen::Matrix3d& covariance, double k = 1.0);

// What happened.
struct Summary {
  bool usable = false;
  std::string reason;         // why (not) usable, in words
  std::string termination;    // Ceres' termination type and message
  double initial_cost = 0.0;  // 0.5 sum r^2 (whitened, robustified)
  double final_cost = 0.0;
  int iterations = 0;
  double solve_time = 0.0;       // [s] wall clock of the Ceres solve
  double covariance_time = 0.0;  // [s] wall clock of the covariance (schur_covariance.h)
  int num_observations = 0;      // image observations
  int num_residuals = 0;
  int num_parameters = 0;  // free (tangent) parameters
  int redundancy = 0;
  int num_outliers = 0;
  std::vector<int> outliers;         // observation indices (whitened residual > outlier_threshold)
  double rms_residual_px = 0.0;      // [px] of the inlier image observations
  double sigma0 = 0.0;               // [-] sqrt(2 final_cost_unrobustified / redundancy)
  std::vector<double> image_rms_px;  // [px] per image
  // Ids of the points the solution leaves undetermined (the 3x3 normal block
  // of the point singular at the solution: rays parallel, or all but one
  // image weighted to nothing by the robust loss): dropped with their
  // observations before the covariance, not written back, not counted in the
  // statistics above; the rest of the epoch stays usable.
  std::vector<std::string> undetermined_points;
  Precision precision;

  bool IsSolutionUsable() const { return usable; }
  std::string BriefReport() const;
  // "tie/3, tie/17, ..." (the first five of undetermined_points).
  std::string UndeterminedList() const;
};

class BundleAdjuster {
 public:
  // Throws ConfigError from options.Check().
  BundleAdjuster(const Options& options, const Config& config);

  // Checks the input, solves, and on success writes the solution into *scene.
  // On any failure (bad input, too weak a datum, divergence) the Summary says
  // why and *scene is unchanged. Throws InvalidArgument only for indices that
  // point nowhere (a programming error).
  Summary Solve(Scene* scene) const;

  // The input checks alone: returns an empty string when the scene can be
  // adjusted, else the reason.
  std::string CheckInput(const Scene& scene) const;

  const Options& options() const { return options_; }
  const Config& config() const { return config_; }

 private:
  Options options_;
  Config config_;
};

// Solver setup shared by the collinearity adjustment and the BAL solver:
// builds ceres::Solver::Options from ours and runs it, points in elimination
// group 0 (Schur), `last_blocks` (a camera's interior) in a group after the
// other blocks. Returns Ceres' summary fields in *summary.
//
// Ceres orders the blocks of one group by their address, so the reduced
// camera system's column order (and with it its rounding) follows the heap
// unless each group's blocks lie in one array: pass the blocks of one array
// as points, of another as last_blocks, of a third as the rest. A block's
// place in an ill-conditioned system (a datum without heights: reciprocal
// condition 1e-15) moved a copr camera by 1 cm from run to run before.
struct SolveReport {
  bool converged = false;
  bool failed = false;
  std::string termination;
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;
  double time = 0.0;
};
SolveReport SolveCeresProblem(const Options& options, const std::vector<double*>& point_blocks,
                              int num_cameras, ceres::Problem* problem,
                              const std::vector<double*>& last_blocks = {});

}  // namespace adjustment
}  // namespace slope_monitor
