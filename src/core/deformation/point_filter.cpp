#include "slope_monitor/core/deformation/point_filter.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Cholesky>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace deformation {
namespace {

constexpr double kDay = 86400.0;

// Transition and process noise over tau days for q given in m^2/day^5.
void Transition(double tau, double q_day, Matrix9d* F, Matrix9d* Q) {
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  F->setIdentity();
  F->block<3, 3>(0, 3) = tau * I;
  F->block<3, 3>(0, 6) = 0.5 * tau * tau * I;
  F->block<3, 3>(3, 6) = tau * I;
  const double t2 = tau * tau, t3 = t2 * tau, t4 = t3 * tau, t5 = t4 * tau;
  Eigen::Matrix3d q1;
  q1 << t5 / 20.0, t4 / 8.0, t3 / 6.0,  //
      t4 / 8.0, t3 / 3.0, t2 / 2.0,     //
      t3 / 6.0, t2 / 2.0, tau;
  q1 *= q_day;
  for (Eigen::Index r = 0; r < 3; ++r)
    for (Eigen::Index c = 0; c < 3; ++c) Q->block<3, 3>(3 * r, 3 * c) = q1(r, c) * I;
}

}  // namespace

void FilterOptions::Check() const {
  if (!(jerk_spectral_density >= 0.0) || !std::isfinite(jerk_spectral_density))
    throw ConfigError(
        Message("jerk_spectral_density = ", jerk_spectral_density, " m^2/s^5 must be >= 0"));
  if (!(initial_velocity_sigma > 0.0) || !std::isfinite(initial_velocity_sigma))
    throw ConfigError(
        Message("initial_velocity_sigma = ", initial_velocity_sigma, " m/s must be > 0"));
  if (!(initial_acceleration_sigma > 0.0) || !std::isfinite(initial_acceleration_sigma))
    throw ConfigError(
        Message("initial_acceleration_sigma = ", initial_acceleration_sigma, " m/s^2 must be > 0"));
  if (!(origin_velocity_sigma > 0.0) || !std::isfinite(origin_velocity_sigma))
    throw ConfigError(
        Message("origin_velocity_sigma = ", origin_velocity_sigma, " m/s must be > 0"));
}

FilterState PointFilter::Origin(double stamp) const {
  FilterState s;
  s.initialized = true;
  s.stamp = stamp;
  const double sv = options_.origin_velocity_sigma * kDay;
  const double sa = options_.initial_acceleration_sigma * kDay * kDay;
  s.P.block<3, 3>(3, 3) = sv * sv * Eigen::Matrix3d::Identity();
  s.P.block<3, 3>(6, 6) = sa * sa * Eigen::Matrix3d::Identity();
  return s;
}

Eigen::Vector3d FilterState::Velocity() const { return x.segment<3>(3) / kDay; }
Eigen::Vector3d FilterState::Acceleration() const { return x.segment<3>(6) / (kDay * kDay); }
Eigen::Matrix3d FilterState::VelocityCovariance() const {
  return P.block<3, 3>(3, 3) / (kDay * kDay);
}

FilterState PointFilter::Predict(const FilterState& state, double stamp) const {
  FilterState out = state;
  if (!state.initialized || stamp <= state.stamp) return out;
  const double tau = (stamp - state.stamp) / kDay;
  // q [m^2/s^5] -> m^2/day^5: multiply by day^5.
  const double q_day = options_.jerk_spectral_density * std::pow(kDay, 5);
  Matrix9d F, Q;
  Transition(tau, q_day, &F, &Q);
  out.x = F * state.x;
  out.P = F * state.P * F.transpose() + Q;
  out.P = 0.5 * (out.P + out.P.transpose());
  out.stamp = stamp;
  return out;
}

UpdateResult PointFilter::Test(const FilterState& state, double stamp, const Eigen::Vector3d& z,
                               const Eigen::Matrix3d& R) const {
  UpdateResult r;
  if (!state.initialized) return r;
  const FilterState p = Predict(state, stamp);
  r.innovation = z - p.x.head<3>();
  r.innovation_covariance = p.P.topLeftCorner<3, 3>() + R;
  r.nis = r.innovation.dot(r.innovation_covariance.ldlt().solve(r.innovation));
  return r;
}

UpdateResult PointFilter::Update(FilterState* state, double stamp, const Eigen::Vector3d& z,
                                 const Eigen::Matrix3d& R) const {
  UpdateResult r;
  if (!state->initialized) {
    state->initialized = true;
    state->stamp = stamp;
    state->x.setZero();
    state->x.head<3>() = z;
    state->P.setZero();
    state->P.topLeftCorner<3, 3>() = R;
    const double sv = options_.initial_velocity_sigma * kDay;
    const double sa = options_.initial_acceleration_sigma * kDay * kDay;
    state->P.block<3, 3>(3, 3) = sv * sv * Eigen::Matrix3d::Identity();
    state->P.block<3, 3>(6, 6) = sa * sa * Eigen::Matrix3d::Identity();
    r.innovation_covariance = R;
    return r;
  }
  // Measurements older than the state are applied at the state's time (the
  // OrderedFilter never does this; it re-runs in time order instead).
  *state = Predict(*state, stamp);
  r.innovation = z - state->x.head<3>();
  const Eigen::Matrix<double, 9, 3> PHt = state->P.leftCols<3>();
  r.innovation_covariance = state->P.topLeftCorner<3, 3>() + R;
  const Eigen::LDLT<Eigen::Matrix3d> S(r.innovation_covariance);
  r.nis = r.innovation.dot(S.solve(r.innovation));
  const Eigen::Matrix<double, 9, 3> K = S.solve(PHt.transpose()).transpose();
  state->x += K * r.innovation;
  // Joseph form: P = (I - K H) P (I - K H)^T + K R K^T.
  Matrix9d IKH = Matrix9d::Identity();
  IKH.leftCols<3>() -= K;
  state->P = IKH * state->P * IKH.transpose() + K * R * K.transpose();
  state->P = 0.5 * (state->P + state->P.transpose());
  return r;
}

bool OrderedFilter::AddOrigin(double stamp) {
  if (base_.initialized || !entries_.empty()) return false;
  base_ = filter_.Origin(stamp);
  has_origin_ = true;
  return true;
}

bool OrderedFilter::Add(double stamp, uint64_t sequence, const Eigen::Vector3d& z,
                        const Eigen::Matrix3d& R, UpdateResult* result) {
  if (base_.initialized && stamp < base_.stamp) return false;
  Entry e;
  e.stamp = stamp;
  e.sequence = sequence;
  e.z = z;
  e.R = R;
  // Insert after every entry with (stamp, sequence) <= the new one.
  auto pos =
      std::upper_bound(entries_.begin(), entries_.end(), e, [](const Entry& a, const Entry& b) {
        return a.stamp < b.stamp || (a.stamp == b.stamp && a.sequence < b.sequence);
      });
  size_t index = static_cast<size_t>(pos - entries_.begin());
  entries_.insert(pos, e);
  ++count_;
  FilterState state = index == 0 ? base_ : entries_[index - 1].after;
  for (size_t i = index; i < entries_.size(); ++i) {
    entries_[i].result = filter_.Update(&state, entries_[i].stamp, entries_[i].z, entries_[i].R);
    entries_[i].after = state;
  }
  if (result) *result = entries_[index].result;
  // Fold entries that fell out of the reorder window into the base.
  const double newest = entries_.back().stamp;
  while (entries_.size() > 1 && entries_.front().stamp < newest - reorder_window_) {
    base_ = entries_.front().after;
    entries_.pop_front();
  }
  return true;
}

std::optional<FilterState> OrderedFilter::StateAt(double stamp) const {
  const FilterState* best = base_.initialized && base_.stamp <= stamp ? &base_ : nullptr;
  for (const Entry& e : entries_) {
    if (e.stamp > stamp) break;
    best = &e.after;
  }
  if (!best) return std::nullopt;
  return filter_.Predict(*best, stamp);
}

}  // namespace deformation
}  // namespace slope_monitor
