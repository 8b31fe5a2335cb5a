// Inverse-velocity (Fukuzono 1985) forecast of the time of slope failure.
//
// Fukuzono's law of accelerating creep: dv/dt = A v^alpha (alpha > 1), so
//   (1/v)^(alpha - 1) = A (alpha - 1) (tf - t),
// i.e. y(t) = v^(1 - alpha) falls linearly to zero at the failure time tf.
// For alpha = 2 (the common case) 1/v is linear in t.
//
// The forecast fits y = c0 + c1 t by least squares over the samples inside
// the window [t_last - window, t_last], and extrapolates to y = 0:
//   tf = -c0 / c1  (valid only for c1 < 0: an accelerating point)
// Its uncertainty comes from the fit's covariance (scaled by the residual
// variance, so correlated or noisy velocities widen it), propagated to tf
// with the Jacobian d tf / d(c0, c1) = (-1/c1, c0/c1^2). Time is fitted
// relative to the last sample for conditioning.
#pragma once

#include <string>
#include <vector>

namespace slope_monitor {
namespace deformation {

struct ForecastOptions {
  double window = 2.0 * 86400.0;  // [s] length of the fitting window (ending at the last sample)
  double alpha = 2.0;             // [-] Fukuzono exponent, (1, 10]
  int min_samples = 6;            // [-] samples in the window needed for a forecast
  double min_velocity = 0.0;      // [m/s] samples slower than this are left out (1/v explodes)
  double significance = 3.0;      // [-] the slope of y(t) must be below 0 by this many sigma
  double max_horizon =
      365.0 * 86400.0;  // [s] a forecast further than this after t_last is not valid
  void Check() const;   // throws ConfigError naming the field
};

struct VelocitySample {
  double stamp = 0.0;     // [s]
  double velocity = 0.0;  // [m/s] speed (> 0)
};

struct Forecast {
  bool valid = false;
  double failure_time = 0.0;  // [s] predicted tf (stamp)
  double sigma = 0.0;         // [s] 1-sigma of tf
  double window_start = 0.0;  // [s] first sample used
  double window_end = 0.0;    // [s] last sample used
  double window = 0.0;        // [s] window_end - window_start
  int num_samples = 0;
  double alpha = 2.0;
  double slope = 0.0;  // [d y / d t] fitted
  double slope_sigma = 0.0;
  std::string reason;  // why it is not valid (or "ok")
};

// Fits the samples (any order; sorted internally).
Forecast ForecastFailure(const std::vector<VelocitySample>& samples,
                         const ForecastOptions& options);

// The same law fitted to the measured displacements themselves, which have
// independent errors (filtered velocities are autocorrelated and lag an
// accelerating point, so a fit to them understates its uncertainty). With
// y the displacement along the direction of motion, integrating v(t):
//   alpha = 2:  y(t) = D - C ln(tf - t)              (1/v = (tf - t) / C)
//   otherwise:  y(t) = D - C (tf - t)^b / b,  b = (alpha - 2) / (alpha - 1)
//                                                  (v = C (tf - t)^(b - 1))
// For a given tf the model is linear in (C, D); tf is found by a
// logarithmic grid over (t_last, t_last + max_horizon] refined by golden
// section (variable projection), and the covariance of (tf, C, D) is
// (J' W J)^-1 scaled by the reduced chi-square when it exceeds 1. The
// acceleration is significant when the fit beats a straight line
// (constant velocity) by chi2_line - chi2 >= significance^2. `slope` reports
// the inverse-velocity slope d(1/v)/dt = -1/C for alpha = 2.
struct DisplacementSample {
  double stamp = 0.0;         // [s]
  double displacement = 0.0;  // [m] along the direction of motion
  double sigma = 0.0;         // [m] 1-sigma (> 0)
};
Forecast ForecastFromDisplacements(const std::vector<DisplacementSample>& samples,
                                   const ForecastOptions& options);

}  // namespace deformation
}  // namespace slope_monitor
