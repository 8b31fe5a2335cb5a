// Writes a simulated survey (core/sim/survey.h) as a ROS 1 bag with the
// topics of doc/simulator.md. Shared by the make_survey_bag tool and the
// replay test, so both write exactly the same bag.
#pragma once

#include <string>

#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace ros_adapters {

struct SurveyBagSummary {
  int images = 0;
  int camera_infos = 0;
  int epoch_markers = 0;
  int gnss_fixes = 0;
  int radio_blocks = 0;
  int tf_static = 0;
};

// Writes `path` (compression "bz2", "lz4" or "none"); throws IoError naming
// the file when the bag cannot be written, InvalidArgument for an unknown
// compression. Messages are written in time order; /tf_static first.
SurveyBagSummary WriteSurveyBag(const sim::Survey& survey, const std::string& path,
                                const std::string& compression = "bz2");

}  // namespace ros_adapters
}  // namespace slope_monitor
