// Benchmark: camera_capture's publishing rate for a folder of 12 MP JPEGs
// (folder scan with EXIF, JPEG completeness check, decode, conversion to
// sensor_msgs/Image + camera_info + NavSatFix + position prior, epoch
// tracking: the nodelet's FramePublisher path) against the plain OpenCV
// decode rate (cv::imread) of the same files, in the same process.
//
//   bench_capture_folder [--images N] [--rounds R] [--width W] [--height H]   (defaults 10 3 4000
//   3000)
//
// Each image goes through the three paths back to back (order rotated), so a
// shared machine's load hits them alike. Prints one line per measurement, the
// per-round ratios and "ratio ours/cv_imread = X" (the median over rounds of
// the rate ratio; 1.0 means publishing costs no more than decoding).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>
#pragma GCC diagnostic pop

#include "slope_monitor/ros/capture_conversions.h"

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A textured "terrain" photo: smoothed noise (fixed seed) plus gradients.
cv::Mat Terrain(int width, int height, int seed) {
  cv::RNG rng(1234 + seed);
  cv::Mat small(height / 4, width / 4, CV_8UC3);
  rng.fill(small, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(small, small, cv::Size(0, 0), 1.2);
  cv::Mat img;
  cv::resize(small, img, cv::Size(width, height), 0, 0, cv::INTER_LINEAR);
  cv::Mat fine(height, width, CV_8UC3);
  rng.fill(fine, cv::RNG::NORMAL, 0, 12);
  cv::add(img, fine, img);
  return img;
}

void WriteExif(const std::string& path, int i) {
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
  auto image = Exiv2::ImageFactory::open(path);
  image->readMetadata();
  Exiv2::ExifData& exif = image->exifData();
  char buf[32];
  std::snprintf(buf, sizeof(buf), "2024:05:01 %02d:%02d:%02d", 10 + (2 * i) / 3600,
                ((2 * i) / 60) % 60, (2 * i) % 60);
  exif["Exif.Photo.DateTimeOriginal"] = std::string(buf);
  exif["Exif.Image.Make"] = std::string("BenchCam");
  exif["Exif.Photo.FocalLength"] = Exiv2::Rational(88, 10);
  exif["Exif.GPSInfo.GPSLatitudeRef"] = std::string("N");
  exif["Exif.GPSInfo.GPSLatitude"] = std::string("35/1 0/1 0/1");
  exif["Exif.GPSInfo.GPSLongitudeRef"] = std::string("E");
  exif["Exif.GPSInfo.GPSLongitude"] = std::string("139/1 0/1 0/1");
  exif["Exif.GPSInfo.GPSAltitudeRef"] = std::string("0");
  exif["Exif.GPSInfo.GPSAltitude"] = Exiv2::Rational(150, 1);
  image->writeMetadata();
#pragma GCC diagnostic pop
}

}  // namespace

int main(int argc, char** argv) {
  int n = 10, rounds = 3, width = 4000, height = 3000;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    const int v = std::atoi(argv[i + 1]);
    if (v <= 0) {
      std::fprintf(stderr, "bench_capture_folder: %s needs a positive integer\n", a.c_str());
      return 2;
    }
    if (a == "--images")
      n = v;
    else if (a == "--rounds")
      rounds = v;
    else if (a == "--width")
      width = v;
    else if (a == "--height")
      height = v;
    else {
      std::fprintf(stderr, "bench_capture_folder: unknown option %s\n", a.c_str());
      return 2;
    }
  }
  char tmpl[] = "/tmp/sm_bench_capture_XXXXXX";
  if (mkdtemp(tmpl) == nullptr) return 1;
  const std::string dir = tmpl;
  std::vector<std::string> files;
  double bytes = 0;
  for (int i = 0; i < n; ++i) {
    const std::string path = dir + "/img_" + std::to_string(i) + ".jpg";
    cv::imwrite(path, Terrain(width, height, i), {cv::IMWRITE_JPEG_QUALITY, 92});
    WriteExif(path, i);
    bytes += std::filesystem::file_size(path);
    files.push_back(path);
  }
  std::printf("folder: %d JPEGs %dx%d (%.1f MP), mean %.2f MB\n", n, width, height,
              width * height / 1e6, bytes / n / 1e6);

  // Warm-up (page cache, decoder tables).
  for (const auto& f : files) cv::imread(f);

  // The machine may be shared: each image goes through the three paths back to
  // back (order rotated), so all see the same load; per round
  // the sums are compared, and the best round of each path is reported.
  namespace sm = slope_monitor;
  volatile size_t sink = 0;
  sm::ros_adapters::FramePublisherOptions po;
  po.has_site_origin = true;
  po.site_origin = {35.0, 139.0, 100.0};
  po.pixel_size = 0.0024;
  sm::ros_adapters::CaptureOutputs out;
  out.image = [&](const sensor_msgs::ImagePtr& img, const sensor_msgs::CameraInfoPtr&) {
    sink = sink + img->data.size();
  };
  out.fix = [&](const sensor_msgs::NavSatFix& f) { sink = sink + static_cast<size_t>(f.latitude); };
  out.prior = [&](const geometry_msgs::PoseWithCovarianceStamped&) { sink = sink + 1; };
  sm::capture::FolderSourceOptions fo;
  fo.folder = dir;
  std::vector<double> base_t(rounds, 0.0), ours_t(rounds, 0.0), copy_t(rounds, 0.0);
  for (int r = 0; r < rounds; ++r) {
    // Ours: the folder scan (EXIF of every file) counts too.
    double t0 = Now();
    sm::ros_adapters::FramePublisher publisher(po, out);
    sm::capture::FolderSource source(fo);
    sm::capture::EpochTracker tracker(sm::capture::EpochOptions{});
    ours_t[r] += Now() - t0;
    // The former path for comparison: decode into a Mat of its own, then copy
    // it into the message (cv_bridge), as before the decode-into-message change.
    t0 = Now();
    sm::capture::FolderSource copy_source(fo);
    copy_t[r] += Now() - t0;
    int published = 0;
    for (int i = 0; i < n; ++i) {
      for (int k = 0; k < 3; ++k) {
        const int which = (k + i + r) % 3;
        t0 = Now();
        if (which == 0) {
          sink = sink + cv::imread(files[i], cv::IMREAD_COLOR).total();
          base_t[r] += Now() - t0;
        } else if (which == 1) {
          if (publisher.Step(&source, &tracker, true) ==
              sm::ros_adapters::FramePublisher::StepResult::kPublished) {
            ++published;
          }
          ours_t[r] += Now() - t0;
        } else {
          sm::capture::Frame frame;
          if (copy_source.Next(&frame)) {
            sink = sink +
                   sm::ros_adapters::ToImageMsg(frame, sm::ros_adapters::FrameHeader(frame, "cam"))
                       ->data.size();
          }
          copy_t[r] += Now() - t0;
        }
      }
    }
    if (published != n) {
      std::fprintf(stderr, "bench_capture_folder: published %d of %d images\n", published, n);
      return 1;
    }
  }
  std::filesystem::remove_all(dir);
  std::vector<double> ratios;
  for (int r = 0; r < rounds; ++r) ratios.push_back(base_t[r] / ours_t[r]);
  std::sort(ratios.begin(), ratios.end());
  const double best_base = *std::min_element(base_t.begin(), base_t.end());
  const double best_ours = *std::min_element(ours_t.begin(), ours_t.end());
  const double best_copy = *std::min_element(copy_t.begin(), copy_t.end());
  const double base_rate = n / best_base, ours_rate = n / best_ours, copy_rate = n / best_copy;
  std::printf("cv_imread decode: %.3f images/s (%.1f ms/image)\n", base_rate, 1e3 / base_rate);
  std::printf("camera_capture publish path: %.3f images/s (%.1f ms/image)\n", ours_rate,
              1e3 / ours_rate);
  std::printf(
      "former copying path (decode, then copy into the message): %.3f images/s (%.1f ms/image)\n",
      copy_rate, 1e3 / copy_rate);
  std::printf("per-round ratios ours/cv_imread:");
  for (double x : ratios) std::printf(" %.3f", x);
  std::printf("\n");
  std::printf("ratio copying/cv_imread = %.3f\n", best_base / best_copy);
  std::printf("ratio ours/cv_imread = %.3f\n", ratios[ratios.size() / 2]);
  return 0;
}
