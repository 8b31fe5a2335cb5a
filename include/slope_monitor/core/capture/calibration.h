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

// The pixel size [mm] of a camera whose EXIF has a focal length but no
// focal-plane resolution (phones, many DJI cameras), so that the nominal
// model's principal distance in pixels is a prior the adjustment refines:
// from the 35 mm equivalent focal length where EXIF has it (c_px = f35 /
// 43.27 mm x the image diagonal in px), else COLMAP's prior c_px = 1.2 x the
// larger image side. *source says which ("35 mm equivalent 24 mm" or
// "1.2 x the larger image side"). Throws InvalidArgument naming `file` when
// there is no focal length or the size is not positive.
double PixelSizePrior(const ExifInfo& exif, int width, int height, const std::string& file,
                      std::string* source);
// PixelSizePrior without a 35 mm equivalent: the principal distance in
// pixels taken as this x the larger image side.
inline constexpr double kFocalPriorOfLargerSide = 1.2;

// Converts camera_info fields to the collinearity model and back and checks
// the round trip reproduces K, D (5 plumb_bob terms) and the size to a
// relative 1e-9, and that the size matches the image (when width/height > 0).
// Returns the model. Throws InvalidArgument naming `context` and the field.
camera::CameraModel CheckCameraInfo(const camera::CameraInfoFields& info, double pixel_size,
                                    int image_width, int image_height, const std::string& context);

}  // namespace capture
}  // namespace slope_monitor
