// Deterministic fuzz of the message validation layer (issue 22): 5000
// PointDisplacementArray messages with random hostile fields (fixed seed).
// Whatever passes is usable: finite, in range, with a symmetric positive
// definite covariance and a short printable id. Nothing throws.
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Cholesky>

#include "../fuzz/mutator.h"
#include "slope_monitor/core/io/safe_file.h"
#include "slope_monitor/ros/validation.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

constexpr double kFuzzNow = 1.7e9;

class Hostile {
 public:
  explicit Hostile(unsigned seed) : rng_(seed) {}
  double Value(double typical) {
    static const double kExtremes[] = {1e300,     -1e300, 1e-300, NAN,         INFINITY,
                                       -INFINITY, 0.0,    -0.0,   4294967296.0};
    if (Coin(0.15)) return kExtremes[Below(9)];
    return typical * (1.0 + 0.5 * std::normal_distribution<double>()(rng_));
  }
  std::string Id() {
    if (Coin(0.8)) return "p" + std::to_string(Below(50));
    std::string s(Below(300), 'x');
    for (char& c : s) c = static_cast<char>(Below(256));
    return s;
  }
  bool Coin(double p) { return std::uniform_real_distribution<double>(0, 1)(rng_) < p; }
  size_t Below(size_t n) { return std::uniform_int_distribution<size_t>(0, n - 1)(rng_); }

 private:
  std::mt19937 rng_;
};

TEST(ValidationFuzz, WhatPassesIsUsable) {
  Hostile h(fuzz::Seed());
  const int n = fuzz::Iterations(5000);
  MessageValidator v;
  size_t passed = 0, seen = 0;
  for (int i = 0; i < n; ++i) {
    slope_monitor::PointDisplacementArray a;
    a.header.stamp = ros::Time(kFuzzNow - h.Below(100000));
    a.epoch = static_cast<uint32_t>(i / 10);  // message-level checks: validation_test.cpp
    for (size_t k = 0, count = h.Below(6); k < count; ++k) {
      slope_monitor::PointDisplacement d;
      d.point_id = h.Id();
      d.source_name = "fuzz";
      d.stamp = ros::Time(kFuzzNow - 10.0);
      d.reference_stamp = ros::Time(kFuzzNow - 1e5);
      d.reference_position.x = h.Value(100.0);
      d.reference_position.y = h.Value(-50.0);
      d.reference_position.z = h.Value(300.0);
      d.displacement.x = h.Value(0.01);
      d.significance = h.Value(3.0);
      const double s2 = h.Value(1e-6);
      for (int c = 0; c < 3; ++c) d.covariance[4 * c] = s2;
      if (h.Coin(0.2)) d.covariance[1] = h.Value(1e-6);
      if (h.Coin(0.2)) d.covariance[3] = d.covariance[1];
      a.displacements.push_back(d);
    }
    seen += a.displacements.size();
    slope_monitor::PointDisplacementArray out;
    ASSERT_NO_THROW(out = v.Filter(a, "fuzz", kFuzzNow)) << "message " << i;
    for (const auto& d : out.displacements) {
      ++passed;
      EXPECT_EQ(io::IdProblem(d.point_id), "");
      const Eigen::Vector3d x(d.reference_position.x, d.reference_position.y,
                              d.reference_position.z);
      EXPECT_TRUE(x.allFinite() && x.cwiseAbs().maxCoeff() <= 1e5) << x.transpose();
      Eigen::Matrix3d c;
      for (int k = 0; k < 9; ++k) c(k / 3, k % 3) = d.covariance[k];
      EXPECT_EQ(Eigen::LLT<Eigen::Matrix3d>(c).info(), Eigen::Success) << c;
    }
  }
  EXPECT_GT(passed, static_cast<size_t>(n) / 5);
  EXPECT_LT(passed, seen);
  EXPECT_EQ(v.total_rejected(), seen - passed) << "every dropped element is counted";
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
