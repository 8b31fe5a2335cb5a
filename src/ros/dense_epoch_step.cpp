#include "slope_monitor/ros/dense_epoch_step.h"

#include "slope_monitor/core/dense/change_polygons.h"
#include "slope_monitor/ros/change_area_conversions.h"

#include <cv_bridge/cv_bridge.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/image_limits.h"

namespace slope_monitor {
namespace ros_adapters {

namespace {

int64_t Nanoseconds(const ros::Time& t) { return static_cast<int64_t>(t.toNSec()); }

}  // namespace

dense::SurfaceSeriesOptions SeriesOptions(const DenseEpochParameters& p) {
  dense::SurfaceSeriesOptions o;
  o.surface = p.surface;
  o.change = p.change;
  o.outlines = p.outlines;
  o.stable_mask = p.stable_mask;
  o.report_dir = p.report_dir;
  o.site_crs = p.site_crs;
  return o;
}

dense::EpochOrientations OrientationsOf(const slope_monitor::AdjustmentSolution& s) {
  dense::EpochOrientations out;
  out.epoch = static_cast<int>(s.epoch);
  out.stamp_ns = Nanoseconds(s.header.stamp);
  out.adjusted_points = AdjustedPoints(s);
  for (const slope_monitor::CameraEstimate& e : s.cameras) {
    dense::PhotoOrientation o;
    o.camera = e.camera_name;
    o.stamp_ns = Nanoseconds(e.image_header.stamp);
    o.principal_distance = e.principal_distance;
    o.x0 = e.x0;
    o.y0 = e.y0;
    o.distortion = e.distortion;
    o.pose =
        camera::ExteriorOrientation::FromOpticalFromSite(FromPose(e.site_from_optical).Inverse());
    out.photos.push_back(std::move(o));
  }
  return out;
}

DenseEpochStep::DenseEpochStep(const DenseEpochParameters& parameters)
    : parameters_(parameters), photos_(parameters.photos), series_(SeriesOptions(parameters)) {}

void DenseEpochStep::OnCameraInfo(const std::string& camera, const sensor_msgs::CameraInfo& info) {
  if (!Uses(camera)) return;
  try {
    photos_.SetCamera(camera, CameraModelFromCameraInfo(info, parameters_.pixel_size));
  } catch (const Error& e) {
    throw InvalidArgument(Message("camera_info of '", camera, "': ", e.what()));
  }
}

std::vector<dense::PhotoEpoch> DenseEpochStep::OnImage(const std::string& camera,
                                                       const sensor_msgs::Image& image,
                                                       double now) {
  if (!Uses(camera)) return {};
  dense::Photo photo;
  photo.camera = camera;
  photo.stamp_ns = Nanoseconds(image.header.stamp);
  try {
    CheckImageMessage(image);
    photo.image = cv_bridge::toCvCopy(image)->image;
  } catch (const std::exception& e) {
    log_.push_back({LogLine::kWarn, Message("image of '", camera, "' at ",
                                            image.header.stamp.toSec(), " dropped: ", e.what())});
    return {};
  }
  std::vector<dense::PhotoEpoch> done = photos_.AddPhoto(std::move(photo), now);
  for (const std::string& line : photos_.TakeDropped()) log_.push_back({LogLine::kWarn, line});
  return done;
}

std::vector<dense::PhotoEpoch> DenseEpochStep::OnSolution(
    const slope_monitor::AdjustmentSolution& solution, double now) {
  if (!solution.usable) {
    log_.push_back({LogLine::kWarn,
                    Message("epoch ", solution.epoch, " not measured: the solution is not usable (",
                            solution.message, ")")});
    return {};
  }
  return photos_.AddSolution(OrientationsOf(solution), now);
}

std::vector<LogLine> DenseEpochStep::TakeLog() {
  std::vector<LogLine> out;
  out.swap(log_);
  return out;
}

DenseEpochOutput DenseEpochStep::Measure(const dense::PhotoEpoch& e,
                                         const std::function<void(const std::string&)>& progress) {
  DenseEpochOutput out;
  out.epoch = e.input.epoch;
  if (!e.missing.empty())
    out.log.push_back({LogLine::kWarn, Message("epoch ", e.input.epoch, ": ", e.missing.size(),
                                               " oriented photo(s) not used (", e.reason,
                                               "; first: ", e.missing.front(), ")")});
  if (!e.no_surface.empty()) {
    // A survey without a UAV flight and without stereo pairs: not an error
    // (debug: process_bag does not print it for each epoch; the node does).
    out.log.push_back({LogLine::kDebug, e.no_surface});
    return out;
  }
  const dense::SeriesEpoch s = series_.Measure(e.input, progress);
  for (const std::string& error : s.errors) out.log.push_back({LogLine::kError, error});
  out.files = s.files;
  if (!s.surface) return out;
  out.log.push_back({LogLine::kInfo, s.surface->summary.BriefReport()});
  if (s.change_summary)
    out.log.push_back({LogLine::kInfo, Message("epoch ", e.input.epoch,
                                               " change: ", s.change_summary->BriefReport())});
  std_msgs::Header header;
  header.stamp.fromNSec(static_cast<uint64_t>(e.stamp_ns));
  header.frame_id = parameters_.frame_id;
  out.cloud = MakeSurfaceCloud(*s.surface, s.change ? &*s.change : nullptr, header);
  if (!s.surface->points.empty())
    out.legend = MakeChangeScaleBeside(*s.surface, parameters_.change_scale, header);
  if (reference_epoch_ < 0) reference_epoch_ = e.input.epoch;
  if (s.change) {
    try {
      const std::vector<dense::ChangePolygon> polygons =
          dense::ChangePolygons(s.change->change, dense::ChangePolygonOptions());
      out.log.push_back({LogLine::kInfo, Message("epoch ", e.input.epoch, ": ", polygons.size(),
                                                 " area(s) of significant change")});
      out.areas = ToChangeAreaMsg(polygons, static_cast<uint32_t>(e.input.epoch),
                                  static_cast<uint32_t>(reference_epoch_), header);
    } catch (const std::exception& ex) {
      out.log.push_back(
          {LogLine::kError,
           Message("epoch ", e.input.epoch, " change polygons (the DoD is kept): ", ex.what())});
    }
  }
  return out;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
