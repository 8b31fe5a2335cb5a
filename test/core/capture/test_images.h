// Test helpers: textured images, JPEGs written with cv::imwrite and EXIF tags
// written with exiv2 directly (independently of the reader under test), temp
// directories. Header-only, shared by the capture tests (core and ROS side).
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>

namespace slope_monitor {
namespace capture_test {

constexpr double kMay1st10h = 1714557600.0;  // 2024-05-01 10:00:00 UTC (date -u -d ... +%s)

// A temporary directory removed on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    std::string pattern =
        (std::filesystem::temp_directory_path() / ("sm_capture_" + tag + "_XXXXXX")).string();
    std::vector<char> buf(pattern.begin(), pattern.end());
    buf.push_back('\0');
    if (mkdtemp(buf.data()) == nullptr) throw std::runtime_error("mkdtemp failed for " + pattern);
    path_ = buf.data();
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

// A deterministic textured image: a smooth gradient plus a checker pattern
// whose phase depends on `seed`, and a constant level offset `level`.
inline cv::Mat TexturedImage(int width, int height, int channels, int seed, int level = 0) {
  cv::Mat img(height, width, channels == 1 ? CV_8UC1 : CV_8UC3);
  for (int r = 0; r < height; ++r) {
    for (int c = 0; c < width; ++c) {
      const int checker = (((r + seed) / 16 + (c + 3 * seed) / 16) % 2) * 60;
      const int v =
          std::min(255, std::max(0, level + (r * 100) / height + (c * 60) / width + checker));
      if (channels == 1) {
        img.at<uint8_t>(r, c) = static_cast<uint8_t>(v);
      } else {
        img.at<cv::Vec3b>(r, c) = cv::Vec3b(static_cast<uint8_t>(v), static_cast<uint8_t>(255 - v),
                                            static_cast<uint8_t>((v + 7 * seed) % 256));
      }
    }
  }
  return img;
}

struct ExifTags {
  std::string date_time;  // "YYYY:MM:DD HH:MM:SS"; empty: not written
  std::string subsec;     // "25" = 0.25 s
  std::string offset;     // "+09:00"; empty: not written
  std::string make, model;
  int focal_num = 0, focal_den = 1;  // FocalLength rational; 0/1: not written
  // FocalPlaneXResolution [pixels per unit] and its unit (2 inch, 3 cm, 4 mm); 0: not written
  int focal_plane_x_resolution = 0, focal_plane_unit = 4;
  bool gps = false;
  double lat_deg = 0.0, lon_deg = 0.0;  // signed
  double alt_m = 0.0;                   // signed (below sea level negative)
};

// "d/1 m/1 s*10000/10000" for a positive angle.
inline std::string DmsRational(double deg) {
  deg = std::abs(deg);
  const int d = static_cast<int>(deg);
  const double mf = (deg - d) * 60.0;
  const int m = static_cast<int>(mf);
  const long s = std::lround((mf - m) * 60.0 * 10000.0);
  return std::to_string(d) + "/1 " + std::to_string(m) + "/1 " + std::to_string(s) + "/10000";
}

// Writes the tags into an existing image file with exiv2.
inline void WriteExifTags(const std::string& path, const ExifTags& t) {
  auto image = Exiv2::ImageFactory::open(path);
  image->readMetadata();
  Exiv2::ExifData& exif = image->exifData();
  if (!t.date_time.empty()) exif["Exif.Photo.DateTimeOriginal"] = t.date_time;
  if (!t.subsec.empty()) exif["Exif.Photo.SubSecTimeOriginal"] = t.subsec;
  if (!t.offset.empty()) exif["Exif.Photo.OffsetTimeOriginal"] = t.offset;
  if (!t.make.empty()) exif["Exif.Image.Make"] = t.make;
  if (!t.model.empty()) exif["Exif.Image.Model"] = t.model;
  if (t.focal_num > 0) exif["Exif.Photo.FocalLength"] = Exiv2::Rational(t.focal_num, t.focal_den);
  if (t.focal_plane_x_resolution > 0) {
    exif["Exif.Photo.FocalPlaneXResolution"] = Exiv2::Rational(t.focal_plane_x_resolution, 1);
    exif["Exif.Photo.FocalPlaneResolutionUnit"] = static_cast<uint16_t>(t.focal_plane_unit);
  }
  if (t.gps) {
    exif["Exif.GPSInfo.GPSVersionID"] = "2 3 0 0";
    exif["Exif.GPSInfo.GPSLatitudeRef"] = t.lat_deg >= 0 ? "N" : "S";
    exif["Exif.GPSInfo.GPSLatitude"] = DmsRational(t.lat_deg);
    exif["Exif.GPSInfo.GPSLongitudeRef"] = t.lon_deg >= 0 ? "E" : "W";
    exif["Exif.GPSInfo.GPSLongitude"] = DmsRational(t.lon_deg);
    exif["Exif.GPSInfo.GPSAltitudeRef"] = t.alt_m >= 0 ? "0" : "1";
    exif["Exif.GPSInfo.GPSAltitude"] =
        Exiv2::Rational(static_cast<int>(std::lround(std::abs(t.alt_m) * 1000)), 1000);
  }
  image->setExifData(exif);
  image->writeMetadata();
}

// Writes a JPEG (quality 95) and its EXIF tags.
inline void WriteJpeg(const std::string& path, const cv::Mat& img, const ExifTags& tags) {
  if (!cv::imwrite(path, img, {cv::IMWRITE_JPEG_QUALITY, 95}))
    throw std::runtime_error("imwrite failed: " + path);
  WriteExifTags(path, tags);
}

// Copies the first `fraction` of a file's bytes to `dst` (a truncated file).
inline void WriteTruncatedCopy(const std::string& src, const std::string& dst, double fraction) {
  std::ifstream in(src, std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream out(dst, std::ios::binary);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size() * fraction));
}

inline void WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

// Sets a file's modification time [s since the Unix epoch].
inline void SetFileTime(const std::string& path, double t) {
  struct timespec ts[2];
  ts[0].tv_sec = ts[1].tv_sec = static_cast<time_t>(std::floor(t));
  ts[0].tv_nsec = ts[1].tv_nsec = static_cast<long>((t - std::floor(t)) * 1e9);
  if (utimensat(AT_FDCWD, path.c_str(), ts, 0) != 0)
    throw std::runtime_error("utimensat failed: " + path);
}

// Mean absolute difference of two images of the same size and type.
inline double MeanAbsDiff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  const cv::Scalar m = cv::mean(d);
  double s = 0;
  for (int i = 0; i < a.channels(); ++i) s += m[i];
  return s / a.channels();
}

}  // namespace capture_test
}  // namespace slope_monitor
#pragma GCC diagnostic pop
