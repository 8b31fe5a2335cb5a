#include "slope_monitor/core/capture/calibration.h"

#include <algorithm>
#include <cmath>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {

camera::CameraModel NominalModelFromExif(const ExifInfo& exif, int width, int height,
                                         double pixel_size, const std::string& file) {
  if (!(exif.focal_length_mm > 0.0)) {
    throw InvalidArgument(
        Message(file, ": no EXIF focal length (Exif.Photo.FocalLength) for a nominal camera_info"));
  }
  if (width <= 0 || height <= 0 || !(pixel_size > 0.0)) {
    throw InvalidArgument(Message(file, ": nominal camera needs a positive size (", width, "x",
                                  height, ") and pixel_size (", pixel_size, " mm)"));
  }
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = exif.focal_length_mm;
  camera::CameraModel model(camera::Sensor{width, height, pixel_size},
                            camera::DistortionModel::kNone, interior);
  model.Check();
  return model;
}

double PixelSizePrior(const ExifInfo& exif, int width, int height, const std::string& file,
                      std::string* source) {
  if (!(exif.focal_length_mm > 0.0) || width <= 0 || height <= 0) {
    throw InvalidArgument(Message(file, ": a pixel size prior needs the EXIF focal length (",
                                  exif.focal_length_mm, " mm) and the image size (", width, "x",
                                  height, ")"));
  }
  double c_px = kFocalPriorOfLargerSide * std::max(width, height);
  *source = Message(kFocalPriorOfLargerSide, " x the larger image side");
  if (exif.focal_length_35mm > 0.0) {
    const double diagonal_35mm = std::hypot(36.0, 24.0);
    c_px = exif.focal_length_35mm / diagonal_35mm * std::hypot(width, height);
    *source = Message("35 mm equivalent ", exif.focal_length_35mm, " mm");
  }
  return exif.focal_length_mm / c_px;
}

camera::CameraModel CheckCameraInfo(const camera::CameraInfoFields& info, double pixel_size,
                                    int image_width, int image_height, const std::string& context) {
  if (image_width > 0 && image_height > 0 &&
      (info.width != image_width || info.height != image_height)) {
    throw InvalidArgument(Message(context, ": camera_info size ", info.width, "x", info.height,
                                  " differs from the image size ", image_width, "x", image_height));
  }
  camera::CameraModel model;
  try {
    model = camera::CameraModel::FromCameraInfo(info, pixel_size);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(Message(context, ": ", e.what()));
  }
  const camera::CameraInfoFields back = model.ToCameraInfo();
  auto close = [](double a, double b) {
    return std::abs(a - b) <= 1e-9 * std::max(1.0, std::abs(a) + std::abs(b));
  };
  for (int i = 0; i < 9; ++i) {
    if (!close(info.k[i], back.k[i])) {
      throw InvalidArgument(Message(context, ": camera_info K[", i, "] = ", info.k[i],
                                    " does not survive the collinearity round trip (", back.k[i],
                                    ")"));
    }
  }
  for (size_t i = 0; i < back.d.size(); ++i) {
    const double d = i < info.d.size() ? info.d[i] : 0.0;
    if (!close(d, back.d[i])) {
      throw InvalidArgument(Message(context, ": camera_info D[", i, "] = ", d,
                                    " does not survive the collinearity round trip (", back.d[i],
                                    ")"));
    }
  }
  return model;
}

}  // namespace capture
}  // namespace slope_monitor
