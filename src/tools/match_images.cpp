// match_images: tie points between the overlapping photos of a crew's folder
// with the package's photo pair matcher (core/matching/photo_pair_matcher.h).
//
//   rosrun slope_monitor match_images --image A.jpg --image B.jpg [--image C.jpg ...] [--out
//   tie_points.csv]
//
// Pairs: by footprint overlap from the EXIF GNSS position, the XMP heading
// (sensefly / DJI / Camera yaw), the EXIF focal length and pixel size
// (FocalPlaneXResolution) and a flying height of
// PairSelectionOptions::height_above_ground; every pair that has a photo
// without them. Each photo's features are computed once and reused for all
// its pairs. Prints one line per pair
//   <A> <B>: <N> tie points, epipolar rms <r> px, <t> s
// (r: RMS distance to the epipolar lines of a RANSAC fundamental matrix of
// the tie points, cv::findFundamentalMat; t: the pair's matching time), then
//   total: <P> pairs, <N> tie points, epipolar rms <r> px, <t> s (features <f> s for <k> photos)
// --out writes CSV: image_a,image_b,xa,ya,xb,yb,cov_xx,cov_xy,cov_yy,quality
// (full-resolution OpenCV pixels; covariance of xb in px^2).
// Every photo is checked before it is used (io::CheckImageFile,
// core/io/image_file.h): missing, empty, not a JPEG/PNG/TIFF/PGM by its
// content, a header claiming more than --max-megapixels (default 100) or a
// truncated or damaged JPEG/PNG is named with the reason and left out:
//   match_images: skipped image 'IMG_2.JPG': truncated JPEG: the data ends at byte ...
// and the other photos are matched.
// Exit status: 0 every photo read and tie points found; 2 some photos
// skipped, the others matched with tie points; 1 fewer than two readable
// photos, no tie point at all, a usage error or an unwritable --out.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/capture/photo_attitude.h"
#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_file.h"
#include "slope_monitor/core/matching/photo_pair_matcher.h"

using namespace slope_monitor;

namespace {

int Usage(const std::string& why, std::ostream& out = std::cerr) {  // --help: std::cout
  out << "match_images: " << why << "\n"
      << "usage: match_images --image A.jpg --image B.jpg [--image C.jpg ...] [--out "
         "tie_points.csv] [--max-megapixels MP]\n"
         "exit status: 0 all read, 2 some photos skipped, 1 nothing matched or an error\n";
  return 1;
}

struct Photo {
  std::string path;
  matching::PhotoFootprint
      footprint;  // has_position false without GNSS, focal length or pixel size
};

// Checks each photo (io::CheckImageFile) and reads its EXIF/XMP pose; a
// photo that fails the check is named with the reason on stderr and left
// out (counted in *skipped). Photos without GNSS pair with every other.
std::vector<Photo> ReadPhotos(const std::vector<std::string>& paths,
                              const matching::PairSelectionOptions& selection,
                              const io::ImageFileOptions& image_options, int* skipped) {
  std::vector<Photo> photos;
  std::optional<capture::LocalTangentPlane> ltp;
  for (const std::string& path : paths) {
    try {
      const io::ImageHeader header = io::CheckImageFile(path, image_options);
      const std::string note = io::FormatNote(path, header);
      if (!note.empty()) std::cerr << "match_images: note: " << note << "\n";
    } catch (const IoError& e) {
      std::cerr << "match_images: skipped " << e.what() << "\n";
      ++*skipped;
      continue;
    }
    Photo p;
    p.path = path;
    capture::ExifInfo exif;
    capture::PhotoAttitude att;
    try {
      exif = capture::ReadExif(path);
      att = capture::ReadPhotoAttitude(path);
    } catch (const Error& e) {
      std::cerr << "match_images: " << e.what() << " (paired with every other photo)\n";
    }
    if (exif.has_gps && exif.focal_length_mm > 0.0 && att.has_pixel_size && att.width > 0 &&
        att.height > 0) {
      const capture::Geodetic g{exif.gps.latitude_deg, exif.gps.longitude_deg, 0.0};
      if (!ltp) ltp.emplace(g);
      p.footprint = matching::NadirFootprint(ltp->ToSite(g).head<2>(), att.has_yaw, att.yaw_deg,
                                             cv::Size(att.width, att.height), exif.focal_length_mm,
                                             att.pixel_size_mm, selection);
    }
    photos.push_back(p);
  }
  return photos;
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  std::vector<std::string> paths;
  std::string out_path;
  io::ImageFileOptions image_options;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if ((a == "--image" || a == "--out" || a == "--max-megapixels") && i + 1 >= argc)
      return Usage(a + " needs a value");
    if (a == "--image") {
      paths.push_back(argv[++i]);
    } else if (a == "--out") {
      out_path = argv[++i];
    } else if (a == "--max-megapixels") {
      const std::string v = argv[++i];
      char* end = nullptr;
      image_options.max_megapixels = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !(image_options.max_megapixels > 0))
        return Usage("--max-megapixels '" + v + "' is not a number > 0");
    } else if (a == "-h" || a == "--help") {
      Usage("tie points between overlapping photos", std::cout);
      return 0;
    } else {
      return Usage("unknown argument '" + a + "'");
    }
  }
  if (paths.size() < 2) {
    return Usage(paths.empty()
                     ? "no --image given (two or more are needed)"
                     : "only one --image given (" + paths[0] + "): two or more are needed");
  }
  try {
    const matching::PhotoFeatureOptions feature_options;
    const matching::PhotoPairOptions pair_options;
    const matching::PairSelectionOptions selection;
    int skipped = 0;
    const std::vector<Photo> photos = ReadPhotos(paths, selection, image_options, &skipped);
    if (photos.size() < 2) {
      std::cerr << "match_images: " << photos.size() << " of " << paths.size()
                << " photos readable: two or more are needed\n";
      return 1;
    }
    std::vector<matching::PhotoFootprint> footprints;
    footprints.reserve(photos.size());
    for (const Photo& p : photos) footprints.push_back(p.footprint);
    const auto pairs = matching::SelectOverlappingPairs(footprints, selection);
    // A photo's features are computed at its first pair and released after
    // its last one: memory holds only the photos of pairs still to come.
    std::vector<size_t> last_use(photos.size(), 0);
    for (size_t k = 0; k < pairs.size(); ++k)
      last_use[pairs[k].first] = last_use[pairs[k].second] = k;
    std::vector<std::unique_ptr<matching::PhotoFeatures>> features(photos.size());
    double feature_seconds = 0.0;
    int featured = 0;
    // A photo that passed the check but cannot be decoded is named once and
    // its pairs are left out.
    std::vector<bool> undecodable(photos.size(), false);
    auto get = [&](int i) -> const matching::PhotoFeatures& {
      if (!features[i]) {
        cv::Mat image;
        try {
          image = io::ReadImageChecked(photos[i].path, cv::IMREAD_COLOR, image_options);
        } catch (const IoError& e) {
          if (!undecodable[i]) {
            std::cerr << "match_images: skipped " << e.what() << "\n";
            ++skipped;
          }
          undecodable[i] = true;
          throw;
        }
        features[i] =
            std::make_unique<matching::PhotoFeatures>(image, photos[i].path, feature_options);
        feature_seconds += features[i]->seconds();
        ++featured;
      }
      return *features[i];
    };

    std::ofstream out;
    if (!out_path.empty()) {
      out.open(out_path);
      if (!out) throw IoError(Message(out_path, ": cannot be written"));
      out << "image_a,image_b,xa,ya,xb,yb,cov_xx,cov_xy,cov_yy,quality\n";
    }
    int total = 0;
    double seconds = 0.0, sum_sq = 0.0;
    for (size_t k = 0; k < pairs.size(); ++k) {
      const auto [i, j] = pairs[k];
      if (undecodable[i] || undecodable[j]) continue;
      matching::PhotoPairResult r;
      try {
        const matching::PhotoFeatures& a = get(i);
        r = matching::MatchPhotoPair(a, get(j), pair_options);
      } catch (const IoError&) {  // named in get()
        if (last_use[i] == k) features[i].reset();
        if (last_use[j] == k) features[j].reset();
        continue;
      }
      if (last_use[i] == k) features[i].reset();
      if (last_use[j] == k) features[j].reset();
      const int n = static_cast<int>(r.tie_points.size());
      std::printf("%s %s: %d tie points, epipolar rms %.3f px, %.2f s\n", photos[i].path.c_str(),
                  photos[j].path.c_str(), n, r.summary.epipolar_rms, r.summary.seconds);
      if (!r.summary.message.empty()) std::printf("  (%s)\n", r.summary.message.c_str());
      total += n;
      seconds += r.summary.seconds;
      sum_sq += n * r.summary.epipolar_rms * r.summary.epipolar_rms;
      for (const auto& t : r.tie_points) {
        if (!out) break;
        char line[512];
        std::snprintf(line, sizeof(line), "%s,%s,%.3f,%.3f,%.3f,%.3f,%.4e,%.4e,%.4e,%.3f\n",
                      photos[i].path.c_str(), photos[j].path.c_str(), t.xa.x(), t.xa.y(), t.xb.x(),
                      t.xb.y(), t.covariance(0, 0), t.covariance(0, 1), t.covariance(1, 1),
                      t.quality);
        out << line;
      }
    }
    std::printf(
        "total: %zu pairs, %d tie points, epipolar rms %.3f px, %.2f s (features %.2f s for %d "
        "photos)\n",
        pairs.size(), total, total > 0 ? std::sqrt(sum_sq / total) : 0.0, seconds, feature_seconds,
        featured);
    if (out_path.size() && !out) throw IoError(Message(out_path, ": write failed"));
    if (total == 0) {
      std::cerr << "match_images: no tie points\n";
      return 1;
    }
    if (skipped > 0) {
      std::cerr << "match_images: " << skipped << " of " << paths.size() << " photos skipped\n";
      return 2;
    }
  } catch (const Error& e) {
    std::cerr << "match_images: " << e.what() << "\n";
    return 1;
  } catch (const cv::Exception& e) {
    std::cerr << "match_images: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
