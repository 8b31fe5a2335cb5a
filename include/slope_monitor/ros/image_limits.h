// Image messages checked before any conversion (bounded memory on any
// input). A sensor_msgs/Image whose header claims more pixels than
// max_megapixels, or whose header does not describe its data (step * height
// != data size, step shorter than a row), is refused before cv_bridge or any
// step touches it: a message forged or broken in a bag, or sent on the site
// network, costs at most its own bytes.
//
//   ros_adapters::CheckImageMessage(image);  // throws InvalidArgument, e.g.
//   // image 20000 x 20000 px (400.0 MP), more than max_megapixels 100
//
// process_bag checks each image record's size in the bag (MaxImageMessageBytes)
// before reading it, and the header after; the conversions the nodelets use
// (target_conversions, sequence_conversions, dense_conversions, the dense and
// targetless steps) check the header with the default limit.
#pragma once

#include <cstddef>
#include <string>

#include <sensor_msgs/Image.h>

#include "slope_monitor/core/io/image_file.h"

namespace slope_monitor {
namespace ros_adapters {

struct ImageMessageLimits {
  // [MP, 1e6 px] largest width x height accepted: the image files' limit
  // (io::ImageFileOptions), the largest camera crews use. > 0.
  double max_megapixels = io::ImageFileOptions().max_megapixels;
  void Check() const;  // ConfigError naming max_megapixels
};

// Throws InvalidArgument giving the size and the reason (see the file comment).
void CheckImageMessage(const sensor_msgs::Image& image,
                       const ImageMessageLimits& limits = ImageMessageLimits());

// The largest serialised sensor_msgs/Image within the limits [bytes]: 8
// bytes per pixel (rgba16, 64FC1) plus 1 MiB for the header and encoding.
size_t MaxImageMessageBytes(const ImageMessageLimits& limits = ImageMessageLimits());

}  // namespace ros_adapters
}  // namespace slope_monitor
