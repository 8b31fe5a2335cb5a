// The photos of one flight (a crew's folder, or the images of one UAV epoch):
// which are used, and the camera they share.
//
// A flight is taken by one camera at one image size. The photos are read in
// name order; the camera is the one most photos share (make, model, width,
// height, focal length from EXIF); a photo of another camera or size, one
// without a readable header, and one that is not an image are left out, each
// named with the reason (FlightPhotos::skipped). The nominal camera model
// (the adjustment's start for self-calibration): principal distance = EXIF
// focal length, principal point at the centre, no distortion yet; pixel size
// from EXIF FocalPlaneXResolution, else FlightPhotoOptions::pixel_size_mm,
// else a prior from the 35 mm equivalent focal length or 1.2 x the larger
// image side (FlightPhotos::focal_prior says which).
// GNSS positions (EXIF) and the autopilot's attitude (XMP) are kept per photo.
// Each file is checked whole first (io::CheckImageFile): an empty,
// truncated or damaged photo, or one whose header claims more pixels than
// the budget, is named and left out without being decoded.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/capture/photo_attitude.h"
#include "slope_monitor/core/io/image_file.h"

namespace slope_monitor {
namespace flight {

struct FlightPhotoOptions {
  // [mm] pixel size of a camera whose EXIF has no FocalPlaneXResolution (0:
  // a prior from the focal length, capture::PixelSizePrior, which the
  // orientation self-calibrates), >= 0.
  double pixel_size_mm = 0.0;
  // [mm] focal length of a camera whose EXIF has none (0: such photos are
  // named and left out), >= 0.
  double focal_length_mm = 0.0;
  // Every photo is checked whole before use (io::CheckImageFile: header,
  // truncation, pixel budget); one that fails is named and left out.
  io::ImageFileOptions image;
  void Check() const;  // throws ConfigError naming the field
};

struct FlightPhoto {
  std::string path;
  std::string name;  // file name without folder
  int width = 0, height = 0;
  capture::ExifInfo exif;
  capture::PhotoAttitude attitude;
};

struct SkippedPhoto {
  std::string path;
  std::string reason;
};

struct FlightPhotos {
  std::vector<FlightPhoto> photos;  // used, in name order
  std::vector<SkippedPhoto> skipped;
  camera::CameraModel nominal;  // the shared camera's nominal model
  std::string camera_label;     // "Canon EOS DIGITAL REBEL XSi 4272x2848 f=18 mm"
  int with_gnss = 0;            // photos with an EXIF position
  int with_yaw = 0;             // photos with the autopilot's heading
  FlightPhotoOptions options;   // as read with
  // Where the principal distance in pixels comes from: "" (EXIF focal
  // length and focal-plane resolution, or the options' pixel size), else the
  // prior (capture::PixelSizePrior's source), which the orientation frees
  // from the start.
  std::string focal_prior;
};

// Image files of a folder (.jpg .jpeg .png .tif .tiff, any case), sorted by
// name. Throws IoError naming the folder when it is missing, not a folder, or
// holds no image file.
std::vector<std::string> ListPhotoFolder(const std::string& folder);

// Reads the headers and EXIF/XMP of the photos (nothing is decoded). Throws
// IoError when no photo is usable (the message says why, naming the first
// few); otherwise the unusable ones are in `skipped`.
FlightPhotos ReadFlightPhotos(const std::vector<std::string>& paths,
                              const FlightPhotoOptions& options = {});

}  // namespace flight
}  // namespace slope_monitor
