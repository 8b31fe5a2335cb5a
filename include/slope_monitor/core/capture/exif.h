// EXIF metadata of survey photos, read with exiv2: capture time, camera
// make/model, focal length and the GNSS position written by the camera/UAV.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "slope_monitor/core/capture/geodesy.h"

namespace slope_monitor {
namespace capture {

// The 1-sigma of a photo's EXIF GNSS position (a consumer receiver in the
// aircraft): the one default of the capture's position priors
// (camera_capture) and of process_flight's (flight_orientation.h).
inline constexpr double kExifGnssSigmaHorizontal = 3.0;  // [m] east, north
inline constexpr double kExifGnssSigmaVertical = 6.0;    // [m] up

struct ExifInfo {
  // Exif.Photo.DateTimeOriginal (+ SubSecTimeOriginal), read as UTC; when
  // Exif.Photo.OffsetTimeOriginal ("+09:00") is present it is removed so the
  // value is true UTC. [s since the Unix epoch]
  bool has_time = false;
  double time = 0.0;
  bool time_zone_applied = false;  // OffsetTimeOriginal was present and used

  std::string make;              // Exif.Image.Make ("" when absent)
  std::string model;             // Exif.Image.Model
  double focal_length_mm = 0.0;  // Exif.Photo.FocalLength [mm]; 0 when absent
  // Exif.Photo.FocalLengthIn35mmFilm [mm]: the focal length a 36 x 24 mm
  // frame would need for the same angle of view (diagonal); 0 when absent.
  double focal_length_35mm = 0.0;

  // Exif.GPSInfo.GPSLatitude/GPSLongitude (deg/min/sec with N/S, E/W refs)
  // and GPSAltitude (with GPSAltitudeRef: 0 above, 1 below sea level) [m].
  bool has_gps = false;
  bool has_gps_altitude = false;
  Geodetic gps;  // height_m is the EXIF altitude (usually above sea level)
};

// Reads the EXIF block of an image file. Throws IoError naming the file when
// exiv2 cannot open or parse it; a file without EXIF gives an empty ExifInfo.
// A malformed individual tag (e.g. an unparsable date) throws IoError naming
// the file and the tag.
ExifInfo ReadExif(const std::string& path);

// The camera a photo was taken with, as a flight tells its photos apart:
// photos share one camera model only when all of this is equal (EXIF make
// and model, the image size, the focal length to 0.01 mm). One rule for the
// capture's folder scan and process_flight (flight_photos.cc): a photo of
// another camera or size is left out of the flight, named with Describe().
struct PhotoCamera {
  std::string make, model;
  int width = 0, height = 0;
  long focal_centi_mm = 0;  // EXIF focal length [0.01 mm]; 0 when absent

  static PhotoCamera Of(const ExifInfo& exif, int width, int height);
  // "Canon Canon PowerShot S100 4000x3000 f=5.2 mm" ("unknown camera" without make and model).
  std::string Describe() const;
  bool operator<(const PhotoCamera& o) const;
  bool operator==(const PhotoCamera& o) const { return !(*this < o) && !(o < *this); }
  bool operator!=(const PhotoCamera& o) const { return !(*this == o); }
};

// The camera most of `cameras` share (on a tie the first in PhotoCamera
// order) and how many photos it has; {PhotoCamera(), 0} for none.
std::pair<PhotoCamera, int> MostCommonCamera(const std::vector<PhotoCamera>& cameras);

// "YYYY:MM:DD HH:MM:SS" (+ sub-second digits "123" = 0.123 s) as UTC -> s since
// the Unix epoch. Throws InvalidArgument naming `context` and the text.
double ParseExifDateTime(const std::string& text, const std::string& subsec,
                         const std::string& context);

// "+09:00" / "-05:30" -> seconds east of UTC. Throws InvalidArgument.
double ParseExifTimeOffset(const std::string& text, const std::string& context);

}  // namespace capture
}  // namespace slope_monitor
