// Fusion of two sources against constructed truth: a point moving at a known
// constant velocity and one accelerating (Fukuzono law), measured by radio
// (dense, noisier) and adjusted targets (every 6 h, more precise).
#include <cstdio>

#include <gtest/gtest.h>

#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/deformation/point_filter.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

using testing::kDay;
using testing::kT0;

EstimatorOptions Options() {
  EstimatorOptions o;
  o.filter.jerk_spectral_density = 2e-31;
  return o;
}

struct Rms {
  double sum = 0.0;
  int n = 0;
  void Add(const Eigen::Vector3d& e) {
    sum += e.squaredNorm();
    ++n;
  }
  double Value() const { return n ? std::sqrt(sum / n) : 0.0; }
};

struct FusionRun {
  Rms fused, radio_alone, target_alone, radio_raw, target_raw;
  PointState final_state;
  double final_stamp = 0.0;
};

// Feeds radio (sigma 5 mm, every 30 min) and targets (sigma 1.5/1.5/2.5 mm,
// every 6 h) of one point with motion m for `days`; errors of the fused and
// single-source filters are taken after every batch that updates them.
FusionRun RunFusion(const testing::Motion& m, double days,
                    const Eigen::Vector3d& target_bias = Eigen::Vector3d::Zero()) {
  testing::SourceSpec radio;
  radio.source = Source::kRadio;
  radio.interval = 1800.0;
  radio.sigma = Eigen::Vector3d(0.005, 0.005, 0.005);
  radio.seed = 11;
  testing::SourceSpec target;
  target.source = Source::kTarget;
  target.name = "bundle_adjuster";
  target.interval = 6 * 3600.0;
  target.sigma = Eigen::Vector3d(0.0015, 0.0015, 0.0025);
  target.bias = target_bias;
  target.seed = 12;
  const double t_end = kT0 + days * kDay;
  const auto batches = testing::Merge({testing::MakeBatches(radio, {"p1"}, {m}, t_end),
                                       testing::MakeBatches(target, {"p1"}, {m}, t_end)});
  Estimator est(Options());
  FusionRun run;
  const double burn_in = kT0 + 0.5 * kDay;  // errors after the filters settled
  for (const Batch& b : batches) {
    est.AddBatch(b);
    const Measurement& meas = b.measurements[0];
    const Eigen::Vector3d truth = m.Displacement(b.stamp);
    if (b.stamp < burn_in) continue;
    const PointState p = est.GetSnapshot().points.at(0);
    run.fused.Add(p.displacement - truth);
    for (const SourceEstimate& s : p.per_source) {
      if (s.source != meas.source) continue;
      (s.source == Source::kRadio ? run.radio_alone : run.target_alone).Add(s.displacement - truth);
    }
    (meas.source == Source::kRadio ? run.radio_raw : run.target_raw).Add(meas.displacement - truth);
  }
  run.final_state = est.GetSnapshot().points.at(0);
  run.final_stamp = run.final_state.stamp;
  return run;
}

void Print(const char* name, const FusionRun& r) {
  std::printf(
      "[%s] RMS vs truth [mm]: radio raw %.2f, target raw %.2f | radio alone (filtered) %.2f, "
      "targets alone (filtered) %.2f, fused %.2f\n",
      name, r.radio_raw.Value() * 1e3, r.target_raw.Value() * 1e3, r.radio_alone.Value() * 1e3,
      r.target_alone.Value() * 1e3, r.fused.Value() * 1e3);
}

void ExpectWithin3Sigma(const PointState& p, const Eigen::Vector3d& truth) {
  for (int k = 0; k < 3; ++k) {
    const double sigma = std::sqrt(p.displacement_covariance(k, k));
    EXPECT_LT(std::abs(p.displacement(k) - truth(k)), 3.0 * sigma)
        << "axis " << k << ": " << p.displacement(k) << " vs truth " << truth(k) << " sigma "
        << sigma;
  }
}

TEST(Fusion, ConstantVelocityBeatsEachSourceAlone) {
  testing::Motion m;
  m.v0 = 8e-3 / kDay;  // 8 mm/day
  const FusionRun r = RunFusion(m, 4.0);
  Print("constant velocity", r);
  ExpectWithin3Sigma(r.final_state, m.Displacement(r.final_stamp));
  EXPECT_LT(r.fused.Value(), r.radio_alone.Value());
  EXPECT_LT(r.fused.Value(), r.target_alone.Value());
  EXPECT_LT(r.fused.Value(), r.radio_raw.Value());
  EXPECT_LT(r.fused.Value(), r.target_raw.Value());
  // Velocity within 3 sigma of the truth along the motion.
  const Eigen::Vector3d v_true = m.Velocity(r.final_stamp);
  for (int k = 0; k < 3; ++k)
    EXPECT_LT(std::abs(r.final_state.velocity(k) - v_true(k)),
              3.0 * std::sqrt(r.final_state.velocity_covariance(k, k)));
  EXPECT_FALSE(r.final_state.sources_disagree) << r.final_state.alert_reason;
}

TEST(Fusion, AcceleratingPointTrackedWithin3Sigma) {
  testing::Motion m;
  m.v0 = 5e-3 / kDay;
  m.accelerating = true;
  m.failure_time = kT0 + 8.0 * kDay;
  const FusionRun r = RunFusion(m, 5.0);
  Print("accelerating", r);
  ExpectWithin3Sigma(r.final_state, m.Displacement(r.final_stamp));
  EXPECT_LT(r.fused.Value(), r.radio_alone.Value());
  EXPECT_LT(r.fused.Value(), r.target_alone.Value());
  EXPECT_GT(r.final_state.speed, 1.5 * m.v0);  // it did accelerate: v(5 d) = 8/3 v0
  EXPECT_FALSE(r.final_state.sources_disagree) << r.final_state.alert_reason;
}

TEST(Fusion, BiasedSourceIsReportedNotAveraged) {
  testing::Motion m;
  m.v0 = 8e-3 / kDay;
  const FusionRun r = RunFusion(m, 3.0, Eigen::Vector3d(0.02, 0.0, 0.0));  // targets 20 mm off in x
  EXPECT_TRUE(r.final_state.sources_disagree);
  ASSERT_FALSE(r.final_state.comparisons.empty());
  const SourceComparison& c = r.final_state.comparisons.front();
  EXPECT_TRUE(c.disagree);
  EXPECT_NEAR(std::abs(c.difference.x()), 0.02, 0.006);  // the difference is the bias
  EXPECT_NE(r.final_state.alert_reason.find("disagree"), std::string::npos)
      << r.final_state.alert_reason;
}

TEST(Fusion, OutOfOrderArrivalGivesTheSameEstimate) {
  testing::Motion m;
  m.v0 = 8e-3 / kDay;
  testing::SourceSpec radio;
  radio.interval = 600.0;
  testing::SourceSpec target;
  target.source = Source::kTarget;
  target.interval = 4 * 3600.0;
  target.sigma = Eigen::Vector3d(0.002, 0.002, 0.002);
  target.seed = 5;
  const double t_end = kT0 + 2 * kDay;
  const auto radio_b = testing::MakeBatches(radio, {"p1"}, {m}, t_end);
  const auto target_b = testing::MakeBatches(target, {"p1"}, {m}, t_end);
  Estimator in_order(Options()), late(Options());
  for (const Batch& b : testing::Merge({radio_b, target_b})) in_order.AddBatch(b);
  // Targets arrive 3 h after their stamp (adjustment delay): radio gets ahead.
  std::vector<std::pair<double, const Batch*>> arrival;
  for (const Batch& b : radio_b) arrival.push_back({b.stamp, &b});
  for (const Batch& b : target_b) arrival.push_back({b.stamp + 3 * 3600.0, &b});
  std::stable_sort(arrival.begin(), arrival.end(),
                   [](auto& a, auto& b) { return a.first < b.first; });
  for (const auto& a : arrival) late.AddBatch(*a.second);
  const PointState a = in_order.GetSnapshot().points.at(0), b = late.GetSnapshot().points.at(0);
  EXPECT_EQ(a.num_measurements, b.num_measurements);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(a.displacement(k), b.displacement(k), 1e-12);
    EXPECT_NEAR(a.velocity(k), b.velocity(k), 1e-18);
  }
}

TEST(Fusion, AliasJoinsARadioTransmitterToItsTarget) {
  EstimatorOptions o = Options();
  o.aliases["radio/tx1"] = "tag36h11/5";
  Estimator est(o);
  Batch b;
  b.stamp = kT0 + 3600;
  Measurement m;
  m.point_id = "radio/tx1";
  m.source = Source::kRadio;
  m.stamp = b.stamp;
  m.reference_stamp = kT0;
  m.covariance = 1e-6 * Eigen::Matrix3d::Identity();
  b.measurements.push_back(m);
  m.point_id = "tag36h11/5";
  m.source = Source::kTarget;
  b.measurements.push_back(m);
  const BatchSummary s = est.AddBatch(b);
  EXPECT_EQ(s.accepted, 2);
  const Snapshot snap = est.GetSnapshot();
  ASSERT_EQ(snap.points.size(), 1u);
  EXPECT_EQ(snap.points[0].id, "tag36h11/5");
  EXPECT_EQ(snap.points[0].sources.size(), 2u);
}

TEST(Fusion, BadMeasurementsAreRefusedWithTheirName) {
  Estimator est(Options());
  Batch b;
  b.stamp = kT0;
  Measurement m;
  m.point_id = "p7";
  m.source_name = "hex_matcher";
  m.stamp = kT0 + 10;
  m.reference_stamp = kT0;
  m.covariance = -Eigen::Matrix3d::Identity();
  b.measurements.push_back(m);
  Measurement other = m;
  other.point_id = "p8";
  other.reference_stamp = kT0 - 5 * kDay;  // another datum
  other.covariance = Eigen::Matrix3d::Identity() * 1e-6;
  Measurement good = m;
  good.point_id = "p9";
  good.covariance = Eigen::Matrix3d::Identity() * 1e-6;
  b.measurements = {m, good, other};
  const BatchSummary s = est.AddBatch(b);
  EXPECT_EQ(s.accepted, 1);
  EXPECT_EQ(s.refused, 2);
  ASSERT_EQ(s.messages.size(), 2u);
  EXPECT_NE(s.messages[0].find("p7"), std::string::npos);
  EXPECT_NE(s.messages[0].find("positive definite"), std::string::npos);
  EXPECT_NE(s.messages[1].find("p8"), std::string::npos);
  EXPECT_NE(s.messages[1].find("reference"), std::string::npos);
}

TEST(PointFilter, ConstantAccelerationWithoutNoiseIsExact) {
  // Noise-free measurements of d = 0.5 a t^2 with tiny R: the filter must
  // recover the acceleration (hand-checkable model).
  FilterOptions o;
  o.jerk_spectral_density = 0.0;
  PointFilter f(o);
  FilterState s;
  const Eigen::Vector3d a(1e-9, -2e-9, 0.5e-9);  // m/s^2
  for (int i = 0; i <= 48; ++i) {
    const double t = i * 3600.0;
    f.Update(&s, t, 0.5 * a * t * t, 1e-12 * Eigen::Matrix3d::Identity());
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(s.Acceleration()(k), a(k), 1e-3 * a.norm());
    EXPECT_NEAR(s.Velocity()(k), a(k) * 48 * 3600.0, 1e-3 * a.norm() * 48 * 3600.0);
  }
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
