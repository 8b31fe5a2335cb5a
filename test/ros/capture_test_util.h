// What the camera_capture tests share (test/ros and test/rostest; header
// only): the EXIF tags of a simulated UAV photo, and a recorder of what
// ros_adapters::FramePublisher publishes.
#pragma once

#include <string>
#include <vector>

#include "../core/capture/test_images.h"
#include "slope_monitor/ros/capture_conversions.h"

namespace slope_monitor {
namespace capture_test {

// EXIF of a photo taken on 2024-05-01 at `hms` (HH:MM:SS) + `subsec`, by a
// "SimCam" camera `model` with an 8.8 mm lens, at GNSS position lat, lon [deg],
// alt [m].
inline ExifTags UavPhotoTags(const std::string& model, const std::string& hms,
                             const std::string& subsec, double lat, double lon, double alt) {
  ExifTags t;
  t.date_time = "2024:05:01 " + hms;
  t.subsec = subsec;
  t.make = "SimCam";
  t.model = model;
  t.focal_num = 88;
  t.focal_den = 10;
  t.gps = true;
  t.lat_deg = lat;
  t.lon_deg = lon;
  t.alt_m = alt;
  return t;
}

// Everything a FramePublisher published, in order; `order` lists images and
// epoch markers as they came ("S0" epoch 0 starts, "I" an image, "P" picks,
// "E0" it ends).
struct Recorded {
  std::vector<sensor_msgs::ImagePtr> images;
  std::vector<sensor_msgs::CameraInfoPtr> infos;
  std::vector<sensor_msgs::NavSatFix> fixes;
  std::vector<geometry_msgs::PoseWithCovarianceStamped> priors;
  std::vector<slope_monitor::EpochMarker> epochs;
  std::vector<slope_monitor::TargetObservationArray> picks;
  std::vector<std::string> warnings;
  std::vector<std::string> order;
};

// Publisher outputs that append to *r (which must outlive the publisher).
inline ros_adapters::CaptureOutputs RecordInto(Recorded* r) {
  ros_adapters::CaptureOutputs out;
  out.image = [r](const sensor_msgs::ImagePtr& i, const sensor_msgs::CameraInfoPtr& c) {
    r->images.push_back(i);
    r->infos.push_back(c);
    r->order.push_back("I");
  };
  out.fix = [r](const sensor_msgs::NavSatFix& f) { r->fixes.push_back(f); };
  out.prior = [r](const geometry_msgs::PoseWithCovarianceStamped& p) { r->priors.push_back(p); };
  out.epoch = [r](const slope_monitor::EpochMarker& m) {
    r->epochs.push_back(m);
    r->order.push_back((m.end ? "E" : "S") + std::to_string(m.epoch));
  };
  out.picks = [r](const slope_monitor::TargetObservationArray& m) {
    r->picks.push_back(m);
    r->order.push_back("P");
  };
  out.warn = [r](const std::string& w) { r->warnings.push_back(w); };
  return out;
}

// Everything a FramePublisher with `options` publishes from `folder`, read
// to its end as camera_capture reads a folder (epochs by the default gap).
inline Recorded PublishFolder(const std::string& folder,
                              const ros_adapters::FramePublisherOptions& options) {
  Recorded r;
  ros_adapters::FramePublisher publisher(options, RecordInto(&r));
  capture::FolderSourceOptions fo;
  fo.folder = folder;
  capture::FolderSource source(fo);
  capture::EpochTracker tracker(capture::EpochOptions{});
  while (publisher.Step(&source, &tracker, true) ==
         ros_adapters::FramePublisher::StepResult::kPublished) {
  }
  return r;
}

}  // namespace capture_test
}  // namespace slope_monitor
