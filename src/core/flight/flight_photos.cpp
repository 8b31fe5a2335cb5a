#include "slope_monitor/core/flight/flight_photos.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "slope_monitor/core/capture/calibration.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace flight {
namespace {

bool HasImageExtension(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return std::tolower(c); });
  return e == ".jpg" || e == ".jpeg" || e == ".png" || e == ".tif" || e == ".tiff";
}

// The camera of a photo: what must be equal for photos to share one model
// (the capture's folder scan uses the same rule).
capture::PhotoCamera KeyOf(const FlightPhoto& p) {
  return capture::PhotoCamera::Of(p.exif, p.width, p.height);
}

}  // namespace

void FlightPhotoOptions::Check() const {
  RequireOption("flight photo", pixel_size_mm >= 0.0 && std::isfinite(pixel_size_mm),
                "pixel_size_mm", "must be >= 0");
  image.Check();
  RequireOption("flight photo", focal_length_mm >= 0.0 && std::isfinite(focal_length_mm),
                "focal_length_mm", "must be >= 0");
}

std::vector<std::string> ListPhotoFolder(const std::string& folder) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(folder, ec)) throw IoError(Message(folder, ": no such folder"));
  if (!fs::is_directory(folder, ec)) throw IoError(Message(folder, ": not a folder"));
  std::vector<std::string> paths;
  for (const auto& e : fs::directory_iterator(folder, ec))
    if (e.is_regular_file() && HasImageExtension(e.path())) paths.push_back(e.path().string());
  if (ec) throw IoError(Message(folder, ": cannot be listed (", ec.message(), ")"));
  if (paths.empty())
    throw IoError(Message(folder, ": holds no photo (.jpg, .jpeg, .png, .tif, .tiff)"));
  std::sort(paths.begin(), paths.end());
  return paths;
}

FlightPhotos ReadFlightPhotos(const std::vector<std::string>& paths,
                              const FlightPhotoOptions& options) {
  options.Check();
  FlightPhotos out;
  out.options = options;
  std::vector<FlightPhoto> read;
  std::vector<std::string> prior_of;  // per photo read: its focal prior ("" none)
  for (const std::string& path : paths) {
    FlightPhoto p;
    p.path = path;
    p.name = std::filesystem::path(path).filename().string();
    try {
      io::CheckImageFile(path, options.image);
      p.exif = capture::ReadExif(path);
      p.attitude = capture::ReadPhotoAttitude(path);
    } catch (const std::exception& e) {
      out.skipped.push_back({path, Message("cannot be read as a photo: ", e.what())});
      continue;
    }
    p.width = p.attitude.width;
    p.height = p.attitude.height;
    if (p.width <= 0 || p.height <= 0) {
      out.skipped.push_back({path, "no image size in its header (not an image, or truncated)"});
      continue;
    }
    if (!(p.exif.focal_length_mm > 0.0)) p.exif.focal_length_mm = options.focal_length_mm;
    if (!(p.exif.focal_length_mm > 0.0)) {
      out.skipped.push_back({path, "no focal length in its EXIF (give the flight's focal length)"});
      continue;
    }
    if (!p.attitude.has_pixel_size) {
      p.attitude.pixel_size_mm = options.pixel_size_mm;
      p.attitude.has_pixel_size = options.pixel_size_mm > 0.0;
    }
    std::string prior;
    if (!p.attitude.has_pixel_size) {
      p.attitude.pixel_size_mm = capture::PixelSizePrior(p.exif, p.width, p.height, p.path, &prior);
      p.attitude.has_pixel_size = true;
    }
    read.push_back(p);
    prior_of.push_back(prior);
  }
  std::vector<capture::PhotoCamera> cameras;
  for (const FlightPhoto& p : read) cameras.push_back(KeyOf(p));
  const auto [main, main_count] = capture::MostCommonCamera(cameras);
  if (main_count == 0) {
    std::string why;
    for (size_t i = 0; i < out.skipped.size() && i < 3; ++i)
      why += Message(i ? "; " : "", out.skipped[i].path, ": ", out.skipped[i].reason);
    throw IoError(Message("none of the ", paths.size(), " photos can be used (", why, ")"));
  }
  out.camera_label = main.Describe();
  for (size_t i = 0; i < read.size(); ++i) {
    const FlightPhoto& p = read[i];
    if (KeyOf(p) != main) {
      out.skipped.push_back(
          {p.path, Message("another camera or size (", KeyOf(p).Describe(), ") than the flight's ",
                           main_count, " photos (", out.camera_label, ")")});
      continue;
    }
    out.with_gnss += p.exif.has_gps ? 1 : 0;
    out.with_yaw += p.attitude.has_yaw ? 1 : 0;
    if (out.photos.empty()) out.focal_prior = prior_of[i];
    out.photos.push_back(p);
  }
  const FlightPhoto& first = out.photos.front();
  out.nominal = capture::NominalModelFromExif(first.exif, first.width, first.height,
                                              first.attitude.pixel_size_mm, first.path);
  return out;
}

}  // namespace flight
}  // namespace slope_monitor
