#include "slope_monitor/ros/capture_conversions.h"

#include <cmath>
#include <filesystem>
#include <limits>

#include <cv_bridge/cv_bridge.h>

namespace slope_monitor {
namespace ros_adapters {

std_msgs::Header FrameHeader(const capture::Frame& frame, const std::string& frame_id) {
  std_msgs::Header h;
  h.stamp.fromSec(frame.stamp);
  h.frame_id = frame_id;
  return h;
}

sensor_msgs::ImagePtr ToImageMsg(const capture::Frame& frame, const std_msgs::Header& header) {
  return cv_bridge::CvImage(header, frame.encoding, frame.image).toImageMsg();
}

sensor_msgs::NavSatFix ToNavSatFix(const capture::ExifInfo& exif, const GnssOptions& o,
                                   const std_msgs::Header& header) {
  sensor_msgs::NavSatFix fix;
  fix.header = header;
  fix.status.status = sensor_msgs::NavSatStatus::STATUS_FIX;
  fix.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS;
  fix.latitude = exif.gps.latitude_deg;
  fix.longitude = exif.gps.longitude_deg;
  fix.altitude = exif.has_gps_altitude ? exif.gps.height_m + o.geoid_height
                                       : std::numeric_limits<double>::quiet_NaN();
  const double h2 = o.sigma_horizontal * o.sigma_horizontal;
  const double v2 = o.sigma_vertical * o.sigma_vertical;
  fix.position_covariance = {h2, 0.0, 0.0, 0.0, h2, 0.0, 0.0, 0.0, v2};
  fix.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_APPROXIMATED;
  return fix;
}

geometry_msgs::PoseWithCovarianceStamped ToPositionPrior(const sensor_msgs::NavSatFix& fix,
                                                         const capture::SiteFrame& site,
                                                         const std::string& site_frame) {
  const capture::Geodetic g{fix.latitude, fix.longitude, fix.altitude};
  const Eigen::Vector3d x = site.ToSite(g);
  Eigen::Matrix3d cov;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) cov(r, c) = fix.position_covariance[3 * r + c];
  const Eigen::Matrix3d cov_site = site.CovarianceToSite(g, cov);
  geometry_msgs::PoseWithCovarianceStamped prior;
  prior.header = fix.header;
  prior.header.frame_id = site_frame;
  prior.pose.pose.position.x = x.x();
  prior.pose.pose.position.y = x.y();
  prior.pose.pose.position.z = x.z();
  prior.pose.pose.orientation.w = 1.0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) prior.pose.covariance[6 * r + c] = cov_site(r, c);
  for (int i = 3; i < 6; ++i) prior.pose.covariance[6 * i + i] = 1e6;
  return prior;
}

void SetNadirAttitude(double yaw_deg, double sigma_deg,
                      geometry_msgs::PoseWithCovarianceStamped* prior) {
  const Eigen::Quaterniond q = capture::SiteFromOpticalNadir(yaw_deg);
  prior->pose.pose.orientation.w = q.w();
  prior->pose.pose.orientation.x = q.x();
  prior->pose.pose.orientation.y = q.y();
  prior->pose.pose.orientation.z = q.z();
  const double variance = std::pow(sigma_deg * M_PI / 180.0, 2);
  for (int i = 3; i < 6; ++i) prior->pose.covariance[6 * i + i] = variance;
}

slope_monitor::EpochMarker ToEpochMarker(const capture::EpochEvent& e, const std::string& source,
                                         const std::string& frame_id) {
  slope_monitor::EpochMarker m;
  m.header.stamp.fromSec(e.stamp);
  m.header.frame_id = frame_id;
  m.epoch = e.epoch;
  m.end = e.end;
  m.source = source;
  m.count = e.count;
  return m;
}

}  // namespace ros_adapters
}  // namespace slope_monitor

// ---------------------------------------------------------------------------
#include "slope_monitor/core/capture/calibration.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/gcp_list.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/target_conversions.h"

namespace slope_monitor {
namespace ros_adapters {

FramePublisher::FramePublisher(const FramePublisherOptions& options, CaptureOutputs outputs)
    : options_(options), outputs_(std::move(outputs)) {
  if (options_.site_crs)
    site_ = std::make_unique<capture::SiteFrame>(*options_.site_crs);
  else if (options_.has_site_origin)
    site_ = std::make_unique<capture::SiteFrame>(options_.site_origin);
}

void FramePublisher::Warn(const std::string& text) {
  last_warning_ = text;
  if (outputs_.warn) outputs_.warn(text);
}

sensor_msgs::CameraInfo FramePublisher::CameraInfoFor(const capture::Frame& frame) {
  const int w = frame.image.cols, h = frame.image.rows;
  if (options_.has_camera_info) {
    if (!calibration_checked_) {
      calibration_checked_ = true;
      try {
        capture::CheckCameraInfo(FromMsg(options_.camera_info),
                                 options_.pixel_size > 0 ? options_.pixel_size : 1.0, w, h,
                                 "camera_info of " + options_.source_name);
      } catch (const Error& e) {
        Warn(Message("calibration inconsistent with the collinearity model or the image: ",
                     e.what()));
      }
    }
    return options_.camera_info;
  }
  // The pixel pitch: the parameter (or the site file's entry), else the
  // photo's own EXIF (FocalPlaneXResolution), as process_flight reads it.
  const double pixel_size = options_.pixel_size > 0.0       ? options_.pixel_size
                            : frame.attitude.has_pixel_size ? frame.attitude.pixel_size_mm
                                                            : 0.0;
  if (pixel_size > 0.0 && frame.exif.focal_length_mm > 0.0) {
    try {
      return ToMsg(
          capture::NominalModelFromExif(frame.exif, w, h, pixel_size, frame.name).ToCameraInfo());
    } catch (const Error& e) {
      Warn(e.what());
    }
  }
  sensor_msgs::CameraInfo info;  // uncalibrated (camera_info_manager's convention)
  info.width = static_cast<uint32_t>(w);
  info.height = static_cast<uint32_t>(h);
  return info;
}

void FramePublisher::PublishEpoch(const capture::EpochEvent& event) {
  if (outputs_.epoch) outputs_.epoch(ToEpochMarker(event, options_.source_name, options_.frame_id));
}

std::map<std::string, std::vector<slope_monitor::TargetObservation>> PhotoPicks(
    const std::string& gcp_file, const io::TargetList& targets) {
  io::GcpList gcp;
  try {
    gcp = io::ReadGcpList(gcp_file);
  } catch (const std::exception& e) {
    throw ConfigError(Message("gcp list: ", e.what()));
  }
  const std::map<std::string, int> ids = io::GcpTargetIds(gcp);
  std::map<std::string, std::vector<slope_monitor::TargetObservation>> out;
  for (const io::GcpPoint& p : gcp.points) {
    const io::TargetSpec* spec = targets.Find(io::kGcpFamily, ids.at(p.name));
    for (const io::GcpPick& k : p.picks) {
      slope_monitor::TargetObservation o;
      o.id = ids.at(p.name);
      o.family = io::kGcpFamily;
      o.role = TargetRoleToMsg(spec ? std::optional<io::TargetRole>(spec->role) : std::nullopt);
      o.x = k.pixel.x();
      o.y = k.pixel.y();
      const double v = io::kGcpPickSigmaPx * io::kGcpPickSigmaPx;
      o.covariance = {v, 0.0, 0.0, v};
      o.quality = 1.0;
      out[k.image].push_back(o);
    }
  }
  return out;
}

// The picks of the frame's photo (by file name), on `picks` with the image's header.
void FramePublisher::PublishPicks(const capture::Frame& frame, const std_msgs::Header& header) {
  const std::string name = std::filesystem::path(frame.name).filename().string();
  const auto it = options_.picks.find(name);
  if (it == options_.picks.end()) return;
  slope_monitor::TargetObservationArray msg;
  msg.header = header;
  msg.camera_name = options_.source_name;
  msg.image_width = static_cast<uint32_t>(frame.image.cols);
  msg.image_height = static_cast<uint32_t>(frame.image.rows);
  msg.observations = it->second;
  outputs_.picks(msg);
  picked_photos_published_.insert(name);
}

// At the end of the source: photos of the gcp list that were not published.
void FramePublisher::WarnUnpublishedPicks() {
  for (const auto& [name, picks] : options_.picks)
    if (!picked_photos_published_.count(name))
      Warn(Message(options_.picks_file, ": photo '", name, "' was not published (not in the ",
                   "source, or left out): its ", picks.size(), " pick(s) left out"));
}

void FramePublisher::PublishFrame(const capture::Frame& frame, sensor_msgs::ImagePtr image) {
  const std_msgs::Header header = FrameHeader(frame, options_.frame_id);
  if (outputs_.picks && !options_.picks.empty()) PublishPicks(frame, header);
  if (outputs_.image) {
    sensor_msgs::CameraInfoPtr info(new sensor_msgs::CameraInfo(CameraInfoFor(frame)));
    info->header = header;
    if (image && frame.in_image_buffer && !image->data.empty() &&
        frame.image.data == image->data.data() && frame.image.isContinuous()) {
      // The pixels are already in the message (decoded into it): fill in the rest.
      image->header = header;
      image->height = static_cast<uint32_t>(frame.image.rows);
      image->width = static_cast<uint32_t>(frame.image.cols);
      image->encoding = frame.encoding;
      image->is_bigendian = 0;
      image->step = static_cast<uint32_t>(frame.image.cols * frame.image.elemSize());
    } else {
      image = ToImageMsg(frame, header);
    }
    outputs_.image(image, info);
  }
  if (frame.exif.has_gps) {
    const sensor_msgs::NavSatFix fix = ToNavSatFix(frame.exif, options_.gnss, header);
    if (outputs_.fix) outputs_.fix(fix);
    if (site_ && outputs_.prior) {
      if (frame.exif.has_gps_altitude) {
        geometry_msgs::PoseWithCovarianceStamped prior =
            ToPositionPrior(fix, *site_, options_.site_frame);
        if (frame.attitude.has_yaw) {
          const capture::Geodetic at{fix.latitude, fix.longitude, fix.altitude};
          SetNadirAttitude(site_->HeadingToSite(at, frame.attitude.yaw_deg),
                           options_.attitude_sigma, &prior);
        }
        outputs_.prior(prior);
      } else {
        Warn(Message(frame.name, ": EXIF GNSS position has no altitude; no position prior"));
      }
    }
  }
  ++published_;
}

FramePublisher::StepResult FramePublisher::Step(capture::FrameSource* source,
                                                capture::EpochTracker* tracker, bool look_ahead) {
  capture::Frame frame;
  // Let the source decode into the outgoing message's data (no copy).
  sensor_msgs::ImagePtr image;
  if (outputs_.image) {
    source->set_image_buffer([&image](int rows, int cols, int type) {
      image.reset(new sensor_msgs::Image);
      const size_t step = static_cast<size_t>(cols) * CV_ELEM_SIZE(type);
      image->data.resize(step * static_cast<size_t>(rows));
      return cv::Mat(rows, cols, type, image->data.data(), step);
    });
  }
  struct ClearBuffer {
    capture::FrameSource* source;
    ~ClearBuffer() { source->set_image_buffer({}); }
  } clear_buffer{source};
  const bool got = source->Next(&frame);
  for (const auto& s : source->TakeSkipped()) {
    ++skipped_;
    // The reason usually starts with the file name already.
    const bool named = s.reason.rfind(s.name + ": ", 0) == 0;
    Warn(Message("skipped ", s.name, ": ", named ? s.reason.substr(s.name.size() + 2) : s.reason,
                 " (", source->skipped_count(), " skipped so far)"));
  }
  if (!got) {
    if (auto end = tracker->Close()) PublishEpoch(*end);
    WarnUnpublishedPicks();
    return StepResult::kEnd;
  }
  for (const auto& e : tracker->BeforeFrame(frame.stamp)) PublishEpoch(e);
  PublishFrame(frame, frame.in_image_buffer ? image : nullptr);
  if (look_ahead) {
    for (const auto& e : tracker->AfterFrame(source->PeekNextStamp(), true)) PublishEpoch(e);
  }
  return StepResult::kPublished;
}

}  // namespace ros_adapters
}  // namespace slope_monitor

// ---------------------------------------------------------------------------
#include <sys/stat.h>

#include <iomanip>
#include <map>
#include <sstream>

#include <rosbag/bag.h>
#include <rosbag/view.h>

namespace slope_monitor {
namespace ros_adapters {

BagReport CheckBag(const std::string& path, const BagCheckOptions& options) {
  return CheckBags({path}, options);
}

BagReport CheckBags(const std::vector<std::string>& paths, const BagCheckOptions& options) {
  if (!(options.gap > 0.0) || !(options.epoch_gap > 0.0)) {
    throw InvalidArgument(Message("bag check gaps must be > 0 (gap = ", options.gap,
                                  ", epoch_gap = ", options.epoch_gap, ")"));
  }
  if (paths.empty()) throw InvalidArgument("bag check: no bag file given");
  BagReport report;
  std::string path;  // the file(s), for messages
  for (const auto& p : paths) path += (path.empty() ? "" : ", ") + p;
  report.path = path;
  // Each file opened on its own first, so an error names the bad one.
  std::vector<std::unique_ptr<rosbag::Bag>> bags;
  for (const auto& p : paths) {
    struct stat st {};
    if (::stat(p.c_str(), &st) != 0) throw IoError(Message(p, ": no such file"));
    if (st.st_size == 0) throw IoError(Message(p, ": the file is empty (0 bytes), not a bag"));
    try {
      bags.push_back(std::make_unique<rosbag::Bag>());
      bags.back()->open(p, rosbag::bagmode::Read);
    } catch (const rosbag::BagException& e) {
      throw IoError(Message(p, ": not a readable bag, or truncated (", e.what(), ")"));
    }
  }
  std::map<std::string, BagTopicStats> topics;
  std::vector<BagEpochBoundary> markers;
  std::vector<BagEpochBoundary> gap_epochs;  // epochs separated by pauses of the whole bag
  uint32_t gap_epoch_count = 0;
  double previous = -1.0;
  try {
    rosbag::View view;  // all files merged in time order (split parts of one recording)
    for (const auto& bag : bags) view.addQuery(*bag);
    for (const rosbag::MessageInstance& m : view) {
      const double t = m.getTime().toSec();
      BagTopicStats& s = topics[m.getTopic()];
      if (s.count == 0) {
        s.topic = m.getTopic();
        s.datatype = m.getDataType();
        s.first = t;
      } else {
        const double g = t - s.last;
        s.max_gap = std::max(s.max_gap, g);
        if (g > options.gap) report.gaps.push_back({s.topic, s.last, t});
      }
      s.last = t;
      ++s.count;
      if (report.messages == 0) report.start = t;
      report.end = std::max(report.end, t);
      ++report.messages;
      if (m.getDataType() == "slope_monitor/EpochMarker") {
        const auto marker = m.instantiate<slope_monitor::EpochMarker>();
        if (marker)
          markers.push_back(
              {t, static_cast<bool>(marker->end), marker->epoch, marker->count, m.getTopic()});
      }
      if (previous < 0.0 || t - previous > options.epoch_gap) {
        if (previous >= 0.0) {
          gap_epochs.push_back({previous, true, gap_epochs.back().epoch, gap_epoch_count, ""});
        }
        const uint32_t k = gap_epochs.empty() ? 0 : gap_epochs.back().epoch + 1;
        gap_epochs.push_back({t, false, k, 0, ""});
        gap_epoch_count = 0;
      }
      ++gap_epoch_count;
      previous = t;
    }
    for (auto& bag : bags) bag->close();
  } catch (const rosbag::BagException& e) {
    throw IoError(Message(path, ": not a readable bag, or truncated (", e.what(), ")"));
  } catch (const ros::Exception& e) {
    throw IoError(Message(path, ": cannot read a message (", e.what(), "); truncated or corrupt?"));
  }
  if (report.messages == 0) throw IoError(Message(path, ": the bag holds no message"));
  gap_epochs.push_back({previous, true, gap_epochs.back().epoch, gap_epoch_count, ""});
  for (auto& [name, s] : topics) report.topics.push_back(s);
  report.epochs_from_markers = !markers.empty();
  report.epochs = markers.empty() ? gap_epochs : markers;
  return report;
}

std::string FormatBagReport(const BagReport& r) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(3);
  out << "bag: " << r.path << "\n";
  out << "messages: " << r.messages << "\n";
  out << "time span: " << r.start << " .. " << r.end << " (" << r.end - r.start << " s)\n";
  out << "topics: " << r.topics.size() << "\n";
  for (const auto& t : r.topics) {
    out << "  " << t.topic << "  " << t.datatype << "  " << t.count << " msgs  " << t.first
        << " .. " << t.last << "  max gap " << t.max_gap << " s\n";
  }
  out << "epochs (" << (r.epochs_from_markers ? "EpochMarker messages" : "time gaps") << "):\n";
  for (const auto& e : r.epochs) {
    out << "  " << (e.end ? "end   " : "start ") << "epoch " << e.epoch << " at " << e.time;
    if (e.end) out << "  count " << e.count;
    if (!e.topic.empty()) out << "  (" << e.topic << ")";
    out << "\n";
  }
  out << "gaps: " << r.gaps.size() << "\n";
  for (const auto& g : r.gaps)
    out << "  " << g.topic << "  " << g.from << " .. " << g.to << " (" << g.to - g.from << " s)\n";
  return out.str();
}

}  // namespace ros_adapters
}  // namespace slope_monitor
