// resect_camera: a fixed camera's interior and exterior orientation from
// surveyed points picked in one photo, through the core's
// adjustment::ResectCamera.
//
//   rosrun slope_monitor resect_camera --image IMG --gcp FILE [--site FILE | --crs EPSG:NNNN]
//       [--position X Y Z [--position-sigma S]] [--camera-info YAML | --focal-mm F --sensor-mm W H]
//       [--free c,k1,...] [--pixel-sigma S] [--point-sigma S] [--pixel-origin opencv|corner] --out
//       PREFIX
//
// Without --camera-info the nominal camera is c = --focal-mm (or the EXIF
// focal length), the principal point at the image centre, no distortion, with
// the pixel pitch from --sensor-mm. With --site FILE the points (and
// --position) are in the site file's CRS and the pose is written in its `site`
// frame (what the site's cameras[].pose_file holds). Without it coordinates
// are used as given (a projected CRS in metres, or a local frame); --crs is
// then only recorded in PREFIX.pose.yaml.
// Writes PREFIX.yaml (camera_info_manager calibration, in pixels) and
// PREFIX.pose.yaml (position, theta/phi/kappa, the site_from_optical
// quaternion, and the 6x6 covariance of X0 Y0 Z0 theta phi kappa [m^2, rad^2]).
// The photo is checked before it is decoded (io::ReadImageChecked,
// core/io/image_file.h: its size from the header, refused above 100 MP; a
// truncated or damaged JPEG/PNG refused), e.g.
//   resect_camera: --image: image 'IMG.jpg': truncated JPEG: the data ends at byte ...
// Exit status: 0 the camera resected and both files written; 1 anything else
// (a bad photo or input file, no solution, a usage error). There is one
// input photo, so no partial result (status 2) exists.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <camera_calibration_parsers/parse.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/adjustment/resect_camera.h"
#include "slope_monitor/core/capture/calibration.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/image_file.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/surveyed_points.h"
#include "slope_monitor/ros/conversions.h"

using namespace slope_monitor;

namespace {

int Usage(std::ostream& out = std::cerr) {  // --help: std::cout
  out << "usage: resect_camera --image IMG --gcp FILE [--site FILE | --crs EPSG:NNNN] "
         "[--position X Y Z "
         "[--position-sigma S]] [--camera-info YAML | --focal-mm F --sensor-mm W H] [--free "
         "c,k1,...] "
         "[--pixel-sigma S] [--point-sigma S] [--pixel-origin opencv|corner] --out PREFIX\n"
         "exit status: 0 resected and written, 1 otherwise\n";
  return 1;
}

double Number(const std::string& flag, const std::string& text) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v))
    throw InvalidArgument(Message(flag, ": '", text, "' is not a number"));
  return v;
}

// Flags with their values (a flag takes every following argument up to the
// next "--" word); each known flag has a fixed count.
std::map<std::string, std::vector<std::string>> ParseArgs(int argc, char** argv) {
  static const std::map<std::string, int> kArity = {{"--image", 1},
                                                    {"--gcp", 1},
                                                    {"--crs", 1},
                                                    {"--position", 3},
                                                    {"--position-sigma", 1},
                                                    {"--camera-info", 1},
                                                    {"--focal-mm", 1},
                                                    {"--sensor-mm", 2},
                                                    {"--free", 1},
                                                    {"--pixel-sigma", 1},
                                                    {"--point-sigma", 1},
                                                    {"--pixel-origin", 1},
                                                    {"--out", 1},
                                                    {"--site", 1}};
  std::map<std::string, std::vector<std::string>> args;
  for (int i = 1; i < argc;) {
    const std::string flag = argv[i];
    const auto it = kArity.find(flag);
    if (it == kArity.end()) throw InvalidArgument(Message("unknown argument '", flag, "'"));
    if (i + it->second >= argc)
      throw InvalidArgument(Message(flag, " needs ", it->second, " value(s)"));
    std::vector<std::string> v(argv + i + 1, argv + i + 1 + it->second);
    args[flag] = v;
    i += 1 + it->second;
  }
  return args;
}

camera::CameraModel NominalCamera(const std::map<std::string, std::vector<std::string>>& a,
                                  const std::string& image, int width, int height) {
  if (a.count("--camera-info")) {
    if (a.count("--focal-mm") || a.count("--sensor-mm"))
      throw InvalidArgument("give either --camera-info or --focal-mm/--sensor-mm, not both");
    const std::string path = a.at("--camera-info")[0];
    std::string name;
    sensor_msgs::CameraInfo info;
    if (!camera_calibration_parsers::readCalibration(path, name, info))
      throw IoError(Message("--camera-info: cannot read a camera calibration from '", path, "'"));
    return capture::CheckCameraInfo(ros_adapters::FromMsg(info), 1.0, width, height, path);
  }
  if (!a.count("--sensor-mm"))
    throw InvalidArgument(
        "no camera: give --camera-info YAML or --focal-mm F --sensor-mm W H (or --sensor-mm W H "
        "with the focal length in the image's EXIF)");
  const double w = Number("--sensor-mm", a.at("--sensor-mm")[0]);
  const double h = Number("--sensor-mm", a.at("--sensor-mm")[1]);
  if (!(w > 0 && h > 0)) throw InvalidArgument("--sensor-mm: width and height must be > 0");
  const double pitch = w / width;
  if (std::abs(h / height - pitch) > 0.02 * pitch) {
    throw InvalidArgument(Message("--sensor-mm ", w, " x ", h, " mm does not match the image's ",
                                  width, " x ", height, " px with square pixels (", w / width,
                                  " vs ", h / height, " mm/px)"));
  }
  capture::ExifInfo exif;
  if (a.count("--focal-mm")) {
    exif.focal_length_mm = Number("--focal-mm", a.at("--focal-mm")[0]);
    if (!(exif.focal_length_mm > 0)) throw InvalidArgument("--focal-mm must be > 0");
  } else {
    exif = capture::ReadExif(image);
  }
  return capture::NominalModelFromExif(exif, width, height, pitch, image);
}

void PrintPoints(const adjustment::ResectCameraSummary& s, double critical) {
  std::printf("%-14s %10s %10s %8s %8s %8s %7s\n", "point", "u", "v", "du", "dv", "|d|", "|w|");
  for (const auto& p : s.points) {
    std::printf("%-14s %10.2f %10.2f %8.3f %8.3f %8.3f %7.2f%s\n", p.id.c_str(), p.observed.x(),
                p.observed.y(), p.residual.x(), p.residual.y(), p.residual.norm(), p.w,
                p.snooping_failed ? "  FAIL" : "");
  }
  std::printf("RMS %.3f px over %zu points\n", s.rms_px, s.points.size());
  std::printf("sigma0 %.3f (a posteriori, unit weight), redundancy %d\n", s.sigma0, s.redundancy);
  for (const auto& p : s.parameters) {
    const bool angle = p.name == "theta" || p.name == "phi" || p.name == "kappa";
    const double f = angle ? kDegPerRad : 1.0;
    std::printf("%-6s %18.8g +- %.4g %s\n", p.name.c_str(), p.value * f, p.sigma * f,
                angle                                                  ? "deg"
                : (p.name == "X0" || p.name == "Y0" || p.name == "Z0") ? "m"
                : (p.name == "c" || p.name == "x0" || p.name == "y0")  ? "mm"
                                                                       : "");
  }
  if (s.message.rfind("covariance", 0) == 0)
    std::printf("WARNING %s: the sigmas are not known\n", s.message.c_str());
  for (const auto& w : s.correlation_warnings) std::printf("WARNING correlation %s\n", w.c_str());
  if (s.redundancy == 0) std::printf("no redundancy: the residuals cannot be tested\n");
  for (const auto& p : s.points) {
    if (p.snooping_failed)
      std::printf("FLAG %s: fails data snooping (Baarda), |w| = %.2f > %.2f\n", p.id.c_str(), p.w,
                  critical);
  }
}

// Where the coordinates come from and go: the site file's CRS and `site`
// frame (--site), or the points' own coordinates (crs only recorded).
struct Frame {
  std::optional<SiteCrs> site;
  std::string site_file;
  std::string crs;  // the site's, or --crs, or ""
};

void WritePose(const std::string& path, const adjustment::ResectCameraSummary& s,
               const Frame& frame, const std::string& image) {
  std::ofstream out(path);
  if (!out) throw IoError(Message("cannot write '", path, "'"));
  const auto& e = s.exterior;
  const Eigen::Quaterniond q = camera::SiteFromOpticalFromAngles(e.angles);
  out << std::setprecision(12);
  if (frame.site) {
    out << "# resect_camera: pose of the camera in the site frame of " << frame.site_file << "\n";
    out << "site_file: \"" << frame.site_file << "\"\n";
  } else {
    out << "# resect_camera: pose of the camera in site (projected CRS coordinates as given)\n";
  }
  out << "image: \"" << image << "\"\n";
  out << "crs: \"" << frame.crs << "\"\n";
  out << "position: [" << e.position.x() << ", " << e.position.y() << ", " << e.position.z()
      << "]  # X0 Y0 Z0 [m]\n";
  if (frame.site) {
    const Eigen::Vector3d c = frame.site->CrsFromSite(e.position);
    out << "position_crs: [" << c.x() << ", " << c.y() << ", " << c.z() << "]  # the same in crs\n";
  }
  out << "angles_deg: {theta: " << e.angles.theta * kDegPerRad
      << ", phi: " << e.angles.phi * kDegPerRad << ", kappa: " << e.angles.kappa * kDegPerRad
      << "}\n";
  out << "# site_from_optical (REP 103 optical frame), x y z w\n";
  out << "quaternion: [" << q.x() << ", " << q.y() << ", " << q.z() << ", " << q.w() << "]\n";
  out << "# covariance of X0 Y0 Z0 [m] theta phi kappa [rad], row-major 6x6\n";
  out << "covariance: [";
  for (int i = 0; i < 36; ++i) out << (i ? ", " : "") << s.exterior_covariance(i / 6, i % 6);
  out << "]\n";
  out << "rms_px: " << s.rms_px << "\n";
  out << "points: " << s.points.size() << "\n";
}

// --site FILE: the site's CRS and frame; else --crs (recorded only).
Frame ReadFrame(const std::map<std::string, std::vector<std::string>>& a) {
  Frame f;
  if (a.count("--site")) {
    if (a.count("--crs"))
      throw InvalidArgument(
          "give either --site FILE (the points in the site's CRS) or --crs, not both");
    f.site_file = a.at("--site")[0];
    const io::SiteFile site = io::LoadSiteFile(f.site_file);
    f.site.emplace(site.crs);
    f.crs = site.crs.crs;
  } else if (a.count("--crs")) {
    f.crs = a.at("--crs")[0];
  }
  return f;
}

// A point of `what` in the site CRS -> site, naming it when PROJ cannot.
Eigen::Vector3d ToSite(const Frame& f, const Eigen::Vector3d& x, const std::string& what) {
  if (!f.site) return x;
  try {
    return f.site->SiteFromCrs(x);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(Message(what, ": not convertible from ", f.crs, " to the site frame of ",
                                  f.site_file, ": ", e.what()));
  }
}

}  // namespace

int main(int argc, char** argv) {
  try {
    if (argc < 2) return Usage();
    if (std::string(argv[1]) == "-h" || std::string(argv[1]) == "--help") {
      Usage(std::cout);
      return 0;
    }
    const auto a = ParseArgs(argc, argv);
    if (!a.count("--image") || !a.count("--gcp") || !a.count("--out")) return Usage();
    const Frame frame = ReadFrame(a);
    const std::string image = a.at("--image")[0];
    cv::Mat full;
    try {
      full = io::ReadImageChecked(image, cv::IMREAD_GRAYSCALE);
    } catch (const IoError& e) {
      throw IoError(Message("--image: ", e.what()));
    }
    const int width = full.cols, height = full.rows;
    io::PixelOrigin origin = io::PixelOrigin::kOpenCv;
    if (a.count("--pixel-origin")) {
      const std::string o = a.at("--pixel-origin")[0];
      if (o == "corner") {
        origin = io::PixelOrigin::kCorner;
      } else if (o != "opencv") {
        throw InvalidArgument(
            Message("--pixel-origin: '", o, "' is neither 'opencv' nor 'corner'"));
      }
    }
    const std::string gcp = a.at("--gcp")[0];
    auto points = io::ReadSurveyedPoints(gcp, origin);
    for (auto& p : points) p.xyz = ToSite(frame, p.xyz, Message(gcp, ":", p.line, " (", p.id, ")"));
    adjustment::ResectCameraOptions options;
    if (a.count("--free")) {
      options.free_interior.clear();
      std::stringstream list(a.at("--free")[0]);
      for (std::string n; std::getline(list, n, ',');)
        if (!n.empty()) options.free_interior.push_back(n);
    }
    if (a.count("--pixel-sigma"))
      options.pixel_sigma = Number("--pixel-sigma", a.at("--pixel-sigma")[0]);
    if (a.count("--point-sigma"))
      options.point_sigma = Number("--point-sigma", a.at("--point-sigma")[0]);
    if (a.count("--position")) {
      options.has_position = true;
      for (int k = 0; k < 3; ++k) options.position(k) = Number("--position", a.at("--position")[k]);
      options.position = ToSite(frame, options.position, "--position");
      if (a.count("--position-sigma"))
        options.position_sigma = Number("--position-sigma", a.at("--position-sigma")[0]);
    } else if (a.count("--position-sigma")) {
      throw InvalidArgument("--position-sigma needs --position X Y Z");
    }
    const camera::CameraModel nominal = NominalCamera(a, image, width, height);
    const auto s = adjustment::ResectCamera(points, nominal, options);
    if (frame.site)
      std::printf("frame: site of %s (points and --position in %s)\n", frame.site_file.c_str(),
                  frame.crs.c_str());
    std::printf("start: %s\n", s.start.c_str());
    if (!s.success) {
      std::cerr << "resect_camera: " << s.message << "\n";
      return 1;
    }
    PrintPoints(s, options.snooping_critical);
    const std::string prefix = a.at("--out")[0];
    // The calibration in pixels (camera_info_manager's file format).
    sensor_msgs::CameraInfo info = ros_adapters::ToMsg(s.model.ToCameraInfo());
    if (!camera_calibration_parsers::writeCalibration(prefix + ".yaml", "camera", info))
      throw IoError(Message("cannot write '", prefix, ".yaml'"));
    WritePose(prefix + ".pose.yaml", s, frame, image);
    std::printf("wrote %s.yaml and %s.pose.yaml\n", prefix.c_str(), prefix.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "resect_camera: " << e.what() << "\n";
    return 1;
  }
}
