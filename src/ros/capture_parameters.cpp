#include "slope_monitor/ros/capture_parameters.h"

#include <algorithm>
#include <array>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/io/target_file.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/uav_topics.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

// The site file (io::LoadSiteFile): the position priors' frame (its
// local_enu origin or its shifted_crs grid, unless site_origin is set), this
// camera's pixel size (its entry, by the camera's name, unless pixel_size is
// set; none: the photos' EXIF pitch) and a folder's picks from the site's gcp
// list.
void ApplyCaptureSiteFile(const std::string& path, bool origin_from_site, bool folder,
                          FramePublisherOptions* o) {
  const io::SiteFile site = io::LoadSiteFile(path);
  if (origin_from_site) {
    o->has_site_origin = true;
    if (site.crs.frame == SiteCrsOptions::Frame::kLocalEnu) {
      const Eigen::Vector3d lon_lat_h = SiteCrs(site.crs).origin_wgs84();
      o->site_origin = {lon_lat_h.y(), lon_lat_h.x(), lon_lat_h.z()};
    } else {
      o->site_crs = site.crs;  // shifted_crs: the priors in its grid
    }
  }
  const io::SiteCamera* camera = site.FindCamera(o->source_name);
  if (camera && !(o->pixel_size > 0.0)) o->pixel_size = camera->pixel_size;
  // Points picked in this UAV camera's photos (a gcp list as the site's
  // targets): published with each photo of a folder (names).
  if (folder && camera && camera->kind == io::CameraKind::kUav && site.targets &&
      io::IsGcpListName(site.targets_file)) {
    o->picks = PhotoPicks(site.targets_file, *site.targets);
    o->picks_file = site.targets_file;
  }
}

// site_origin and interior, checked (after the site file).
void ApplyOriginAndInterior(ParamReader& p, CaptureParameters* c) {
  FramePublisherOptions& o = c->publisher;
  if (!c->site_origin.empty()) {
    if (c->site_origin.size() != 3) {
      throw ConfigError(Message("parameter '", p.FullKey("site_origin"),
                                "' must be [lat_deg, lon_deg, height_m], got ",
                                c->site_origin.size(), " values"));
    }
    o.has_site_origin = true;
    o.site_origin = {c->site_origin[0], c->site_origin[1], c->site_origin[2]};
    capture::CheckGeodetic(o.site_origin, p.FullKey("site_origin").c_str());
  }
  if (c->interior.empty()) return;
  if (c->interior.size() != camera::kNumInterior) {
    throw ConfigError(Message("parameter '", p.FullKey("interior"), "' needs ",
                              camera::kNumInterior, " values (c x0 y0 k1 k2 k3 p1 p2 b1 b2), got ",
                              c->interior.size()));
  }
  if (!c->camera_info_url.empty()) {
    throw ConfigError(Message("parameters '", p.FullKey("interior"), "' and '",
                              p.FullKey("camera_info_url"), "' are both set; use one calibration"));
  }
  if (!(o.pixel_size > 0.0) || c->sensor_width <= 0 || c->sensor_height <= 0) {
    throw ConfigError(Message("parameter '", p.FullKey("interior"),
                              "' needs pixel_size, sensor_width and sensor_height"));
  }
  std::array<double, camera::kNumInterior> a{};
  std::copy(c->interior.begin(), c->interior.end(), a.begin());
  try {
    const camera::CameraModel m(camera::Sensor{c->sensor_width, c->sensor_height, o.pixel_size},
                                camera::DistortionModelFromName(c->distortion_model), a);
    m.Check();
    o.camera_info = ToMsg(m.ToCameraInfo());
    o.has_camera_info = true;
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message("parameter '", p.FullKey("interior"), "': ", e.what()));
  }
}

// The source's own keys: folder, video, device and schedule.
void ReadSources(ParamReader& p, CaptureParameters* c) {
  capture::FolderSourceOptions& f = c->folder;
  f.folder = p.String("folder", f.folder);
  f.extensions = p.StringList("extensions", f.extensions);
  f.time_source = p.String("time_source", f.time_source, {"exif", "file"});
  f.clock_offset = p.Double("clock_offset", f.clock_offset, -1e9, 1e9, "s");
  f.encoding = c->encoding;
  capture::VideoSourceOptions& v = c->video;
  v.path = p.String("video_file", v.path);
  v.start_time = p.Double("video_start_time", v.start_time, -1.0, 1e10, "s");
  v.fps = p.Double("video_fps", v.fps, 0.0, 1000.0, "Hz");
  v.frame_step = p.Int("frame_step", v.frame_step, 1, 100000);
  v.encoding = c->encoding;
  capture::DeviceSourceOptions& d = c->device;
  d.device = p.String("device", d.device);
  d.api = p.String("device_api", d.api, {"v4l2", "any"});
  d.width = p.Int("width", d.width, 0, 20000, "px");
  d.height = p.Int("height", d.height, 0, 20000, "px");
  d.fps = p.Double("fps", d.fps, 0.0, 1000.0, "Hz");
  d.exposure = p.Double("exposure", d.exposure, -1.0, 1e7, "device units");
  d.encoding = c->encoding;
  c->retry_interval = p.Double("retry_interval", c->retry_interval, 0.1, 3600.0, "s");
  c->continuous = p.Bool("continuous", c->continuous);
  capture::ScheduleOptions& s = c->schedule;
  s.interval = p.Double("schedule/interval", s.interval, 0.0, 7 * 86400.0, "s");
  s.windows = p.StringList("schedule/windows", s.windows);
  s.utc_offset_hours = p.Double("schedule/utc_offset", s.utc_offset_hours, -14.0, 14.0, "h");
  s.frames_per_epoch = p.Int("schedule/frames_per_epoch", s.frames_per_epoch, 1, 1000);
}

}  // namespace

CaptureParameters ReadCaptureParameters(ParamReader& p, const std::string& node_namespace) {
  CaptureParameters c;
  FramePublisherOptions& o = c.publisher;
  c.source = p.String("source", c.source, {"device", "folder", "video"});
  c.camera_name = p.String("camera_name", c.camera_name);
  // The camera's name by the graph's one rule (ros/uav_topics.h): ns /uav/camera is camera uav.
  o.source_name = p.String("source_name", CameraOfNamespace(node_namespace));
  c.site_file = p.String("site_file", c.site_file);
  o.frame_id = p.String("frame_id", c.camera_name + "_optical");
  c.camera_info_url = p.String("camera_info_url", c.camera_info_url);
  o.pixel_size = p.Double("pixel_size", o.pixel_size, 0.0, 1.0, "mm");
  c.interior = p.DoubleList("interior", c.interior);
  c.distortion_model = p.String("distortion_model", c.distortion_model,
                                {"none", "radial", "brown", "brown_affinity"});
  c.sensor_width = p.Int("sensor_width", c.sensor_width, 0, 100000, "px");
  c.sensor_height = p.Int("sensor_height", c.sensor_height, 0, 100000, "px");
  c.encoding = p.String("encoding", c.encoding, {"auto", "mono8", "bgr8"});
  c.rate = p.Double("rate", c.rate, 0.001, 1000.0, "Hz");
  c.start_delay = p.Double("start_delay", c.start_delay, 0.0, 3600.0, "s");
  c.subscriber_wait = p.Double("subscriber_wait", c.subscriber_wait, 0.0, 3600.0, "s");
  c.exit_at_end = p.Bool("exit_at_end", c.exit_at_end);
  ReadSources(p, &c);
  capture::EpochOptions& e = c.epochs;
  e.gap = p.Double("epoch_gap", e.gap, 1e-3, 1e9, "s");
  e.max_duration = p.Double("epoch_max_duration", e.max_duration, 0.0, 1e9, "s");
  e.first_epoch =
      static_cast<uint32_t>(p.Int("first_epoch", static_cast<int>(e.first_epoch), 0, 1000000000));
  c.site_origin = p.DoubleList("site_origin", c.site_origin);
  o.site_frame = p.String("site_frame", o.site_frame);
  o.gnss.sigma_horizontal =
      p.Double("gnss_sigma_horizontal", o.gnss.sigma_horizontal, 1e-4, 1e4, "m");
  o.gnss.sigma_vertical = p.Double("gnss_sigma_vertical", o.gnss.sigma_vertical, 1e-4, 1e4, "m");
  o.gnss.geoid_height = p.Double("geoid_height", o.gnss.geoid_height, -200.0, 200.0, "m");
  o.attitude_sigma = p.Double("attitude_sigma", o.attitude_sigma, 0.01, 180.0, "deg");
  p.CheckNoUnknownKeys();
  if (!c.site_file.empty())
    ApplyCaptureSiteFile(c.site_file, c.site_origin.empty(), c.source == "folder", &o);
  ApplyOriginAndInterior(p, &c);
  c.epochs.Check();
  if (c.source == "folder") {
    c.folder.Check();
    c.source_description = "folder " + c.folder.folder;
  } else if (c.source == "video") {
    c.video.Check();
    c.source_description = "video " + c.video.path;
  } else {
    c.device.Check();
    c.schedule.Check();
    c.source_description = (c.device.api == "v4l2" ? "V4L2 " : "camera ") + c.device.device;
  }
  return c;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
