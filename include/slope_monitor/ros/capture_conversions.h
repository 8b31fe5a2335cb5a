// Conversions of camera_capture's core types (capture::Frame, EXIF GNSS,
// epoch events) into ROS messages.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/NavSatFix.h>
#include <std_msgs/Header.h>

#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/capture/sources.h"
#include "slope_monitor/core/capture/timing.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace ros_adapters {

// Header for a frame: stamp from the frame (UTC seconds), the given frame id.
std_msgs::Header FrameHeader(const capture::Frame& frame, const std::string& frame_id);

// The image (copied) with the frame's encoding and the header.
sensor_msgs::ImagePtr ToImageMsg(const capture::Frame& frame, const std_msgs::Header& header);

struct GnssOptions {
  // [m] 1-sigma of the EXIF GNSS position (exif.h: shared with process_flight)
  double sigma_horizontal = capture::kExifGnssSigmaHorizontal;  // east and north
  double sigma_vertical = capture::kExifGnssSigmaVertical;      // up
  double geoid_height = 0.0;  // [m] N: ellipsoidal height = EXIF altitude (above sea level) + N
};

// NavSatFix from an EXIF GNSS position (altitude converted to ellipsoidal
// height with geoid_height; covariance diagonal in ENU, COVARIANCE_TYPE_APPROXIMATED;
// status FIX, service GPS). Altitude is NaN when the EXIF has none.
sensor_msgs::NavSatFix ToNavSatFix(const capture::ExifInfo& exif, const GnssOptions& options,
                                   const std_msgs::Header& header);

// Position prior in `site` from a NavSatFix with an altitude: position from
// the local tangent plane, the fix covariance rotated into site axes,
// identity orientation with variance 1e6 rad^2 (unknown).
geometry_msgs::PoseWithCovarianceStamped ToPositionPrior(const sensor_msgs::NavSatFix& fix,
                                                         const capture::SiteFrame& site,
                                                         const std::string& site_frame);

// The orientation of *prior: a nadir photo flown at heading yaw_deg
// (capture::SiteFromOpticalNadir), sigma_deg about each axis.
void SetNadirAttitude(double yaw_deg, double sigma_deg,
                      geometry_msgs::PoseWithCovarianceStamped* prior);

slope_monitor::EpochMarker ToEpochMarker(const capture::EpochEvent& event,
                                         const std::string& source, const std::string& frame_id);

// ---------------------------------------------------------------------------
// FramePublisher: camera_capture's publishing path (used by the nodelet, and
// by tests without a ROS master through plain callbacks): epoch markers, image
// + camera_info, GNSS fix and position prior for each frame of a source.
// ---------------------------------------------------------------------------
struct CaptureOutputs {
  std::function<void(const sensor_msgs::ImagePtr&, const sensor_msgs::CameraInfoPtr&)> image;
  std::function<void(const sensor_msgs::NavSatFix&)> fix;
  std::function<void(const geometry_msgs::PoseWithCovarianceStamped&)> prior;
  std::function<void(const slope_monitor::EpochMarker&)> epoch;
  std::function<void(const slope_monitor::TargetObservationArray&)> picks;
  std::function<void(const std::string&)> warn;  // skipped files, calibration problems
};

struct FramePublisherOptions {
  std::string frame_id = "camera_optical";  // header.frame_id of images, camera_info, fix, epochs
  std::string source_name = "camera";       // EpochMarker.source
  std::string site_frame = "site";          // frame of the position prior
  GnssOptions gnss;
  bool has_site_origin = false;  // publish position priors (needs site_origin or site_crs)
  capture::Geodetic site_origin;
  // A site file's frame that is not a tangent plane at a WGS 84 origin
  // (shifted_crs: the priors in its grid, through PROJ); wins over site_origin.
  std::optional<SiteCrsOptions> site_crs;
  // [deg] 1-sigma of the attitude a photo's XMP heading gives the position
  // prior (nadir, SetNadirAttitude); photos without a heading: unknown (1e6 rad^2).
  double attitude_sigma = 10.0;
  double pixel_size = 0.0;  // [mm] sensor pixel pitch; 0: each photo's EXIF pitch, if any
  // A calibration (from camera_info_manager or the package's interior
  // parameters); without one, a nominal one from the EXIF focal length when
  // pixel_size > 0, else an uncalibrated camera_info (size only, K = 0).
  bool has_camera_info = false;
  sensor_msgs::CameraInfo camera_info;
  // Points picked in the photos (the site's gcp list, PhotoPicks), by photo
  // file name: published on `picks` just before the photo's image.
  std::map<std::string, std::vector<slope_monitor::TargetObservation>> picks;
  std::string picks_file;  // the gcp list they came from (messages)
};

// The picks of a site's gcp list (io::LoadGcpTargets: family "gcp", the
// role the site gives each point) by photo file name, each with the pick
// sigma of io::kGcpPickSigmaPx. Throws ConfigError naming the file.
std::map<std::string, std::vector<slope_monitor::TargetObservation>> PhotoPicks(
    const std::string& gcp_file, const io::TargetList& targets);

class FramePublisher {
 public:
  // Throws InvalidArgument for an invalid site origin.
  FramePublisher(const FramePublisherOptions& options, CaptureOutputs outputs);

  enum class StepResult { kPublished, kEnd };
  // Takes the next frame from the source and publishes it with its epoch
  // markers. Sources that can decode straight into the outgoing message's
  // data do (FrameSource::set_image_buffer; 8-bit JPEGs of folders), so a
  // frame is not copied on its way out (look_ahead: the source knows the next stamp, so an epoch
  // end is published right after its last frame). Skipped items are reported through outputs.warn.
  // At the end of the stream the open epoch is closed.
  StepResult Step(capture::FrameSource* source, capture::EpochTracker* tracker, bool look_ahead);
  // Publishes one frame (image + camera_info, GNSS when the EXIF has it).
  // `image` (optional): a message whose data already holds the frame's pixels
  // (frame.in_image_buffer, decoded into it by the source); else the pixels
  // are copied into a new message.
  void PublishFrame(const capture::Frame& frame, sensor_msgs::ImagePtr image = nullptr);
  void PublishEpoch(const capture::EpochEvent& event);

  // The camera_info sent with a frame (see FramePublisherOptions).
  sensor_msgs::CameraInfo CameraInfoFor(const capture::Frame& frame);

  uint64_t published() const { return published_; }
  uint64_t skipped() const { return skipped_; }
  const std::string& last_warning() const { return last_warning_; }

 private:
  void Warn(const std::string& text);
  void PublishPicks(const capture::Frame& frame, const std_msgs::Header& header);
  void WarnUnpublishedPicks();
  FramePublisherOptions options_;
  CaptureOutputs outputs_;
  std::unique_ptr<capture::SiteFrame> site_;
  bool calibration_checked_ = false;
  uint64_t published_ = 0;
  uint64_t skipped_ = 0;
  std::string last_warning_;
  std::set<std::string> picked_photos_published_;
};

// ---------------------------------------------------------------------------
// Recording check (bag_check tool): what a recorded bag holds.
// ---------------------------------------------------------------------------
struct BagCheckOptions {
  double gap = 10.0;  // [s] list per-topic gaps between consecutive messages longer than this, > 0
  double epoch_gap = 600.0;  // [s] without EpochMarker messages, a pause of the whole bag longer
                             // than this separates epochs, > 0
};

struct BagTopicStats {
  std::string topic, datatype;
  uint64_t count = 0;
  double first = 0.0, last = 0.0;  // [s] bag time of the first / last message
  double max_gap = 0.0;            // [s] longest pause between consecutive messages
};

struct BagEpochBoundary {
  double time = 0.0;  // [s] bag time
  bool end = false;   // false: an epoch starts; true: it ends
  uint32_t epoch = 0;
  uint32_t count = 0;  // EpochMarker.count (markers) or messages in the epoch (time gaps)
  std::string topic;   // the EpochMarker topic; "" for time-gap epochs
};

struct BagGap {
  std::string topic;
  double from = 0.0, to = 0.0;  // [s] bag time
};

struct BagReport {
  std::string path;  // the file (CheckBags: the files, comma-separated)
  uint64_t messages = 0;
  double start = 0.0, end = 0.0;      // [s] bag time span
  std::vector<BagTopicStats> topics;  // by topic name
  bool epochs_from_markers = false;   // epochs from EpochMarker messages (else from time gaps)
  std::vector<BagEpochBoundary> epochs;
  std::vector<BagGap> gaps;  // per-topic gaps longer than options.gap
};

// Reads a bag with rosbag and reports it. Throws IoError naming the file when
// it does not exist, is empty, is not a bag, is truncated (its index or a
// chunk cannot be read) or holds no message.
BagReport CheckBag(const std::string& path, const BagCheckOptions& options);
// One report over several bags taken as one recording (the split parts of a
// session): messages merged in time order, so epochs and gaps that span a
// split are reported once. Errors name the file.
BagReport CheckBags(const std::vector<std::string>& paths, const BagCheckOptions& options);
std::string FormatBagReport(const BagReport& report);

}  // namespace ros_adapters
}  // namespace slope_monitor
