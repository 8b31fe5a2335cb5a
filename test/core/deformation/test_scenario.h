// Synthetic monitoring points with known truth for the deformation tests:
// constant velocity or Fukuzono acceleration (v = v0 T / (T - (t - t0))),
// measured by sources with known noise and fixed seeds.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/deformation/estimator.h"

namespace slope_monitor {
namespace deformation {
namespace testing {

constexpr double kDay = 86400.0;
constexpr double kMmPerDay = 1e-3 / kDay;  // 1 mm/day in m/s
constexpr double kT0 = 1700000000.0;       // [s] reference stamp

struct Motion {
  Eigen::Vector3d direction{0.0, -0.94, -0.34};  // unit-ish, normalised below
  double v0 = 0.0;                               // [m/s] speed at t0
  bool accelerating = false;
  double failure_time = 0.0;  // [s] tf (accelerating)

  double Travel(double t) const {
    const double dt = t - kT0;
    if (dt <= 0) return 0.0;
    if (!accelerating) return v0 * dt;
    const double T = failure_time - kT0;
    return v0 * T * std::log(T / (T - dt));
  }
  double Speed(double t) const {
    if (!accelerating) return v0;
    return v0 * (failure_time - kT0) / (failure_time - t);
  }
  Eigen::Vector3d Displacement(double t) const { return direction.normalized() * Travel(t); }
  Eigen::Vector3d Velocity(double t) const { return direction.normalized() * Speed(t); }
};

struct SourceSpec {
  Source source = Source::kRadio;
  std::string name = "radio_phase_solver";
  double interval = 1800.0;                        // [s]
  double offset = 0.0;                             // [s] first measurement after t0
  Eigen::Vector3d sigma{0.003, 0.003, 0.003};      // [m] per axis
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();  // [m]
  unsigned seed = 1;
};

// Batches of one source for several points from t0 + offset to t_end.
inline std::vector<Batch> MakeBatches(const SourceSpec& s, const std::vector<std::string>& ids,
                                      const std::vector<Motion>& motions, double t_end) {
  std::mt19937 rng(s.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<Batch> out;
  uint32_t epoch = 0;
  for (double t = kT0 + s.offset; t <= t_end + 1e-6; t += s.interval) {
    Batch b;
    b.epoch =
        s.source == Source::kRadio ? static_cast<uint32_t>((t - kT0) / (6 * 3600.0)) : epoch++;
    b.stamp = t;
    for (size_t i = 0; i < ids.size(); ++i) {
      Measurement m;
      m.point_id = ids[i];
      m.source = s.source;
      m.source_name = s.name;
      m.epoch = b.epoch;
      m.stamp = t;
      m.reference_stamp = kT0;
      m.reference_position = Eigen::Vector3d(10.0 * i, 50.0, 20.0);
      Eigen::Vector3d noise(n01(rng), n01(rng), n01(rng));
      m.displacement = motions[i].Displacement(t) + s.bias + s.sigma.cwiseProduct(noise);
      m.covariance = s.sigma.cwiseProduct(s.sigma).asDiagonal();
      b.measurements.push_back(m);
    }
    out.push_back(b);
  }
  return out;
}

// Merges several sources' batches in stamp order (stable).
inline std::vector<Batch> Merge(std::vector<std::vector<Batch>> lists) {
  std::vector<Batch> all;
  for (auto& l : lists) all.insert(all.end(), l.begin(), l.end());
  std::stable_sort(all.begin(), all.end(),
                   [](const Batch& a, const Batch& b) { return a.stamp < b.stamp; });
  return all;
}

}  // namespace testing
}  // namespace deformation
}  // namespace slope_monitor
