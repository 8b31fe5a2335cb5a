// Areas of significant surface change between the dense step and the
// deformation estimator: dense::ChangePolygon (core/dense/change_polygons.h)
// -> slope_monitor/ChangeAreaArray -> deformation::AreaBatch
// (core/deformation/change_areas.h).
#pragma once

#include <string>
#include <vector>

#include <std_msgs/Header.h>

#include "slope_monitor/ChangeAreaArray.h"
#include "slope_monitor/core/deformation/estimator.h"
#include "slope_monitor/core/dense/change_polygons.h"

namespace slope_monitor {
namespace ros_adapters {

slope_monitor::ChangeAreaArray ToChangeAreaMsg(const std::vector<dense::ChangePolygon>& polygons,
                                               uint32_t epoch, uint32_t reference_epoch,
                                               const std_msgs::Header& header);

// The message as the estimator's area measurement; `source_name`: the topic.
deformation::AreaBatch AreaBatchFromMsg(const slope_monitor::ChangeAreaArray& msg,
                                        const std::string& source_name);

}  // namespace ros_adapters
}  // namespace slope_monitor
