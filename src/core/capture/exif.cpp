#include "slope_monitor/core/capture/exif.h"

#include <cctype>
#include <cmath>
#include <ctime>
#include <map>
#include <tuple>

// exiv2 0.27 still uses std::auto_ptr in its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace {

std::string Trim(std::string s) {
  while (!s.empty() && (std::isspace(static_cast<unsigned char>(s.back())) || s.back() == '\0'))
    s.pop_back();
  size_t i = 0;
  while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
  return s.substr(i);
}

bool FindString(const Exiv2::ExifData& exif, const char* key, std::string* out) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end()) return false;
  *out = Trim(it->toString());
  return !out->empty();
}

double RationalAt(const Exiv2::Exifdatum& d, long i, const std::string& path) {
  const Exiv2::Rational r = d.toRational(i);
  if (r.second == 0) {
    throw IoError(Message(path, ": EXIF tag ", d.key(), " element ", i, " has a zero denominator"));
  }
  return static_cast<double>(r.first) / static_cast<double>(r.second);
}

// deg/min/sec triplet with a ref ("N"/"S" or "E"/"W") -> signed degrees.
bool ReadAngle(const Exiv2::ExifData& exif, const char* key, const char* ref_key,
               const char* negative_ref, const std::string& path, double* deg) {
  const auto it = exif.findKey(Exiv2::ExifKey(key));
  if (it == exif.end()) return false;
  if (it->count() != 3) {
    throw IoError(Message(path, ": EXIF tag ", key, " has ", it->count(),
                          " values, expected 3 (deg min sec)"));
  }
  double value = RationalAt(*it, 0, path) + RationalAt(*it, 1, path) / 60.0 +
                 RationalAt(*it, 2, path) / 3600.0;
  std::string ref;
  if (!FindString(exif, ref_key, &ref)) {
    throw IoError(Message(path, ": EXIF tag ", key, " is present but ", ref_key, " is missing"));
  }
  if (ref == negative_ref) value = -value;
  *deg = value;
  return true;
}

}  // namespace

double ParseExifDateTime(const std::string& text, const std::string& subsec,
                         const std::string& context) {
  std::tm tm{};
  int consumed = 0;
  const std::string t = Trim(text);
  if (std::sscanf(t.c_str(), "%4d:%2d:%2d %2d:%2d:%2d%n", &tm.tm_year, &tm.tm_mon, &tm.tm_mday,
                  &tm.tm_hour, &tm.tm_min, &tm.tm_sec, &consumed) != 6 ||
      consumed != static_cast<int>(t.size()) || tm.tm_year < 1970 || tm.tm_mon < 1 ||
      tm.tm_mon > 12 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23 || tm.tm_min > 59 ||
      tm.tm_sec > 60) {
    throw InvalidArgument(
        Message(context, ": date/time '", text, "' is not 'YYYY:MM:DD HH:MM:SS'"));
  }
  tm.tm_year -= 1900;
  tm.tm_mon -= 1;
  double seconds = static_cast<double>(timegm(&tm));
  const std::string s = Trim(subsec);
  if (!s.empty()) {
    double scale = 0.1;
    for (char ch : s) {
      if (!std::isdigit(static_cast<unsigned char>(ch))) {
        throw InvalidArgument(
            Message(context, ": sub-second time '", subsec, "' is not a digit string"));
      }
      seconds += scale * (ch - '0');
      scale *= 0.1;
    }
  }
  return seconds;
}

double ParseExifTimeOffset(const std::string& text, const std::string& context) {
  int h = 0, m = 0, consumed = 0;
  char sign = 0;
  const std::string t = Trim(text);
  if (std::sscanf(t.c_str(), "%c%2d:%2d%n", &sign, &h, &m, &consumed) != 3 ||
      consumed != static_cast<int>(t.size()) || (sign != '+' && sign != '-') || h > 14 || m > 59) {
    throw InvalidArgument(
        Message(context, ": time offset '", text, "' is not '+HH:MM' or '-HH:MM'"));
  }
  return (sign == '-' ? -1.0 : 1.0) * (3600.0 * h + 60.0 * m);
}

PhotoCamera PhotoCamera::Of(const ExifInfo& exif, int width, int height) {
  PhotoCamera c;
  c.make = exif.make;
  c.model = exif.model;
  c.width = width;
  c.height = height;
  c.focal_centi_mm = std::lround(exif.focal_length_mm * 100.0);
  return c;
}

std::string PhotoCamera::Describe() const {
  const std::string name = Message(make, make.empty() ? "" : " ", model);
  return Message(name.empty() ? "unknown camera" : name, " ", width, "x", height,
                 " f=", focal_centi_mm / 100.0, " mm");
}

bool PhotoCamera::operator<(const PhotoCamera& o) const {
  return std::tie(make, model, width, height, focal_centi_mm) <
         std::tie(o.make, o.model, o.width, o.height, o.focal_centi_mm);
}

std::pair<PhotoCamera, int> MostCommonCamera(const std::vector<PhotoCamera>& cameras) {
  std::map<PhotoCamera, int> count;
  for (const PhotoCamera& c : cameras) ++count[c];
  std::pair<PhotoCamera, int> most{PhotoCamera(), 0};
  for (const auto& [camera, n] : count)
    if (n > most.second) most = {camera, n};
  return most;
}

ExifInfo ReadExif(const std::string& path) {
  ExifInfo info;
  Exiv2::ExifData exif;
  try {
    auto image = Exiv2::ImageFactory::open(path);
    if (image.get() == nullptr) throw IoError(Message(path, ": exiv2 cannot open the file"));
    image->readMetadata();
    exif = image->exifData();
  } catch (const Exiv2::AnyError& e) {
    throw IoError(Message(path, ": cannot read EXIF metadata (", e.what(), ")"));
  }
  if (exif.empty()) return info;

  std::string dt, subsec, offset;
  if (FindString(exif, "Exif.Photo.DateTimeOriginal", &dt)) {
    FindString(exif, "Exif.Photo.SubSecTimeOriginal", &subsec);
    try {
      info.time = ParseExifDateTime(dt, subsec, path + " Exif.Photo.DateTimeOriginal");
      if (FindString(exif, "Exif.Photo.OffsetTimeOriginal", &offset)) {
        info.time -= ParseExifTimeOffset(offset, path + " Exif.Photo.OffsetTimeOriginal");
        info.time_zone_applied = true;
      }
    } catch (const InvalidArgument& e) {
      throw IoError(e.what());
    }
    info.has_time = true;
  }
  FindString(exif, "Exif.Image.Make", &info.make);
  FindString(exif, "Exif.Image.Model", &info.model);
  const auto fl = exif.findKey(Exiv2::ExifKey("Exif.Photo.FocalLength"));
  if (fl != exif.end() && fl->count() >= 1) info.focal_length_mm = RationalAt(*fl, 0, path);
  const auto f35 = exif.findKey(Exiv2::ExifKey("Exif.Photo.FocalLengthIn35mmFilm"));
  if (f35 != exif.end() && f35->count() >= 1 && f35->toLong(0) > 0)
    info.focal_length_35mm = static_cast<double>(f35->toLong(0));

  double lat = 0.0, lon = 0.0;
  const bool has_lat =
      ReadAngle(exif, "Exif.GPSInfo.GPSLatitude", "Exif.GPSInfo.GPSLatitudeRef", "S", path, &lat);
  const bool has_lon =
      ReadAngle(exif, "Exif.GPSInfo.GPSLongitude", "Exif.GPSInfo.GPSLongitudeRef", "W", path, &lon);
  if (has_lat != has_lon) {
    throw IoError(Message(path, ": EXIF has only one of GPSLatitude and GPSLongitude"));
  }
  if (has_lat) {
    info.has_gps = true;
    info.gps.latitude_deg = lat;
    info.gps.longitude_deg = lon;
    const auto alt = exif.findKey(Exiv2::ExifKey("Exif.GPSInfo.GPSAltitude"));
    if (alt != exif.end() && alt->count() >= 1) {
      double h = RationalAt(*alt, 0, path);
      const auto ref = exif.findKey(Exiv2::ExifKey("Exif.GPSInfo.GPSAltitudeRef"));
      if (ref != exif.end() && ref->count() >= 1 && ref->toLong(0) == 1) h = -h;
      info.gps.height_m = h;
      info.has_gps_altitude = true;
    }
    try {
      CheckGeodetic(info.gps, (path + " EXIF GPS").c_str());
    } catch (const InvalidArgument& e) {
      throw IoError(e.what());
    }
  }
  return info;
}

}  // namespace capture
}  // namespace slope_monitor
#pragma GCC diagnostic pop
