#include "slope_monitor/core/radio/types.h"

#include <cmath>

namespace slope_monitor {
namespace radio {

double WrapPhase(double a) {
  double w = std::remainder(a, 2.0 * M_PI);  // [-pi, pi]
  if (w <= -M_PI) w += 2.0 * M_PI;
  return w;
}

}  // namespace radio
}  // namespace slope_monitor
