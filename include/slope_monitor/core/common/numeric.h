// Small numeric helpers that several modules need alike (one definition, so
// that the unity builds of the libraries never see two; CMakeLists.txt).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

namespace slope_monitor {

constexpr double kDegPerRad = 180.0 / M_PI;
constexpr double kRadPerDeg = M_PI / 180.0;

// The upper median v[n/2] (for an even n the larger of the two middle values);
// 0 for an empty vector.
inline double UpperMedian(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// Wall seconds since `start` (steady clock: for the timings a summary prints).
inline double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace slope_monitor
