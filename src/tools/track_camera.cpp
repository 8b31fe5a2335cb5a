// track_camera: re-orientation of a fixed camera on stable ground, photo by
// photo, through the package's hex matcher (global shift
// on, only stable points) and adjustment::ReorientCamera.
//
//   rosrun slope_monitor track_camera --camera PREFIX --reference A.jpg --image B.jpg [--image
//   C.jpg ...]
//       [--stable-mask M.png | --stable-polygons F] [--dem DEM.tif] --out DIR
//
// PREFIX.yaml / PREFIX.pose.yaml are what resect_camera writes (the camera and
// the reference photo's pose). A stable mask is an 8-bit PNG of the image's
// size, non-zero = stable; a polygons file has one polygon per line, vertices
// as `u v` pairs in pixels (OpenCV convention), `#` comments. Without either,
// the whole image is taken as stable. Prints per photo
//   <image>: rotation <angle> deg (dtheta <a> dphi <b> dkappa <c> deg, sigma <s> deg) rms <r> px
//   over <N> stable points
// (sigma: the largest of the three angles' sigmas) and writes
// DIR/reorientation.csv. With --dem DEM.tif (a GeoTIFF in the camera's site
// coordinates, band 1 height, an optional band "sigma" its height std) also
// the displacement field of each photo (dense::ComputeDisplacementField; the
// monitored area is the image minus the stable area, or the whole image
// without a stable area; the stable area scales the LSC covariance):
//   DIR/field_<image stem>.csv  id,u,v,x,y,z,dx,dy,dz,sigma_x,sigma_y,sigma_z,vx,vy,vz,stable,flag
//                               (site metres, m/s from the photos' EXIF times;
//                               stable 1 = a probe on stable ground (a check,
//                               d ~ 0), flag empty = usable)
//   DIR/field_<image stem>.png  the new photo with the field's arrows, legend
//                               and scale bar (dense/field_picture.h, the
//                               picture the reports get)
//
// Every photo is checked before it is decoded (io::ReadImageChecked,
// core/io/image_file.h: the size from the header, refused above
// --max-megapixels (default 100) before decoding; a truncated or damaged
// JPEG/PNG refused). A --image that fails, or is not the reference's size,
// is named with the reason and skipped:
//   track_camera: skipped --image: image 'B.jpg': truncated JPEG: the data ends at byte ...
// Exit status: 0 every photo read and re-oriented; 2 some photos skipped or
// not re-oriented, at least one re-oriented; 1 none re-oriented, a bad
// --reference, --camera, --stable-mask or --dem, or a usage error.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <camera_calibration_parsers/parse.h>
#include <yaml-cpp/yaml.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/adjustment/reorient_camera.h"
#include "slope_monitor/core/capture/calibration.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/dense/displacement_field.h"
#include "slope_monitor/core/dense/field_picture.h"
#include "slope_monitor/core/dense/targetless_camera.h"
#include "slope_monitor/core/io/camera_pose_file.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/image_file.h"
#include "slope_monitor/core/io/image_polygons.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/ros/conversions.h"

using namespace slope_monitor;

namespace {

int Usage(std::ostream& os = std::cerr, int status = 1) {
  os << "usage: track_camera --camera PREFIX --reference A.jpg --image B.jpg [--image C.jpg ...] "
        "[--stable-mask M.png | --stable-polygons F] [--dem DEM.tif] [--max-megapixels MP] --out "
        "DIR\n"
        "exit status: 0 all re-oriented, 2 some photos skipped or not re-oriented, 1 none or an "
        "error\n";
  return status;
}

camera::CameraModel LoadCamera(const std::string& path) {
  std::string name;
  sensor_msgs::CameraInfo info;
  if (!camera_calibration_parsers::readCalibration(path, name, info))
    throw IoError(Message("--camera: cannot read a camera calibration from '", path, "'"));
  return capture::CheckCameraInfo(ros_adapters::FromMsg(info), 1.0, 0, 0, path);
}

// The stable area as a mask of the image's size (255 = stable).
cv::Mat StableMask(const std::map<std::string, std::vector<std::string>>& a, const cv::Size& size,
                   const io::ImageFileOptions& image_options) {
  if (a.count("--stable-mask") && a.count("--stable-polygons"))
    throw InvalidArgument("give --stable-mask or --stable-polygons, not both");
  if (a.count("--stable-mask")) {
    const std::string path = a.at("--stable-mask")[0];
    cv::Mat m;
    try {
      m = io::ReadImageChecked(path, cv::IMREAD_UNCHANGED, image_options);
    } catch (const IoError& e) {
      throw IoError(Message("--stable-mask: ", e.what()));
    }
    if (m.type() != CV_8UC1)
      throw InvalidArgument(
          Message("--stable-mask '", path, "': not an 8-bit single-channel image"));
    if (m.size() != size)
      throw InvalidArgument(Message("--stable-mask '", path, "' is ", m.cols, "x", m.rows,
                                    " px, the images are ", size.width, "x", size.height));
    return m;
  }
  cv::Mat m(size, CV_8UC1, cv::Scalar(a.count("--stable-polygons") ? 0 : 255));
  if (a.count("--stable-polygons")) {
    for (const auto& p : io::ReadImagePolygons(a.at("--stable-polygons")[0], "--stable-polygons")) {
      std::vector<cv::Point> q;
      q.reserve(p.size());
      for (const auto& v : p) q.emplace_back(cvRound(v.x()), cvRound(v.y()));
      cv::fillPoly(m, std::vector<std::vector<cv::Point>>{q}, cv::Scalar(255));
    }
  }
  return m;
}

// The photo in gray; IoError "<flag>: image '<path>': <reason>".
cv::Mat Gray(const std::string& path, const std::string& flag,
             const io::ImageFileOptions& options) {
  try {
    return io::ReadImageChecked(path, cv::IMREAD_GRAYSCALE, options);
  } catch (const IoError& e) {
    throw IoError(Message(flag, ": ", e.what()));
  }
}

// Capture time of a photo [s] from its EXIF, or NaN.
double PhotoTime(const std::string& path) {
  const capture::ExifInfo e = capture::ReadExif(path);
  return e.has_time ? e.time : std::numeric_limits<double>::quiet_NaN();
}

void WriteFieldCsv(const std::string& path, const dense::DisplacementField& f) {
  std::ofstream out(path);
  if (!out) throw IoError(Message("cannot write '", path, "'"));
  out << "id,u,v,x,y,z,dx,dy,dz,sigma_x,sigma_y,sigma_z,vx,vy,vz,stable,flag\n";
  char line[512];
  for (size_t i = 0; i < f.points.size(); ++i) {
    const dense::FieldPoint& p = f.points[i];
    const Eigen::Vector3d s = p.Sigma();
    std::snprintf(
        line, sizeof(line),
        "%zu,%.2f,%.2f,%.3f,%.3f,%.3f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.6g,%.6g,%.6g,%d,%s\n", i,
        p.xa.x(), p.xa.y(), p.x_ref.x(), p.x_ref.y(), p.x_ref.z(), p.displacement.x(),
        p.displacement.y(), p.displacement.z(), s.x(), s.y(), s.z(), p.velocity.x(), p.velocity.y(),
        p.velocity.z(), p.stable ? 1 : 0, p.flag.c_str());
    out << line;
  }
  if (!out) throw IoError(Message("cannot write '", path, "'"));
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  try {
    std::map<std::string, std::vector<std::string>> a;
    // --help: the usage on stdout, exit 0, nothing read or written
    if (argc == 2 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h"))
      return Usage(std::cout, 0);
    static const char* kKnown[] = {"--camera",      "--reference",       "--image",
                                   "--stable-mask", "--stable-polygons", "--dem",
                                   "--out",         "--max-megapixels"};
    for (int i = 1; i < argc; i += 2) {
      const std::string flag = argv[i];
      if (std::find(std::begin(kKnown), std::end(kKnown), flag) == std::end(kKnown))
        throw InvalidArgument(Message("unknown argument '", flag, "'"));
      if (i + 1 >= argc) throw InvalidArgument(Message(flag, " needs a value"));
      a[flag].push_back(argv[i + 1]);
    }
    if (!a.count("--camera") || !a.count("--reference") || !a.count("--image") || !a.count("--out"))
      return Usage();
    io::ImageFileOptions image_options;
    if (a.count("--max-megapixels")) {
      const std::string& v = a["--max-megapixels"][0];
      char* end = nullptr;
      image_options.max_megapixels = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0')
        throw InvalidArgument(Message("--max-megapixels '", v, "' is not a number"));
    }
    image_options.Check();
    io::GeoRaster dem;
    if (a.count("--dem")) dem = io::ReadGeoTiff(a["--dem"][0]);
    const std::string prefix = a["--camera"][0];
    const camera::CameraModel model = LoadCamera(prefix + ".yaml");
    const camera::ExteriorOrientation reference =
        io::ReadCameraPoseFile(prefix + ".pose.yaml", "--camera");
    const cv::Mat ref = Gray(a["--reference"][0], "--reference", image_options);
    if (ref.cols != model.sensor().width || ref.rows != model.sensor().height)
      throw InvalidArgument(Message("--reference '", a["--reference"][0], "' is ", ref.cols, "x",
                                    ref.rows, " px, the camera ", model.sensor().width, "x",
                                    model.sensor().height));
    const cv::Mat stable = StableMask(a, ref.size(), image_options);
    const bool has_stable_area = a.count("--stable-mask") || a.count("--stable-polygons");
    const double ref_time = a.count("--dem") ? PhotoTime(a["--reference"][0]) : 0.0;
    auto is_stable = [&stable](const Eigen::Vector2d& x) {
      const int c = cvRound(x.x()), r = cvRound(x.y());
      return c >= 0 && r >= 0 && c < stable.cols && r < stable.rows &&
             stable.at<unsigned char>(r, c) != 0;
    };
    std::filesystem::create_directories(a["--out"][0]);
    const std::string csv_path = a["--out"][0] + "/reorientation.csv";
    std::ofstream csv(csv_path);
    if (!csv) throw IoError(Message("cannot write '", csv_path, "'"));
    csv << "image,rotation_deg,dtheta_deg,dphi_deg,dkappa_deg,sigma_theta_deg,sigma_phi_deg,sigma_"
           "kappa_deg,rms_px,"
           "stable_points,outliers,global_shift_u,global_shift_v\n";
    dense::ImageAreas areas;
    if (has_stable_area) areas.stable = is_stable;
    dense::TargetlessCamera camera("--camera " + prefix, model, reference,
                                   a.count("--dem") ? &dem : nullptr, areas,
                                   dense::TargetlessCameraOptions());
    const double ref_t = std::isfinite(ref_time) ? ref_time : 0.0;  // 0: times unknown
    camera.SetReference(ref, ref_t);
    int failures = 0, skipped = 0, reoriented = 0;
    for (const auto& path : a["--image"]) {
      cv::Mat img;
      try {
        img = Gray(path, "--image", image_options);
        if (img.size() != ref.size())
          throw IoError(Message("--image '", path, "' is ", img.cols, "x", img.rows,
                                " px, the reference ", ref.cols, "x", ref.rows));
      } catch (const IoError& e) {
        std::fprintf(stderr, "track_camera: skipped %s\n", e.what());
        ++skipped;
        continue;
      }
      const double t = a.count("--dem") ? PhotoTime(path) : 0.0;
      const dense::TargetlessEpoch e =
          camera.Process(img, std::isfinite(t) && std::isfinite(ref_time) ? t : ref_t,
                         a.count("--dem") ? a["--dem"][0] : "DEM");
      const auto& s = e.reorientation;
      const std::string name = std::filesystem::path(path).filename().string();
      std::fprintf(
          stderr,
          "%s: %d stable candidates, %d matched, %d normal quality; global shift (%.1f, %.1f) px;",
          name.c_str(), e.matches.candidates, e.matches.matched, e.ties, e.matches.global_shift.x(),
          e.matches.global_shift.y());
      for (const auto& r : e.matches.rejects)
        std::fprintf(stderr, " %s %d", r.first.c_str(), r.second);
      std::fprintf(stderr, "\n");
      for (const auto& w : e.warnings) std::fprintf(stderr, "WARN %s\n", w.c_str());
      if (!s.success) {
        std::printf("%s: no re-orientation: %s\n", name.c_str(), s.message.c_str());
        ++failures;
        continue;
      }
      ++reoriented;
      const double sigma = s.sigma.maxCoeff() * kDegPerRad;
      std::printf(
          "%s: rotation %.4f deg (dtheta %.4f dphi %.4f dkappa %.4f deg, sigma %.4f deg) rms %.2f "
          "px over %d "
          "stable points\n",
          name.c_str(), s.rotation_angle * kDegPerRad, s.delta(0) * kDegPerRad,
          s.delta(1) * kDegPerRad, s.delta(2) * kDegPerRad, sigma, s.rms_px, s.num_points);
      csv << name << ',' << s.rotation_angle * kDegPerRad << ',' << s.delta(0) * kDegPerRad << ','
          << s.delta(1) * kDegPerRad << ',' << s.delta(2) * kDegPerRad << ','
          << s.sigma(0) * kDegPerRad << ',' << s.sigma(1) * kDegPerRad << ','
          << s.sigma(2) * kDegPerRad << ',' << s.rms_px << ',' << s.num_points << ','
          << s.num_outliers << ',' << e.matches.global_shift.x() << ','
          << e.matches.global_shift.y() << '\n';
      if (!e.has_field) continue;
      const dense::DisplacementField& f = e.field;
      const std::string stem =
          a["--out"][0] + "/field_" + std::filesystem::path(path).stem().string();
      WriteFieldCsv(stem + ".csv", f);
      dense::WriteDisplacementFieldPng(stem + ".png", img, f, model, s.exterior,
                                       dense::FieldPictureOptions());
      std::fprintf(
          stderr,
          "%s: field of %d probes, %d usable (%d with a window-straddle term), LSC variance factor "
          "%.2f, dt %.0f s;",
          name.c_str(), f.summary.probes, f.summary.usable, f.summary.straddling,
          f.summary.lsc_variance_factor, e.dt);
      for (const auto& kv : f.summary.flags)
        std::fprintf(stderr, " %s %d", kv.first.c_str(), kv.second);
      std::fprintf(stderr, "\n");
    }
    if (reoriented == 0) {
      std::fprintf(stderr,
                   "track_camera: no photo re-oriented (%d skipped, %d without a re-orientation)\n",
                   skipped, failures);
      return 1;
    }
    if (skipped || failures) {
      std::fprintf(stderr, "track_camera: %d of %zu photos skipped, %d without a re-orientation\n",
                   skipped, a["--image"].size(), failures);
      return 2;
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "track_camera: " << e.what() << "\n";
    return 1;
  }
}
