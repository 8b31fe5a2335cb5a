#include "slope_monitor/ros/targetless_camera.h"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <cv_bridge/cv_bridge.h>
#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/PointDisplacement.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/dense/field_picture.h"
#include "slope_monitor/core/io/camera_pose_file.h"
#include "slope_monitor/core/io/image_polygons.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/image_limits.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

diagnostic_msgs::KeyValue Kv(const std::string& key, const std::string& value) {
  diagnostic_msgs::KeyValue kv;
  kv.key = key;
  kv.value = value;
  return kv;
}

// The field's covariance is nearly singular: the displacement of a point
// held on the DEM hardly varies across the surface, so one eigenvalue is
// ~1e-13 m^2. Floored at (0.1 mm)^2, far below the sigmas along the surface
// (mm to cm), so the estimator's covariance check (sigma >= 1e-6 m) and its
// filters stay well conditioned.
Eigen::Matrix3d Conditioned(const Eigen::Matrix3d& c) {
  constexpr double kMinVariance = 1e-8;  // [m^2]
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(0.5 * (c + c.transpose()));
  const Eigen::Vector3d e = es.eigenvalues().cwiseMax(kMinVariance);
  return es.eigenvectors() * e.asDiagonal() * es.eigenvectors().transpose();
}

geometry_msgs::TransformStamped PoseTf(const camera::ExteriorOrientation& pose,
                                       const std::string& frame_id, const std::string& camera,
                                       const ros::Time& stamp) {
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = frame_id;
  t.child_frame_id = camera + "_optical";
  t.transform = ToTransform(pose.SiteFromOptical());
  return t;
}

slope_monitor::PointDisplacementArray ToDisplacements(const dense::DisplacementField& f,
                                                      const std::string& camera,
                                                      const std_msgs::Header& header,
                                                      const ros::Time& reference_stamp,
                                                      unsigned int epoch) {
  slope_monitor::PointDisplacementArray out;
  out.header = header;
  out.epoch = epoch;
  for (size_t i = 0; i < f.points.size(); ++i) {
    const dense::FieldPoint& p = f.points[i];
    if (!p.IsUsable() || p.stable) continue;
    slope_monitor::PointDisplacement d;
    d.point_id = camera + "/p" + std::to_string(i);
    d.source = slope_monitor::PointDisplacement::SOURCE_FEATURE;
    d.source_name = "targetless_camera/" + camera;
    d.reference_stamp = reference_stamp;
    d.stamp = header.stamp;
    d.reference_position.x = p.x_ref.x();
    d.reference_position.y = p.x_ref.y();
    d.reference_position.z = p.x_ref.z();
    d.displacement.x = p.displacement.x();
    d.displacement.y = p.displacement.y();
    d.displacement.z = p.displacement.z();
    const Eigen::Matrix3d cov = Conditioned(p.covariance);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) d.covariance[3 * r + c] = cov(r, c);
    const double n = p.displacement.norm();
    const double var = n > 0 ? p.displacement.dot(cov * p.displacement) / (n * n) : 0.0;
    d.significance = var > 0 ? n / std::sqrt(var) : 0.0;
    out.displacements.push_back(d);
  }
  return out;
}

}  // namespace

TargetlessParameters ReadTargetlessParameters(ParamReader& p) {
  TargetlessParameters t;
  t.site_file = p.String("site_file", t.site_file);
  if (t.site_file.empty())
    throw ConfigError(
        Message(p.FullKey("site_file"),
                ": required (the site file that lists the fixed_targetless cameras)"));
  t.site = io::LoadSiteFile(t.site_file);
  t.reference_images = p.StringList("reference_images", t.reference_images);
  for (const std::string& r : t.reference_images) {
    const size_t eq = r.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == r.size())
      throw ConfigError(Message(p.FullKey("reference_images"), ": entry '", r,
                                "' must read '<camera>=<photo file>'"));
    t.references[r.substr(0, eq)] = r.substr(eq + 1);
  }
  t.frame_id = p.String("frame_id", t.frame_id);
  t.report_dir = p.String("report_dir", t.report_dir);
  dense::TargetlessCameraOptions& o = t.options;
  o.match_radius = p.Double("match_radius", o.match_radius, 1.0, 1000.0, "px");
  o.max_rotation_deg = p.Double("max_rotation_deg", o.max_rotation_deg, 1e-6, 90.0, "deg");
  o.reorient.pixel_sigma = p.Double("pixel_sigma", o.reorient.pixel_sigma, 1e-3, 100.0, "px");
  o.field.spacing_px = p.Double("spacing_px", o.field.spacing_px, 1.0, 10000.0, "px");
  o.field.spacing_m = p.Double("spacing_m", o.field.spacing_m, 0.0, 10000.0, "m");
  o.field.dem_sigma = p.Double("dem_sigma", o.field.dem_sigma, 0.0, 1000.0, "m");
  o.field.min_incidence_deg =
      p.Double("min_incidence_deg", o.field.min_incidence_deg, 0.0, 89.9, "deg");
  o.field.min_los_angle_deg =
      p.Double("min_los_angle_deg", o.field.min_los_angle_deg, 0.0, 89.9, "deg");
  try {
    o.Check();
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message(p.FullKey(""), ": ", e.what()));
  }
  for (const auto& [camera, file] : t.references) {
    const io::SiteCamera* c = t.site.FindCamera(camera);
    if (!c || c->kind != io::CameraKind::kFixedTargetless)
      throw ConfigError(Message(p.FullKey("reference_images"), ": '", camera,
                                "' is not a fixed_targetless camera of ", t.site_file));
  }
  return t;
}

TargetlessCameraRunner::TargetlessCameraRunner(const TargetlessParameters& params,
                                               const io::SiteCamera& camera)
    : params_(params), camera_(camera) {
  const std::string key = params.site.path + ": camera '" + camera.name + "'";
  reference_pose_ = io::ReadCameraPoseFile(camera.pose_file, key + " pose_file");
  try {
    dem_ = io::ReadGeoTiff(camera.dem);
    // A DEM in the site's map CRS (the dense step's surface_eNN.tif) back
    // in the site frame; another EPSG code is refused, naming both.
    if (dem_.epsg != 0) {
      const SiteCrs site(params.site.crs);
      dem_ = io::SiteRasterFromMap(dem_, &site);
    }
  } catch (const Error& e) {
    throw ConfigError(Message(key, " dem: ", e.what()));
  }
  if (!camera.stable_polygons.empty())
    stable_polygons_ = io::ReadImagePolygons(camera.stable_polygons, key + " stable_polygons");
  else if (params.site.stable_areas.empty() && params.site.outline.empty())
    throw ConfigError(Message(key,
                              ": no stable_polygons, and the site has no areas.stable nor "
                              "areas.outline: the stable ground is unknown"));
}

TargetlessOutputs TargetlessCameraRunner::Reference(const sensor_msgs::Image& image,
                                                    const sensor_msgs::CameraInfo& info) {
  if (camera_.pixel_size <= 0.0)
    throw ConfigError(Message(params_.site.path, ": camera '", camera_.name,
                              "' needs pixel_size to read its camera_info"));
  const camera::CameraModel model = CameraModelFromCameraInfo(info, camera_.pixel_size);
  dense::ImageAreas areas;
  if (!stable_polygons_.empty()) {
    const auto polygons = stable_polygons_;
    areas.stable = [polygons](const Eigen::Vector2d& x) { return io::InsideAny(polygons, x); };
  } else {
    areas =
        dense::AreasFromSitePolygons(model, reference_pose_, dem_, params_.site.outline,
                                     params_.site.stable_areas, params_.options.field.max_range);
  }
  tracker_ = std::make_unique<dense::TargetlessCamera>(camera_.name, model, reference_pose_, &dem_,
                                                       areas, params_.options);
  cv::Mat ref;
  double time = image.header.stamp.toSec();
  const auto configured = params_.references.find(camera_.name);
  if (configured != params_.references.end()) {
    ref = cv::imread(configured->second, cv::IMREAD_GRAYSCALE);
    if (ref.empty())
      throw IoError(Message("reference_images: cannot read '", configured->second, "' (camera '",
                            camera_.name, "')"));
    const capture::ExifInfo exif = capture::ReadExif(configured->second);
    if (!exif.has_time)
      throw InvalidArgument(Message("reference_images: '", configured->second,
                                    "' has no EXIF capture time (camera '", camera_.name, "')"));
    time = exif.time;
  } else {
    CheckImageMessage(image);
    ref = cv_bridge::toCvCopy(image, "mono8")->image;
  }
  tracker_->SetReference(ref, time);
  reference_stamp_ = ros::Time(time);
  TargetlessOutputs out;
  out.site_from_optical =
      PoseTf(reference_pose_, params_.frame_id, camera_.name, image.header.stamp);
  out.status.name = "targetless_camera: " + camera_.name;
  out.status.level = diagnostic_msgs::DiagnosticStatus::OK;
  out.status.message = "reference photo set";
  out.info = "camera '" + camera_.name + "': reference photo at " + Fixed(time, 3) + " s";
  return out;
}

TargetlessOutputs TargetlessCameraRunner::OnImage(const sensor_msgs::Image& image,
                                                  const sensor_msgs::CameraInfo& info) {
  if (!tracker_) return Reference(image, info);
  CheckImageMessage(image);
  const cv::Mat img = cv_bridge::toCvCopy(image, "mono8")->image;
  const dense::TargetlessEpoch e = tracker_->Process(img, image.header.stamp.toSec(), camera_.dem);
  TargetlessOutputs out;
  out.warnings = e.warnings;
  diagnostic_msgs::DiagnosticStatus& s = out.status;
  s.name = "targetless_camera: " + camera_.name;
  s.hardware_id = camera_.name;
  const adjustment::ReorientSummary& r = e.reorientation;
  s.values.push_back(Kv("stable ties", std::to_string(e.ties)));
  if (!r.success) {
    s.level = diagnostic_msgs::DiagnosticStatus::ERROR;
    s.message = "no re-orientation: " + r.message;
    out.info = "camera '" + camera_.name + "': " + s.message;
    return out;
  }
  static const char* kAngle[] = {"theta", "phi", "kappa"};
  s.level = e.warnings.empty() ? diagnostic_msgs::DiagnosticStatus::OK
                               : diagnostic_msgs::DiagnosticStatus::WARN;
  s.message = e.warnings.empty() ? "re-oriented" : e.warnings.front();
  s.values.push_back(Kv("rotation [deg]", Fixed(r.rotation_angle * kDegPerRad, 5)));
  for (int k = 0; k < 3; ++k) {
    s.values.push_back(
        Kv(std::string("d") + kAngle[k] + " [deg]", Fixed(r.delta(k) * kDegPerRad, 5)));
    s.values.push_back(
        Kv(std::string("sigma ") + kAngle[k] + " [deg]", Fixed(r.sigma(k) * kDegPerRad, 5)));
  }
  s.values.push_back(Kv("rms [px]", Fixed(r.rms_px, 3)));
  s.values.push_back(Kv("stable points", std::to_string(r.num_points)));
  s.values.push_back(Kv("outliers", std::to_string(r.num_outliers)));
  out.site_from_optical = PoseTf(r.exterior, params_.frame_id, camera_.name, image.header.stamp);
  out.info = "camera '" + camera_.name + "': rotation " + Fixed(r.rotation_angle * kDegPerRad, 4) +
             " deg, rms " + Fixed(r.rms_px, 2) + " px over " + std::to_string(r.num_points) +
             " stable points";
  if (!e.has_field) return out;
  const dense::DisplacementField& f = e.field;
  s.values.push_back(Kv("probes", std::to_string(f.summary.probes)));
  s.values.push_back(Kv("usable", std::to_string(f.summary.usable)));
  s.values.push_back(Kv("window straddle", std::to_string(f.summary.straddling)));
  s.values.push_back(Kv("lsc variance factor", Fixed(f.summary.lsc_variance_factor, 2)));
  std::string flags;
  for (const auto& [flag, n] : f.summary.flags) {
    s.values.push_back(Kv("flag " + flag, std::to_string(n)));
    flags += " " + flag + " " + std::to_string(n);
  }
  std_msgs::Header h = image.header;
  h.frame_id = params_.frame_id;
  out.displacements = ToDisplacements(f, camera_.name, h, reference_stamp_, ++epoch_);
  out.info += "; field: " + std::to_string(f.summary.probes) + " probes, " +
              std::to_string(out.displacements->displacements.size()) + " published" +
              (flags.empty() ? "" : ", flagged:" + flags);
  if (!params_.report_dir.empty()) {
    const std::string path =
        params_.report_dir + "/" + dense::FieldPictureFileName(camera_.name, epoch_);
    try {
      std::filesystem::create_directories(params_.report_dir);
      dense::WriteDisplacementFieldPng(path, img, f, tracker_->model(), r.exterior,
                                       dense::FieldPictureOptions());
      out.picture = path;
      out.info += "; wrote " + path;
    } catch (const std::exception& e) {  // the field is published all the same
      out.warnings.push_back("camera '" + camera_.name + "': " + e.what());
    }
  }
  return out;
}

TargetlessCameras::TargetlessCameras(const TargetlessParameters& params) : params_(params) {
  for (const io::SiteCamera& c : params_.site.cameras)
    if (c.kind == io::CameraKind::kFixedTargetless)
      runners_[c.name] = std::make_unique<TargetlessCameraRunner>(params_, c);
}

std::vector<std::string> TargetlessCameras::cameras() const {
  std::vector<std::string> names;
  for (const auto& kv : runners_) names.push_back(kv.first);
  return names;
}

std::optional<TargetlessOutputs> TargetlessCameras::AddImage(
    const std::string& camera, const sensor_msgs::Image::ConstPtr& image) {
  if (!Handles(camera)) return std::nullopt;
  pending_[camera].images[image->header.stamp] = image;
  return Pair(camera, image->header.stamp);
}

std::optional<TargetlessOutputs> TargetlessCameras::AddCameraInfo(
    const std::string& camera, const sensor_msgs::CameraInfo::ConstPtr& info) {
  if (!Handles(camera)) return std::nullopt;
  pending_[camera].infos[info->header.stamp] = info;
  return Pair(camera, info->header.stamp);
}

std::optional<TargetlessOutputs> TargetlessCameras::Pair(const std::string& camera,
                                                         const ros::Time& stamp) {
  Pending& p = pending_[camera];
  const auto image = p.images.find(stamp);
  const auto info = p.infos.find(stamp);
  if (image == p.images.end() || info == p.infos.end()) return std::nullopt;
  const sensor_msgs::Image::ConstPtr im = image->second;
  const sensor_msgs::CameraInfo::ConstPtr ci = info->second;
  // Older unpaired messages are dropped with the pair.
  p.images.erase(p.images.begin(), std::next(image));
  p.infos.erase(p.infos.begin(), std::next(info));
  return runners_.at(camera)->OnImage(*im, *ci);
}

}  // namespace ros_adapters
}  // namespace slope_monitor
