// The bundle adjuster's service resect_camera (srv/ResectCamera.srv): the
// request converted to adjustment::ResectCamera's input, the summary to the
// response. Bad input (arrays of different lengths, fewer than 4 points, a
// camera_info the collinearity model cannot represent, an unknown parameter
// name) gives success = false and a message naming the field; the caller
// (a ROS service callback) keeps running.
#pragma once

#include "slope_monitor/ResectCamera.h"

namespace slope_monitor {
namespace ros_adapters {

void Resect(const slope_monitor::ResectCamera::Request& request,
            slope_monitor::ResectCamera::Response* response);

}  // namespace ros_adapters
}  // namespace slope_monitor
