#include "slope_monitor/core/capture/photo_attitude.h"

#include <cmath>
#include <string>

// exiv2 0.27 still uses std::auto_ptr in its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

// One of the XMP keys as a number; false when none is present.
bool XmpNumber(const Exiv2::XmpData& xmp, std::initializer_list<const char*> keys,
               const std::string& path, double* out) {
  for (const char* key : keys) {
    for (const auto& d : xmp) {
      if (d.key() != key) continue;
      try {
        size_t used = 0;
        const std::string text = d.toString();
        *out = std::stod(text, &used);
        if (std::isfinite(*out)) return true;
      } catch (const std::exception&) {
      }
      throw IoError(Message(path, ": XMP tag ", key, " is not a number: '", d.toString(), "'"));
    }
  }
  return false;
}

}  // namespace

PhotoAttitude ReadPhotoAttitude(const std::string& path) {
  Exiv2::Image::AutoPtr image;
  try {
    image = Exiv2::ImageFactory::open(path);
    image->readMetadata();
  } catch (const Exiv2::AnyError& e) {
    throw IoError(Message(path, ": cannot read its metadata (", e.what(), ")"));
  }
  PhotoAttitude a;
  a.width = image->pixelWidth();
  a.height = image->pixelHeight();
  const Exiv2::XmpData& xmp = image->xmpData();
  // senseFly writes Yaw / Pitch / Roll, or (older eMotion) Heading /
  // PitchAngle / RollAngle and the Height above take-off.
  a.has_yaw = XmpNumber(xmp,
                        {"Xmp.sensefly.Yaw", "Xmp.sensefly.Heading",
                         "Xmp.drone-dji.FlightYawDegree", "Xmp.Camera.Yaw"},
                        path, &a.yaw_deg);
  a.has_pitch_roll = XmpNumber(xmp,
                               {"Xmp.sensefly.Pitch", "Xmp.sensefly.PitchAngle",
                                "Xmp.drone-dji.FlightPitchDegree", "Xmp.Camera.Pitch"},
                               path, &a.pitch_deg) &&
                     XmpNumber(xmp,
                               {"Xmp.sensefly.Roll", "Xmp.sensefly.RollAngle",
                                "Xmp.drone-dji.FlightRollDegree", "Xmp.Camera.Roll"},
                               path, &a.roll_deg);
  a.has_height_above_ground = XmpNumber(
      xmp,
      {"Xmp.drone-dji.RelativeAltitude", "Xmp.Camera.AboveGroundAltitude", "Xmp.sensefly.Height"},
      path, &a.height_above_ground_m);
  const Exiv2::ExifData& exif = image->exifData();
  const auto res = exif.findKey(Exiv2::ExifKey("Exif.Photo.FocalPlaneXResolution"));
  if (res != exif.end() && res->count() > 0) {
    const Exiv2::Rational r = res->toRational(0);
    long unit = 2;  // inch (the EXIF default)
    const auto u = exif.findKey(Exiv2::ExifKey("Exif.Photo.FocalPlaneResolutionUnit"));
    if (u != exif.end() && u->count() > 0) unit = u->toLong(0);
    const double unit_mm = unit == 3 ? 10.0 : unit == 4 ? 1.0 : unit == 5 ? 1e-3 : 25.4;
    if (r.first > 0 && r.second > 0) {
      a.has_pixel_size = true;
      a.pixel_size_mm = unit_mm * static_cast<double>(r.second) / static_cast<double>(r.first);
    }
  }
  return a;
}

Eigen::Quaterniond SiteFromOpticalNadir(double yaw_deg) {
  const double h = yaw_deg * M_PI / 180.0;
  Eigen::Matrix3d site_from_optical;
  site_from_optical.col(0) = Eigen::Vector3d(std::cos(h), -std::sin(h), 0.0);  // image right
  site_from_optical.col(1) =
      Eigen::Vector3d(-std::sin(h), -std::cos(h), 0.0);        // image down: backwards
  site_from_optical.col(2) = Eigen::Vector3d(0.0, 0.0, -1.0);  // viewing direction
  return Eigen::Quaterniond(site_from_optical);
}

}  // namespace capture
}  // namespace slope_monitor

#pragma GCC diagnostic pop
