// Kalman filter over the displacement, velocity and acceleration of one
// monitoring point in 3-D (site frame), and an out-of-order wrapper.
//
// Process model (per axis, the three axes independent): constant
// acceleration driven by white jerk of spectral density q [m^2/s^5]:
//   state x = [d(3), v(3), a(3)]   (m, m/s, m/s^2)
//   d' = v, v' = a, a' = j(t), E[j(t) j(s)] = q delta(t - s)
// Discretised over tau seconds:
//   F = [[I, tau I, tau^2/2 I], [0, I, tau I], [0, 0, I]]
//   Q = q [[tau^5/20, tau^4/8, tau^3/6], [tau^4/8, tau^3/3, tau^2/2], [tau^3/6, tau^2/2, tau]] (x)
//   I3
// Measurement model: z = d + e, e ~ N(0, R) with R the source's 3x3 covariance.
//
// The origin (a source's reference epoch): displacements are measured from
// the reference, so at the reference time the displacement is zero by
// definition. PointFilter::Origin starts the state there with d = 0 exactly
// (P_dd = 0: the reference's own uncertainty is already in every later
// displacement's covariance, which the source computes from both epochs; the
// correlation this leaves between successive displacements is not carried),
// the velocity diffuse (origin_velocity_sigma) and the acceleration prior
// initial_acceleration_sigma. The first displacement d at Delta t after it
// then gives the velocity d / Delta t, its sigma from R, the process noise
// over Delta t and the acceleration prior (sigma_a Delta t / 2).
//
// Internally the state is kept in metres and days so that the
// covariance entries stay within a few orders of magnitude of each other;
// the public accessors return SI units (m, m/s, m/s^2).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace deformation {

using Vector9d = Eigen::Matrix<double, 9, 1>;
using Matrix9d = Eigen::Matrix<double, 9, 9>;

struct FilterOptions {
  double jerk_spectral_density =
      2.0e-29;  // [m^2/s^5] q of the white jerk (2e-29 ~ (10 mm/day^2)^2 per day)
  double initial_velocity_sigma =
      1.0e-6;  // [m/s] prior sigma of the velocity at the first measurement (~86 mm/day)
  // [m/s^2] prior sigma of the acceleration (~0.26 m/day^2: a slide near failure,
  // the demo's half a day before it; 1e-10 (0.75 m/day^2) left the first
  // movement's speed sigma at 95 mm/day for a 6 h interval, no alarm at 240 mm/day)
  double initial_acceleration_sigma = 3.0e-11;
  double origin_velocity_sigma =
      1.0e-3;          // [m/s] velocity prior at the origin (~86 m/day: diffuse; the data decide)
  void Check() const;  // throws ConfigError naming the field
};

// Filter state at one instant (internal units: m, m/day, m/day^2).
struct FilterState {
  bool initialized = false;
  double stamp = 0.0;  // [s]
  Vector9d x = Vector9d::Zero();
  Matrix9d P = Matrix9d::Zero();

  Eigen::Vector3d Displacement() const { return x.head<3>(); }
  Eigen::Vector3d Velocity() const;      // [m/s]
  Eigen::Vector3d Acceleration() const;  // [m/s^2]
  Eigen::Matrix3d DisplacementCovariance() const { return P.topLeftCorner<3, 3>(); }
  Eigen::Matrix3d VelocityCovariance() const;  // [m^2/s^2]
};

struct UpdateResult {
  Eigen::Vector3d innovation = Eigen::Vector3d::Zero();  // [m] z - H x_predicted
  Eigen::Matrix3d innovation_covariance = Eigen::Matrix3d::Zero();
  double nis = 0.0;  // normalised innovation squared (chi-square, 3 dof)
};

class PointFilter {
 public:
  explicit PointFilter(const FilterOptions& options) : options_(options) {}
  // Predicts a copy of `state` to `stamp` (>= state.stamp; earlier stamps are
  // not predicted backwards: the state is returned unchanged).
  FilterState Predict(const FilterState& state, double stamp) const;
  // The state at a source's reference epoch: d = 0 exactly, the velocity
  // diffuse (origin_velocity_sigma), the acceleration prior (see above).
  FilterState Origin(double stamp) const;
  // Initialises (first measurement) or predicts and updates with z, R.
  UpdateResult Update(FilterState* state, double stamp, const Eigen::Vector3d& z,
                      const Eigen::Matrix3d& R) const;
  // Innovation of a measurement against the prediction, without updating.
  UpdateResult Test(const FilterState& state, double stamp, const Eigen::Vector3d& z,
                    const Eigen::Matrix3d& R) const;
  const FilterOptions& options() const { return options_; }

 private:
  FilterOptions options_;
};

// A filter fed in any time order. Measurements are kept sorted by
// (stamp, sequence); a measurement older than the newest one restores the
// state saved just before it and re-runs the later ones, so the result
// depends only on the set of measurements (and the arrival order of equal
// stamps), never on when they arrived. Entries older than `reorder_window`
// behind the newest are folded into a base state; a measurement older than
// the base is refused (Add returns false).
class OrderedFilter {
 public:
  struct Entry {
    double stamp = 0.0;
    uint64_t sequence = 0;
    Eigen::Vector3d z = Eigen::Vector3d::Zero();
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    FilterState after;  // state after this measurement
    UpdateResult result;
  };

  OrderedFilter(const FilterOptions& options, double reorder_window)
      : filter_(options), reorder_window_(reorder_window) {}

  // Starts the filter at the origin (PointFilter::Origin) at `stamp`, before
  // any measurement; false (nothing changed) when it already has a state.
  // The origin is no measurement: count() does not include it.
  bool AddOrigin(double stamp);
  // The velocity is measured: two states (origin and a measurement, or two measurements).
  bool has_velocity() const { return count_ + (has_origin_ ? 1 : 0) >= 2; }

  // False (and nothing changed) when the stamp is older than the base state.
  bool Add(double stamp, uint64_t sequence, const Eigen::Vector3d& z, const Eigen::Matrix3d& R,
           UpdateResult* result = nullptr);
  bool initialized() const { return latest().initialized; }
  const FilterState& latest() const { return entries_.empty() ? base_ : entries_.back().after; }
  // Filtered state at `stamp` (the last state at or before it, predicted to
  // it); nullopt when no measurement at or before `stamp` is held.
  std::optional<FilterState> StateAt(double stamp) const;
  size_t size() const { return entries_.size(); }
  uint64_t count() const { return count_; }
  const PointFilter& filter() const { return filter_; }

 private:
  PointFilter filter_;
  double reorder_window_;
  FilterState base_;
  std::deque<Entry> entries_;
  uint64_t count_ = 0;
  bool has_origin_ = false;
};

}  // namespace deformation
}  // namespace slope_monitor
