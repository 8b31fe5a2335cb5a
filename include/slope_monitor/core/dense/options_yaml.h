// Correlation options from a dense_matcher parameter file (the keys of
// config/defaults/dense_matcher.yaml that belong to CorrelationOptions), for
// the bench and tests that run a named configuration such as
// config/dense_cones.yaml. Keys the file does not set keep the values `o`
// already holds; other keys are ignored (the file may carry the surface
// model's keys too).
#pragma once

#include <string>

#include "slope_monitor/core/dense/correlation.h"

namespace slope_monitor {
namespace dense {

// Throws IoError naming the file when it cannot be read, ConfigError naming
// the key when a value is out of range, and CorrelationOptions::Check's
// ConfigError.
void ReadCorrelationOptions(const std::string& path, CorrelationOptions* o);

}  // namespace dense
}  // namespace slope_monitor
