// Timing of the benchmarks: the median wall time of repeated runs.
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

namespace slope_monitor {
namespace bench {

// Median wall time [ms] of `runs` calls of f().
template <typename F>
double MedianMs(F f, int runs) {
  std::vector<double> t;
  for (int k = 0; k < runs; ++k) {
    const auto a = std::chrono::steady_clock::now();
    f();
    t.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

}  // namespace bench
}  // namespace slope_monitor
