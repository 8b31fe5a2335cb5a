#include "slope_monitor/ros/image_limits.h"

#include <cmath>
#include <cstdio>

#include <sensor_msgs/image_encodings.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace ros_adapters {

void ImageMessageLimits::Check() const {
  RequireOption("ImageMessageLimits", std::isfinite(max_megapixels) && max_megapixels > 0,
                "max_megapixels", Message("must be > 0 (is ", max_megapixels, ")"));
}

void CheckImageMessage(const sensor_msgs::Image& image, const ImageMessageLimits& limits) {
  const double pixels = static_cast<double>(image.width) * image.height;
  char mp[32];
  std::snprintf(mp, sizeof mp, "%.1f", pixels / 1e6);
  if (pixels > limits.max_megapixels * 1e6)
    throw InvalidArgument(Message("image ", image.width, " x ", image.height, " px (", mp,
                                  " MP), more than max_megapixels ", limits.max_megapixels,
                                  "; refused before conversion"));
  if (image.width == 0 || image.height == 0)
    throw InvalidArgument(Message("image ", image.width, " x ", image.height, " px is empty"));
  const double bytes = static_cast<double>(image.step) * image.height;
  if (bytes != static_cast<double>(image.data.size()))
    throw InvalidArgument(Message("image ", image.width, " x ", image.height, " px: step ",
                                  image.step, " x height ", image.height, " = ", bytes,
                                  " bytes, but the message holds ", image.data.size()));
  int channels = 0, depth = 0;
  try {
    channels = sensor_msgs::image_encodings::numChannels(image.encoding);
    depth = sensor_msgs::image_encodings::bitDepth(image.encoding);
  } catch (const std::exception&) {
    return;  // an encoding cv_bridge does not know: refused by the conversion, by name
  }
  const double row = static_cast<double>(image.width) * channels * depth / 8.0;
  if (image.step < row)
    throw InvalidArgument(Message("image ", image.width, " x ", image.height, " px '",
                                  image.encoding, "': step ", image.step,
                                  " bytes is shorter than a row (", row, " bytes)"));
}

size_t MaxImageMessageBytes(const ImageMessageLimits& limits) {
  return static_cast<size_t>(limits.max_megapixels * 1e6 * 8.0) + (size_t{1} << 20);
}

}  // namespace ros_adapters
}  // namespace slope_monitor
