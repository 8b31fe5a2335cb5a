// Calibration of captured images: the camera_info published with each image
// and the package's collinearity parameters (camera::CameraModel) are kept
// consistent through CameraModel::ToCameraInfo / FromCameraInfo.
//
// Three ways to the published camera_info, in this order of precedence:
//   1. a camera_info_manager URL (file://...yaml): checked here to be
//      representable by the collinearity model (CheckCameraInfo);
//   2. the package's interior parameters (interior[10], camera_model.h units,
//      with the sensor pixel size): CameraModel::ToCameraInfo;
//   3. a nominal model from the EXIF focal length and the pixel size
//      (NominalModelFromExif): principal point at the image centre, no distortion.
#pragma once

#include <string>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/capture/exif.h"

namespace slope_monitor {
namespace capture {

// Nominal camera: c = EXIF focal length [mm], x0 = y0 = 0, no distortion.
// Throws InvalidArgument naming `file` when there is no focal length, or the
// size / pixel size is not positive.
camera::CameraModel NominalModelFromExif(const ExifInfo& exif, int width, int height,
                                         double pixel_size, const std::string& file);

// Converts camera_info fields to the collinearity model and back and checks
// the round trip reproduces K, D (5 plumb_bob terms) and the size to a
// relative 1e-9, and that the size matches the image (when width/height > 0).
// Returns the model. Throws InvalidArgument naming `context` and the field.
camera::CameraModel CheckCameraInfo(const camera::CameraInfoFields& info, double pixel_size,
                                    int image_width, int image_height, const std::string& context);

}  // namespace capture
}  // namespace slope_monitor
