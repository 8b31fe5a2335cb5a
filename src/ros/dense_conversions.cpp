#include "slope_monitor/ros/dense_conversions.h"

#include "slope_monitor/ros/param_files.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <cv_bridge/cv_bridge.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_eigen/tf2_eigen.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/dense_epoch_step.h"
#include "slope_monitor/ros/image_limits.h"

namespace slope_monitor {
namespace ros_adapters {

dense::EpochImage EpochImageFromEstimate(const slope_monitor::CameraEstimate& e,
                                         const sensor_msgs::Image& image,
                                         const sensor_msgs::CameraInfo& info, double pixel_size,
                                         dense::ImageKind kind) {
  dense::Photo photo;
  photo.camera = e.camera_name;
  photo.stamp_ns = static_cast<int64_t>(e.image_header.stamp.toNSec());
  CheckImageMessage(image);
  photo.image = cv_bridge::toCvCopy(image)->image;
  slope_monitor::AdjustmentSolution one;
  one.cameras.push_back(e);
  return dense::OrientPhoto(photo, CameraModelFromCameraInfo(info, pixel_size),
                            OrientationsOf(one).photos.front(), kind);
}

std::vector<Eigen::Vector3d> AdjustedPoints(const slope_monitor::AdjustmentSolution& solution) {
  std::vector<Eigen::Vector3d> points;
  for (const slope_monitor::PointEstimate& p : solution.points)
    points.emplace_back(p.position.x, p.position.y, p.position.z);
  return points;
}

sensor_msgs::PointCloud2 MakeSurfaceCloud(const dense::EpochSurfaceResult& surface,
                                          const dense::DemChangeResult* change,
                                          const std_msgs::Header& header) {
  sensor_msgs::PointCloud2 cloud;
  cloud.header = header;
  sensor_msgs::PointCloud2Modifier mod(cloud);
  using sensor_msgs::PointField;
  mod.setPointCloud2Fields(7, "x", 1, PointField::FLOAT32, "y", 1, PointField::FLOAT32, "z", 1,
                           PointField::FLOAT32, "rgb", 1, PointField::FLOAT32, "sigma_z", 1,
                           PointField::FLOAT32, "change", 1, PointField::FLOAT32, "lod", 1,
                           PointField::FLOAT32);
  mod.resize(surface.points.size());
  sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z"),
      rgb(cloud, "rgb"), sz(cloud, "sigma_z"), ch(cloud, "change"), lod(cloud, "lod");
  for (const dense::EpochPoint& p : surface.points) {
    *x = static_cast<float>(p.x_in_site.x());
    *y = static_cast<float>(p.x_in_site.y());
    *z = static_cast<float>(p.x_in_site.z());
    const uint32_t packed =
        (uint32_t(p.bgr[2]) << 16) | (uint32_t(p.bgr[1]) << 8) | uint32_t(p.bgr[0]);
    std::memcpy(&*rgb, &packed, sizeof packed);
    *sz = p.sigma_z;
    *ch = *lod = std::numeric_limits<float>::quiet_NaN();
    int row, col;
    if (change && change->change.CellOf(p.x_in_site.x(), p.x_in_site.y(), &row, &col)) {
      *ch = change->change.At(dense::kChange, row, col);
      *lod = change->change.At(dense::kLodBand, row, col);
    }
    ++x, ++y, ++z, ++rgb, ++sz, ++ch, ++lod;
  }
  return cloud;
}

visualization_msgs::MarkerArray MakeChangeScaleBeside(const dense::EpochSurfaceResult& surface,
                                                      const ChangeScaleOptions& options,
                                                      const std_msgs::Header& header) {
  if (surface.points.empty()) return {};
  Eigen::Vector3d lo = surface.points.front().x_in_site, hi = lo;
  for (const dense::EpochPoint& p : surface.points) {
    lo = lo.cwiseMin(p.x_in_site);
    hi = hi.cwiseMax(p.x_in_site);
  }
  const double side = std::max(hi.x() - lo.x(), hi.y() - lo.y());
  const Eigen::Vector3d base(hi.x() + 0.05 * side, 0.5 * (lo.y() + hi.y()), lo.z());
  return ToChangeScaleMarkers(options, base, 0.5 * side, header);
}

DenseEpochParameters ReadDenseEpochParameters(ParamReader& p) {
  DenseEpochParameters d;
  dense::SurfaceOptions& s = d.surface.surface;
  dense::CorrelationOptions& c = s.correlation;
  c.levels = p.Int("levels", c.levels, 1, 5);
  c.peak_frequency = p.Double("peak_frequency", c.peak_frequency, 0.01, 3.0, "rad/px");
  c.grid_spacing = p.Int("grid_spacing", c.grid_spacing, 1, 64, "px");
  c.final_grid_spacing = p.Int("final_grid_spacing", c.final_grid_spacing, 1, 64, "px");
  c.window = p.Int("window", c.window, 3, 51, "px");
  c.final_window = p.Int("final_window", c.final_window, 0, 51, "px");
  c.lsc_iterations = p.Int("lsc_iterations", c.lsc_iterations, 0, 20);
  c.search_radius = p.Int("search_radius", c.search_radius, 1, 16, "px");
  c.min_correlation = p.Double("min_correlation", c.min_correlation, -1.0, 0.999);
  s.rectify.scale = p.Double("rectify_scale", s.rectify.scale, 0.05, 4.0);
  s.rectify.patch_size = p.Int("patch_size", s.rectify.patch_size, 0, 8192, "px");
  s.cell_size = p.Double("cell_size", s.cell_size, 1e-3, 100.0, "m");
  s.min_points_per_cell = p.Int("min_points_per_cell", s.min_points_per_cell, 1, 1000);
  s.parallax_sigma = p.Double("parallax_sigma", s.parallax_sigma, 1e-3, 10.0, "px");
  d.surface.min_pair_overlap = p.Double("min_pair_overlap", d.surface.min_pair_overlap, 0.01, 1.0);
  d.surface.depth_margin = p.Double("depth_margin", d.surface.depth_margin, 0.0, 10.0);
  d.surface.max_pairs_per_image =
      p.Int("max_pairs_per_image", d.surface.max_pairs_per_image, 1, 100);
  d.surface.max_dem_megabytes =
      p.Double("max_dem_megabytes", d.surface.max_dem_megabytes, 1e-3, 1e5, "MB");
  const Eigen::Vector4d& r0 = d.surface.region;
  const std::vector<double> region = p.DoubleList("region", {r0[0], r0[1], r0[2], r0[3]});
  if (region.size() != 4)
    throw ConfigError(
        Message("parameter '", p.FullKey("region"), "' must be [xmin, xmax, ymin, ymax] (m)"));
  d.surface.region = Eigen::Vector4d(region[0], region[1], region[2], region[3]);
  dense::DemChangeOptions& dc = d.change.change;
  dc.lod_factor = p.Double("lod_factor", dc.lod_factor, 0.01, 10.0);
  dc.coregistration_iterations =
      p.Int("coregistration_iterations", dc.coregistration_iterations, 0, 20);
  dc.min_stable_cells = p.Int("min_stable_cells", dc.min_stable_cells, 4, 1000000000);
  d.change.search_radius =
      p.Double("coregistration_search_radius", d.change.search_radius, 0.0, dc.max_shift, "m");
  // The LoD: one global stable residual, or process_flight's heteroscedastic
  // model (bins by slope and roughness; doc/real_surfaces.md).
  dense::ErrorModelOptions& em = dc.error_model;
  const std::string lod_model = p.String("lod_model", em.enabled ? "slope_roughness" : "global");
  if (lod_model != "global" && lod_model != "slope_roughness")
    throw ConfigError(Message("parameter '", p.FullKey("lod_model"), "' = '", lod_model,
                              "' must be global or slope_roughness"));
  em.enabled = lod_model == "slope_roughness";
  using Spread = dense::ErrorModelOptions::Spread;
  const std::string spread =
      p.String("lod_bin_spread", em.spread == Spread::kQuantile ? "quantile" : "nmad");
  if (spread != "nmad" && spread != "quantile")
    throw ConfigError(Message("parameter '", p.FullKey("lod_bin_spread"), "' = '", spread,
                              "' must be nmad or quantile"));
  em.spread = spread == "quantile" ? Spread::kQuantile : Spread::kNmad;
  d.monitored_outline = p.DoubleList("monitored_outline", d.monitored_outline);
  const std::vector<double>& outline = d.monitored_outline;
  if (outline.size() % 2 != 0 || (!outline.empty() && outline.size() < 6))
    throw ConfigError(
        Message("parameter '", p.FullKey("monitored_outline"),
                "' must be [x1, y1, x2, y2, x3, y3, ...] (m, site; at least 3 vertices)"));
  if (!outline.empty()) {
    d.outlines.emplace_back();
    for (size_t i = 0; i < outline.size(); i += 2)
      d.outlines.back().emplace_back(outline[i], outline[i + 1]);
  }
  d.stable_mask = p.String("stable_mask", d.stable_mask);
  std::vector<std::string> default_cameras;
  for (const io::SiteCamera& cam : io::DefaultCameras()) default_cameras.push_back(cam.name);
  d.cameras = p.StringList("cameras", default_cameras);
  d.uav_cameras =
      p.StringList("uav_cameras", io::CameraNames(io::DefaultCameras(), io::CameraKind::kUav));
  // A site file that lists cameras decides them and their kinds (the two
  // parameters above are then not used).
  d.site_file = p.String("site_file", d.site_file);
  if (!d.site_file.empty()) {
    const io::SiteFile site = io::LoadSiteFile(d.site_file);
    d.site_crs = site.crs;
    if (!site.cameras.empty()) {
      d.cameras.clear();
      d.uav_cameras.clear();
      for (const io::SiteCamera* cam : site.CamerasWithTargets()) {
        d.cameras.push_back(cam->name);
        if (cam->kind == io::CameraKind::kUav) d.uav_cameras.push_back(cam->name);
      }
    }
  }
  // Without a site file, the estimator overlay's geodetic_origin (as the
  // reports: deformation::ReportSiteCrs) georeferences the GeoTIFFs.
  d.site_config = p.String("site_config", d.site_config);
  if (!d.site_crs && !d.site_config.empty()) d.site_crs = SiteCrsOfOverlay(d.site_config);
  std::vector<std::string> default_pairs;
  for (const auto& pair : d.stereo_pairs)
    default_pairs.insert(default_pairs.end(), {pair.first, pair.second});
  const std::vector<std::string> pairs = p.StringList("stereo_pairs", default_pairs);
  d.stereo_pairs.clear();
  if (pairs.size() % 2 != 0)
    throw ConfigError(Message("parameter '", p.FullKey("stereo_pairs"),
                              "' must list cameras in pairs (left, right)"));
  for (size_t i = 0; i < pairs.size(); i += 2) d.stereo_pairs.push_back({pairs[i], pairs[i + 1]});
  d.pixel_size = p.Double("pixel_size", d.pixel_size, 1e-6, 1.0, "mm/px");
  dense::PhotoCollectorOptions& ph = d.photos;
  ph.uav_cameras = d.uav_cameras;
  ph.stereo_pairs = d.stereo_pairs;
  ph.max_photos = p.Int("max_cached_images", ph.max_photos, 1, 10000);
  ph.max_megabytes = p.Double("max_cached_megabytes", ph.max_megabytes, 1e-3, 1e5, "MB");
  ph.photo_wait = p.Double("photo_wait", ph.photo_wait, 0.0, 1e6, "s");
  d.frame_id = p.String("frame_id", d.frame_id);
  d.report_dir = p.String("report_dir", d.report_dir);
  ChangeScaleOptions& cs = d.change_scale;
  cs.min = p.Double("change_colour_min", cs.min, -1e3, 1e3, "m");
  cs.max = p.Double("change_colour_max", cs.max, -1e3, 1e3, "m");
  try {
    cs.Check();
  } catch (const ConfigError& e) {
    throw ConfigError(Message("parameters '", p.FullKey("change_colour_min"), "', '",
                              p.FullKey("change_colour_max"), "': ", e.what()));
  }
  p.CheckNoUnknownKeys();
  d.surface.Check();
  d.change.Check();
  d.photos.Check();
  return d;
}

std::optional<SiteCrsOptions> SiteCrsOfOverlay(const std::string& site_config) {
  XmlRpc::XmlRpcValue overlay = LoadParamFile(site_config);
  ParamReader o(overlay, site_config);
  const std::vector<double> origin = o.DoubleList("geodetic_origin", {});
  if (!origin.empty() && origin.size() != 3)
    throw ConfigError(Message("'geodetic_origin' in ", site_config,
                              " must be [latitude, longitude, height] (deg, deg, m)"));
  if (origin.size() != 3) return std::nullopt;
  return SiteCrs::LocalEnuAtWgs84(origin[0], origin[1], origin[2]).options();
}

DenseMatcherParameters ReadDenseMatcherParameters(ParamReader& p) {
  DenseMatcherParameters d;
  dense::SurfaceOptions& o = d.surface;
  dense::CorrelationOptions& c = o.correlation;
  c.levels = p.Int("levels", c.levels, 1, 5);
  c.peak_frequency = p.Double("peak_frequency", c.peak_frequency, 0.01, 3.0, "rad/px");
  c.grid_spacing = p.Int("grid_spacing", c.grid_spacing, 1, 64, "px");
  c.final_grid_spacing = p.Int("final_grid_spacing", c.final_grid_spacing, 1, 64, "px");
  c.window = p.Int("window", c.window, 3, 51, "px");
  c.final_window = p.Int("final_window", c.final_window, 0, 51, "px");
  c.lsc_iterations = p.Int("lsc_iterations", c.lsc_iterations, 0, 20);
  c.search_radius = p.Int("search_radius", c.search_radius, 1, 16, "px");
  c.final_search_radius = p.Int("final_search_radius", c.final_search_radius, 0, 16, "px");
  c.edge_window = p.Int("edge_window", c.edge_window, 0, 51, "px");
  c.edge_parallax_step = p.Double("edge_parallax_step", c.edge_parallax_step, 0.01, 100.0, "px");
  c.min_correlation = p.Double("min_correlation", c.min_correlation, -1.0, 0.999);
  c.lr_tolerance = p.Double("lr_tolerance", c.lr_tolerance, 0.01, 10.0, "px");
  c.order_tolerance = p.Double("order_tolerance", c.order_tolerance, 0.0, 10.0, "px");
  c.median_filter = p.Bool("median_filter", c.median_filter);
  c.order_check = p.Bool("order_check", c.order_check);
  c.two_way = p.Bool("two_way", c.two_way);
  c.full_right_search = p.Bool("full_right_search", c.full_right_search);
  o.rectify.scale = p.Double("rectify_scale", o.rectify.scale, 0.05, 4.0);
  o.rectify.patch_size = p.Int("patch_size", o.rectify.patch_size, 0, 8192, "px");
  o.rectify.patch_overlap = p.Int("patch_overlap", o.rectify.patch_overlap, 0, 4096, "px");
  o.rectify.min_baseline = p.Double("min_baseline", o.rectify.min_baseline, 1e-9, 1e6, "m");
  o.rectify.min_overlap = p.Double("min_overlap", o.rectify.min_overlap, 0.0, 1.0);
  o.cell_size = p.Double("cell_size", o.cell_size, 1e-3, 100.0, "m");
  o.min_points_per_cell = p.Int("min_points_per_cell", o.min_points_per_cell, 1, 1000);
  o.parallax_sigma = p.Double("parallax_sigma", o.parallax_sigma, 1e-3, 10.0, "px");
  o.max_ray_gap = p.Double("max_ray_gap", o.max_ray_gap, 0.0, 1e3, "m");
  o.ortho_cell_size = p.Double("ortho_cell_size", o.ortho_cell_size, 0.0, 100.0, "m");
  d.config.min_depth = p.Double("min_depth", d.config.min_depth, 1e-3, 1e6, "m");
  d.config.max_depth = p.Double("max_depth", d.config.max_depth, 1e-3, 1e6, "m");
  const Eigen::Vector4d& r0 = d.config.region;
  const std::vector<double> region = p.DoubleList("region", {r0[0], r0[1], r0[2], r0[3]});
  if (region.size() != 4)
    throw ConfigError(
        Message("parameter '", p.FullKey("region"), "' must be [xmin, xmax, ymin, ymax] (m)"));
  d.config.region = Eigen::Vector4d(region[0], region[1], region[2], region[3]);
  d.change.lod_factor = p.Double("lod_factor", d.change.lod_factor, 0.0, 10.0);
  d.change.min_lod = p.Double("min_lod", d.change.min_lod, 0.0, 100.0, "m");
  d.pixel_size = p.Double("pixel_size", d.pixel_size, 1e-6, 1.0, "mm/px");
  d.max_pair_dt = p.Double("max_pair_dt", d.max_pair_dt, 0.0, 1e6, "s");
  d.frame_id = p.String("frame_id", d.frame_id);
  d.output_dir = p.String("output_dir", d.output_dir);
  d.tf_timeout = p.Double("tf_timeout", d.tf_timeout, 0.0, 60.0, "s");
  // The GeoTIFFs' map CRS: the site file's crs, else the overlay's geodetic_origin.
  d.site_file = p.String("site_file", d.site_file);
  if (!d.site_file.empty()) d.site_crs = io::LoadSiteFile(d.site_file).crs;
  d.site_config = p.String("site_config", d.site_config);
  if (!d.site_crs && !d.site_config.empty()) d.site_crs = SiteCrsOfOverlay(d.site_config);
  p.CheckNoUnknownKeys();
  d.surface.Check();
  d.change.Check();
  if (!(d.config.max_depth > d.config.min_depth))
    throw ConfigError(Message("parameter '", p.FullKey("max_depth"), "' = ", d.config.max_depth,
                              " must be > min_depth = ", d.config.min_depth));
  return d;
}

dense::OrientedImage PairImage(const sensor_msgs::Image::ConstPtr& image,
                               const sensor_msgs::CameraInfo& info, double pixel_size) {
  dense::OrientedImage im;
  im.name = image->header.frame_id;
  CheckImageMessage(*image);  // pixel budget and data size
  const cv_bridge::CvImageConstPtr cv = cv_bridge::toCvShare(image);
  im.image = cv->image;
  im.camera = CameraModelFromCameraInfo(info, pixel_size);
  return im;
}

void OrientPairImage(const geometry_msgs::TransformStamped& site_from_optical,
                     dense::OrientedImage* image) {
  const Eigen::Isometry3d t = tf2::transformToEigen(site_from_optical);
  const Rigid3 optical_from_site = Rigid3(Eigen::Matrix3d(t.rotation()), t.translation()).Inverse();
  image->pose = camera::ExteriorOrientation::FromOpticalFromSite(optical_from_site);
  image->oriented = true;
}

sensor_msgs::PointCloud2 PairSurfaceCloud(const dense::SurfaceResult& s,
                                          const std_msgs::Header& header) {
  return MakeFloatCloud(header, {"x", "y", "z", "intensity", "sigma_z"}, s.points.size(),
                        [&](size_t i, float* v) {
                          const dense::SurfacePoint& p = s.points[i];
                          v[0] = p.x_in_site.x();
                          v[1] = p.x_in_site.y();
                          v[2] = p.x_in_site.z();
                          v[3] = p.intensity;
                          v[4] = p.sigma_z;
                        });
}

sensor_msgs::PointCloud2 PairChangeCloud(const dense::ChangeResult& c,
                                         const std_msgs::Header& header) {
  return MakeFloatCloud(header, {"x", "y", "z", "dz", "lod"}, c.significant.size(),
                        [&](size_t i, float* v) {
                          const dense::ChangePoint& p = c.significant[i];
                          v[0] = p.x_in_site.x();
                          v[1] = p.x_in_site.y();
                          v[2] = p.x_in_site.z();
                          v[3] = p.dz;
                          v[4] = p.lod;
                        });
}

}  // namespace ros_adapters
}  // namespace slope_monitor
