// What a UAV writes about a photo beyond exif.h, read with exiv2: the
// autopilot's attitude in the XMP block and the sensor's pixel size.
//
//   * attitude: sensefly (Xmp.sensefly.Yaw/Pitch/Roll), DJI
//     (Xmp.drone-dji.FlightYawDegree/FlightPitchDegree/FlightRollDegree) and
//     Pix4D-style camera tags (Xmp.Camera.Yaw/Pitch/Roll) [deg], yaw = heading
//     clockwise from north;
//   * pixel size [mm] from Exif.Photo.FocalPlaneXResolution and
//     FocalPlaneResolutionUnit (2 inch, 3 cm, 4 mm, 5 um), divided into the
//     unit's length. Cameras write it for the full sensor width
//     (Exif.Photo.PixelXDimension pixels);
//   * the flying height above the take-off point [m]: DJI
//     (Xmp.drone-dji.RelativeAltitude, written as "+68.20") and Pix4D-style
//     camera tags (Xmp.Camera.AboveGroundAltitude); GNSS heights are above
//     the ellipsoid or sea level and say nothing about the ground;
//   * the image size from its header (without decoding the pixels).
#pragma once

#include <string>

#include <Eigen/Geometry>

namespace slope_monitor {
namespace capture {

struct PhotoAttitude {
  bool has_yaw = false;
  double yaw_deg = 0.0;  // [deg] heading, clockwise from north
  bool has_pitch_roll = false;
  double pitch_deg = 0.0;  // [deg]
  double roll_deg = 0.0;   // [deg]
  bool has_pixel_size = false;
  double pixel_size_mm = 0.0;  // [mm]
  bool has_height_above_ground = false;
  double height_above_ground_m = 0.0;  // [m] the autopilot's relative altitude
  int width = 0;                       // [px] from the image header (exiv2), 0 when unknown
  int height = 0;                      // [px]
};

// Throws IoError naming the file when exiv2 cannot open it, or when a tag
// present is not a number (naming the tag). Absent tags leave has_* false.
PhotoAttitude ReadPhotoAttitude(const std::string& path);

// The rotation site_from_optical of a nadir photo whose top edge points along
// the heading `yaw_deg` (clockwise from north; site x east, y north, z up):
// optical z down, y (image down) backwards, x (image right) to the right of
// the flight direction. The autopilot's pitch and roll are not used (how the
// camera sits in the airframe is not in the photo).
Eigen::Quaterniond SiteFromOpticalNadir(double yaw_deg);

}  // namespace capture
}  // namespace slope_monitor
