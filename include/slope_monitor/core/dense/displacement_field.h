// The displacement field of a fixed camera without targets:
// a grid of probe points over the monitored area of the reference photo,
// tracked into a new photo by modified LSC (lsc.h: integer NCC search, then
// LSC with its covariance) around the position the re-orientation predicts,
// and projected onto a DEM by ray-surface intersection.
//
// For a probe xa (reference photo, pose `reference`) and its match xb (new
// photo, pose `current` = the reference position with the re-oriented
// attitude, see adjustment::ReorientCamera):
//   x_ref = first intersection of the ray of xa (reference pose) with the DEM
//   x_new = first intersection of the ray of xb (current pose) with the DEM
//           (FieldInput::current_dem when given: the surface of that epoch)
//   d = x_new - x_ref [m, site],  v = d / dt [m/s]
// The DEM is the surface of the reference epoch; the moved point is taken on
// it (a body that slides along its surface stays on it).
//
// LSC's covariance is that of white noise in a perfect image; resampling,
// interpolation and texture that changes with the view make the real scatter
// larger (measured on the simulator: 3.8 x in sigma). With FieldInput::stable
// the probes on stable ground, whose true displacement is zero, give the
// factor: median of r^T C^-1 r over 2 ln 2 (the median of chi^2(2)), applied
// to every probe's LSC covariance when > 1 (Summary::lsc_variance_factor).
//
// Covariance of d (numeric Jacobians, central differences):
//   J_xb Cov_LSC J_xb^T  +  J_att Cov_att J_att^T  +  J_h sigma_h^2 J_h^T
//   + w w^T  (the window-straddle term, below)
// with J_h the derivative of d with respect to a common shift of the DEM
// height (both points lie on the same local surface: its error is largely
// common to both). The reference pose is taken as exact (its error moves
// both rays together).
//
// Window-straddle term: LSC's covariance holds for a window that moves as
// one (affine). At a body's margin the window sees ground that moves
// differently and LSC returns a texture-weighted blend of its motions, not
// the centre's (measured on the simulator: 11 of 50 probes in the body's
// taper beyond 3 sigma without the term, doc/targetless_camera.md). For a
// usable probe whose usable neighbour in the photo (within 1.5 x the median
// grid distance, r px) differs in displacement by Delta, significantly
// (|Delta_xy| > straddle_min_sigma x the sigma of the difference), the
// motion changes across the window by w = Delta min(1, half_window / r); the
// largest such w adds w w^T to the covariance (Summary::straddling counts
// the probes that got one). Applied before the "inconsistent" test.
//
// Flags (FieldPoint::flag, "" = usable):
//   "no_surface"     a ray does not meet the DEM (outside it or nodata)
//   "grazing"        the ray meets the surface at less than min_incidence_deg
//   "line_of_sight"  the displacement is significant (|d| > 3 sigma along d)
//                    and within min_los_angle_deg of the line of sight: the
//                    camera hardly sees it, the DEM's slope makes it
//   "lsc_<status>"   LSC did not converge (lsc.h status name)
//   "inconsistent"   the horizontal displacement differs from the median of
//                    the usable neighbours on the ground (1.5 x the median
//                    grid distance, >= 3 of them) by > max_neighbour_sigma x
//                    its sigma in x or y: motion unlike its surroundings (a
//                    match pulled by the moving part of its window at a
//                    body's margin, or a blunder)
//   "off_image"      the predicted position leaves the new photo
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/matching/lsc.h"

namespace slope_monitor {
namespace dense {

struct DisplacementFieldOptions {
  // Grid of probes: spacing in pixels of the reference photo (> 0), or, when
  // spacing_m > 0, in metres on the DEM (the DEM's cells at that spacing
  // that the reference photo sees inside the monitored area).
  double spacing_px = 50.0;
  double spacing_m = 0.0;        // [m] >= 0; 0 = use spacing_px
  int border_px = 20;            // [px] probes keep this far from the image edge, >= 0
  int search_radius = 12;        // [px] integer NCC search around the prediction, [0, 50]
  double prefilter_sigma = 1.0;  // [px] Gaussian low-pass before LSC, [0, 5]; 0 = none
  int half_window = 10;          // [px] LSC window (2 h + 1)^2, [2, 50]
  double dem_sigma = 0.1;        // [m] height std of the DEM when it has no "sigma" band, >= 0
  double min_incidence_deg =
      8.0;  // [deg] grazing below this angle between ray and surface, [0, 90)
  double min_los_angle_deg = 30.0;  // [deg] "line_of_sight" within this of the ray, [0, 90)
  // "inconsistent" beyond this x sigma from the median of the neighbours, >= 0; 0 = off.
  double max_neighbour_sigma = 3.0;
  // Window-straddle term (file comment): neighbours whose displacement differs
  // by more than this x the sigma of the difference count, >= 0; 0 = no term.
  double straddle_min_sigma = 3.0;
  // Probes on stable ground (FieldInput::stable) needed to scale the LSC
  // covariance to their scatter, >= 1 (fewer: the LSC covariance as it is).
  int min_stable_probes = 20;
  double max_range = 20000.0;  // [m] rays are followed this far, > 0
  void Check() const;          // throws InvalidArgument naming the field
};

struct FieldPoint {
  Eigen::Vector2d xa = Eigen::Vector2d::Zero();             // [px] probe in the reference photo
  Eigen::Vector2d xb = Eigen::Vector2d::Zero();             // [px] its match in the new photo
  Eigen::Matrix2d covariance_px = Eigen::Matrix2d::Zero();  // [px^2] of xb (LSC)
  double correlation = 0.0;                                 // LSC NCC
  Eigen::Vector4d affine = Eigen::Vector4d::Zero();  // LSC's a1 a2 a4 a5 (0: shift model kept)
  Eigen::Vector3d x_ref = Eigen::Vector3d::Zero();   // [m] site, on the DEM
  Eigen::Vector3d displacement = Eigen::Vector3d::Zero();  // [m] site
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();    // [m^2] of the displacement
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero();      // [m/s] (0 when dt == 0)
  double incidence_deg = 0.0;  // angle between the reference ray and the surface
  double los_angle_deg = 0.0;  // angle between the displacement and the line of sight
  bool stable = false;         // on stable ground (FieldInput::stable): a check, d ~ 0
  std::string flag;            // "" = usable, else the reason (see the file comment)
  bool IsUsable() const { return flag.empty(); }
  // sqrt of the diagonal of `covariance`.
  Eigen::Vector3d Sigma() const { return covariance.diagonal().cwiseSqrt(); }
};

struct DisplacementFieldSummary {
  int probes = 0;  // grid points seen on the DEM inside the monitored area
  int usable = 0;  // without a flag
  // Factor applied to every LSC covariance (>= 1): the scatter of the probes
  // on stable ground against the LSC covariance (see the file comment).
  double lsc_variance_factor = 1.0;
  int straddling = 0;                // usable probes given a window-straddle term
  std::map<std::string, int> flags;  // flag -> count
  double seconds = 0.0;
  bool IsSolutionUsable() const { return usable > 0; }
};

struct DisplacementField {
  std::vector<FieldPoint> points;
  DisplacementFieldSummary summary;
};

struct FieldInput {
  camera::CameraModel model;
  camera::ExteriorOrientation reference;  // pose of the reference photo
  camera::ExteriorOrientation current;    // pose of the new photo (re-oriented)
  Eigen::Matrix3d attitude_covariance =
      Eigen::Matrix3d::Zero();  // [rad^2] theta phi kappa of current
  double dt = 0.0;  // [s] new photo's time - reference's (< 0: an earlier photo); 0 = unknown
  // Stable ground in the reference photo (optional): probes are laid there
  // too (FieldPoint::stable); they do not move, their scatter scales the LSC
  // covariance.
  std::function<bool(const Eigen::Vector2d&)> stable;
  // The monitored area in the reference photo (optional; default: everywhere).
  std::function<bool(const Eigen::Vector2d&)> monitored;
  std::string dem_name = "DEM";  // for messages (e.g. the file name)
  // The surface of the new photo's epoch (optional, e.g. the dense matcher's
  // DEM of that epoch): x_new is intersected with it; without it, with the
  // reference DEM (a body that does not slide along its own surface then
  // errs along the ray by its height change / tan(incidence)).
  const io::GeoRaster* current_dem = nullptr;
};

// First intersection of a ray with the DEM's first band (bilinear surface),
// or false. *t the distance along the (unit) direction.
bool IntersectDem(const io::GeoRaster& dem, const Eigen::Vector3d& origin,
                  const Eigen::Vector3d& direction, double max_range, double* t);

// The window-straddle term of each point (the file comment; zero for
// flagged points and where no neighbour differs significantly), from the
// points' xa, displacement and covariance. min_sigma 0: all zero.
std::vector<Eigen::Matrix3d> WindowStraddleTerms(double min_sigma, int half_window,
                                                 const std::vector<FieldPoint>& points);

// The field between two photos (8-bit or float single channel, the camera's
// size). Throws InvalidArgument naming the DEM (input.dem_name) when no probe
// of the monitored area meets it ("does not cover the view"), and naming the
// image when its size is not the camera's.
DisplacementField ComputeDisplacementField(const cv::Mat& reference_image, const cv::Mat& new_image,
                                           const io::GeoRaster& dem, const FieldInput& input,
                                           const DisplacementFieldOptions& options);

}  // namespace dense
}  // namespace slope_monitor
