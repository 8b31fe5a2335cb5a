// camera_capture run live (test/rostest/camera_capture_live.test): the nodelet
// loaded into a nodelet manager by this test node, through the manager's
// load_nodelet service, once the test has written what it reads:
//   * a folder of JPEGs with EXIF tags (time, GNSS) and a truncated JPEG;
//   * a video file (cv::VideoWriter, MJPG in .avi);
//   * the fixed-camera path (schedule interval, daily windows, trigger
//     service) with device_api "any" reading a video file as the camera;
// and, started by the .test through camera_capture.launch and the node shim,
// a V4L2 device that does not exist (/dev/video_missing_sm): the node stays
// up, reports the device in diagnostics and retries every retry_interval.
//
// Expected values are the EXIF tags, file contents and parameters the test
// wrote; every check is against those.
#include <time.h>

#include <cmath>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nodelet/NodeletLoad.h>
#include <nodelet/NodeletUnload.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/NavSatFix.h>
#include <std_srvs/Trigger.h>
#include <opencv2/videoio.hpp>

#include "../core/capture/test_images.h"
#include "../ros/capture_test_util.h"
#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "test_node.h"

namespace slope_monitor {
namespace {

constexpr double kMay1st10h = 1714557600.0;  // 2024-05-01 10:00:00 UTC
constexpr int kWidth = 160, kHeight = 120;

using rostest_node::WaitFor;

std::string ManagerName() {
  std::string m = "/capture_manager";
  ros::param::get("~manager", m);
  return m;
}

// Sets the nodelet's private parameters, then loads it into the manager.
void LoadCapture(const std::string& name,
                 const std::map<std::string, XmlRpc::XmlRpcValue>& params) {
  for (const auto& [key, value] : params) ros::param::set(name + "/" + key, value);
  const std::string service = ManagerName() + "/load_nodelet";
  ASSERT_TRUE(ros::service::waitForService(service, ros::Duration(30.0)))
      << service << " is not offered";
  nodelet::NodeletLoad srv;
  srv.request.name = name;
  srv.request.type = "slope_monitor/CameraCapture";
  ASSERT_TRUE(rostest_node::CallWithin(service, &srv, 30.0)) << "calling " << service;
  ASSERT_TRUE(srv.response.success) << "the manager did not load " << name;
}

void UnloadCapture(const std::string& name) {
  nodelet::NodeletUnload srv;
  srv.request.name = name;
  EXPECT_TRUE(rostest_node::CallWithin(ManagerName() + "/unload_nodelet", &srv, 30.0) &&
              srv.response.success)
      << name;
  ros::param::del(name);
}

XmlRpc::XmlRpcValue Strings(const std::vector<std::string>& v) {
  XmlRpc::XmlRpcValue list;
  list.setSize(static_cast<int>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) list[static_cast<int>(i)] = v[i];
  return list;
}

XmlRpc::XmlRpcValue Doubles(const std::vector<double>& v) {
  XmlRpc::XmlRpcValue list;
  list.setSize(static_cast<int>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) list[static_cast<int>(i)] = v[i];
  return list;
}

double MeanLevel(const sensor_msgs::Image& img) {
  double s = 0.0;
  for (uint8_t v : img.data) s += v;
  return img.data.empty() ? -1.0 : s / static_cast<double>(img.data.size());
}

// Everything one camera namespace publishes, plus the diagnostics and the
// log messages of the whole graph.
class Recorder {
 public:
  explicit Recorder(const std::string& ns) {
    ros::NodeHandle nh(ns);
    subs_.push_back(nh.subscribe<sensor_msgs::Image>("image_raw", 100,
                                                     [this](const sensor_msgs::ImageConstPtr& m) {
                                                       std::lock_guard<std::mutex> l(mutex_);
                                                       images_.push_back(m);
                                                     }));
    subs_.push_back(nh.subscribe<sensor_msgs::CameraInfo>(
        "camera_info", 100, [this](const sensor_msgs::CameraInfoConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          infos_.push_back(*m);
        }));
    subs_.push_back(nh.subscribe<sensor_msgs::NavSatFix>(
        "gnss/fix", 100, [this](const sensor_msgs::NavSatFixConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          fixes_.push_back(*m);
        }));
    subs_.push_back(nh.subscribe<slope_monitor::EpochMarker>(
        "epoch", 100, [this](const slope_monitor::EpochMarkerConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          epochs_.push_back(*m);
        }));
    ros::NodeHandle root;
    subs_.push_back(root.subscribe<diagnostic_msgs::DiagnosticArray>(
        "/diagnostics", 100, [this](const diagnostic_msgs::DiagnosticArrayConstPtr& m) {
          std::lock_guard<std::mutex> l(mutex_);
          for (const auto& s : m->status) diagnostics_.push_back({ros::WallTime::now(), s});
        }));
    subs_.push_back(root.subscribe<rosgraph_msgs::Log>("/rosout", 1000,
                                                       [this](const rosgraph_msgs::LogConstPtr& m) {
                                                         std::lock_guard<std::mutex> l(mutex_);
                                                         logs_.push_back(*m);
                                                       }));
  }

  std::vector<sensor_msgs::ImageConstPtr> images() const { return Locked(images_); }
  std::vector<sensor_msgs::CameraInfo> infos() const { return Locked(infos_); }
  std::vector<sensor_msgs::NavSatFix> fixes() const { return Locked(fixes_); }
  std::vector<slope_monitor::EpochMarker> epochs() const { return Locked(epochs_); }
  std::vector<rosgraph_msgs::Log> logs() const { return Locked(logs_); }
  struct Diag {
    ros::WallTime received;
    diagnostic_msgs::DiagnosticStatus status;
  };
  // Diagnostics whose hardware_id is `hardware_id`, in arrival order.
  std::vector<Diag> Diagnostics(const std::string& hardware_id) const {
    std::vector<Diag> out;
    for (const auto& d : Locked(diagnostics_)) {
      if (d.status.hardware_id == hardware_id) out.push_back(d);
    }
    return out;
  }
  size_t image_count() const { return images().size(); }
  bool HasEpochEnd(uint32_t epoch) const {
    for (const auto& e : epochs()) {
      if (e.end && e.epoch == epoch) return true;
    }
    return false;
  }

 private:
  template <typename T>
  T Locked(const T& v) const {
    std::lock_guard<std::mutex> l(mutex_);
    return v;
  }
  mutable std::mutex mutex_;
  std::vector<ros::Subscriber> subs_;
  std::vector<sensor_msgs::ImageConstPtr> images_;
  std::vector<sensor_msgs::CameraInfo> infos_;
  std::vector<sensor_msgs::NavSatFix> fixes_;
  std::vector<slope_monitor::EpochMarker> epochs_;
  std::vector<Diag> diagnostics_;
  std::vector<rosgraph_msgs::Log> logs_;
};

std::string Value(const diagnostic_msgs::DiagnosticStatus& s, const std::string& key) {
  for (const auto& kv : s.values) {
    if (kv.key == key) return kv.value;
  }
  return "<no key '" + key + "'>";
}

bool Contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

// A clip of `frames` flat grey frames, frame i at level step * i.
std::string WriteClip(const capture_test::TempDir& dir, const std::string& name, int frames,
                      int step, double fps) {
  const std::string path = dir.File(name);
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps,
                         cv::Size(kWidth, kHeight), true);
  if (!writer.isOpened()) throw std::runtime_error("cv::VideoWriter cannot write MJPG to " + path);
  for (int i = 0; i < frames; ++i) {
    writer.write(cv::Mat(kHeight, kWidth, CV_8UC3, cv::Scalar::all(step * i)));
  }
  writer.release();
  return path;
}

// ---------------------------------------------------------------------------
// (a) A UAV photo folder: EXIF times (camera clock on local time, corrected
// with clock_offset), GNSS, calibration from a camera_info_manager URL, two
// epochs, and a truncated JPEG in the middle that is skipped and counted.
struct Photo {
  std::string name, hms, subsec;
  double offset_s;  // time after 10:00:00 of the EXIF time
  double lat, lon, alt;
};

TEST(CameraCaptureLive, PhotoFolder) {
  capture_test::TempDir dir("live_folder");
  const std::vector<Photo> photos = {
      {"img_a.jpg", "10:00:00", "0", 0.0, 35.1, 139.2, 1200.5},
      {"img_b.jpg", "10:00:01", "5", 1.5, 35.1004, 139.2003, 1210.25},
      {"img_c.jpg", "10:00:03", "25", 3.25, 35.1008, 139.2006, 1220.0},
      {"img_d.jpg", "10:30:00", "", 1800.0, 35.0995, 139.1990, 1199.0},
  };
  auto tags = [](const std::string& hms, const std::string& subsec, double lat, double lon,
                 double alt) {
    return capture_test::UavPhotoTags("UAV-1", hms, subsec, lat, lon, alt);
  };
  for (size_t i = 0; i < photos.size(); ++i) {
    const Photo& p = photos[i];
    capture_test::WriteJpeg(dir.File(p.name),
                            capture_test::TexturedImage(kWidth, kHeight, 3, static_cast<int>(i)),
                            tags(p.hms, p.subsec, p.lat, p.lon, p.alt));
  }
  // Taken between img_b and img_c; cut in half (EXIF intact, image data not).
  capture_test::WriteJpeg(dir.File("whole.jpeg"),
                          capture_test::TexturedImage(kWidth, kHeight, 3, 9),
                          tags("10:00:02", "", 35.1, 139.2, 1200.0));
  capture_test::WriteTruncatedCopy(dir.File("whole.jpeg"), dir.File("img_cut.jpg"), 0.5);
  std::filesystem::remove(dir.File("whole.jpeg"));
  // Calibration (camera_info_manager YAML): plumb_bob with distortion.
  const std::vector<double> K = {152.5, 0.0, 80.25, 0.0, 152.5, 59.75, 0.0, 0.0, 1.0};
  const std::vector<double> D = {-0.12, 0.03, 0.0004, -0.0002, 0.001};
  capture_test::WriteText(
      dir.File("uav.yaml"),
      "image_width: 160\nimage_height: 120\ncamera_name: uav\n"
      "camera_matrix: {rows: 3, cols: 3, data: [152.5, 0.0, 80.25, 0.0, 152.5, 59.75, 0.0, 0.0, "
      "1.0]}\n"
      "distortion_model: plumb_bob\n"
      "distortion_coefficients: {rows: 1, cols: 5, data: [-0.12, 0.03, 0.0004, -0.0002, 0.001]}\n"
      "rectification_matrix: {rows: 3, cols: 3, data: [1, 0, 0, 0, 1, 0, 0, 0, 1]}\n"
      "projection_matrix: {rows: 3, cols: 4, data: [152.5, 0.0, 80.25, 0.0, 0.0, 152.5, 59.75, "
      "0.0, "
      "0.0, 0.0, 1.0, 0.0]}\n");
  const double clock_offset = -32400.0;  // the camera ran on UTC+9 without OffsetTimeOriginal
  const double geoid = 30.5;
  Recorder rec("/uav/camera");
  ros::WallDuration(0.5).sleep();  // subscriptions registered before the nodelet advertises
  LoadCapture("/uav/camera/camera_capture",
              {{"source", "folder"},
               {"folder", dir.path()},
               {"camera_name", "uav"},
               {"frame_id", "uav_optical"},
               {"camera_info_url", "file://" + dir.File("uav.yaml")},
               {"pixel_size", 0.004},
               {"rate", 20.0},
               {"start_delay", 1.5},
               {"clock_offset", clock_offset},
               {"epoch_gap", 600.0},
               {"first_epoch", 7},
               {"geoid_height", geoid},
               {"site_origin", Doubles({35.1, 139.2, 1200.5 + geoid})}});
  ASSERT_TRUE(WaitFor([&] { return rec.HasEpochEnd(8); }, 30.0))
      << "no end marker of the second epoch";
  const std::string hw = "folder " + dir.path();
  // Diagnostics are sent every second: wait for one that counts every image.
  EXPECT_TRUE(WaitFor(
      [&] {
        const auto d = rec.Diagnostics(hw);
        return !d.empty() && Value(d.back().status, "published") == "4";
      },
      5.0));
  ros::WallDuration(0.3).sleep();

  const auto images = rec.images();
  const auto infos = rec.infos();
  const auto fixes = rec.fixes();
  ASSERT_EQ(images.size(), photos.size());
  ASSERT_EQ(infos.size(), photos.size());
  ASSERT_EQ(fixes.size(), photos.size());
  for (size_t i = 0; i < photos.size(); ++i) {
    const Photo& p = photos[i];
    const double stamp = kMay1st10h + p.offset_s + clock_offset;
    const sensor_msgs::Image& img = *images[i];
    EXPECT_NEAR(img.header.stamp.toSec(), stamp, 1e-6) << p.name;
    EXPECT_EQ(img.header.frame_id, "uav_optical");
    EXPECT_EQ(img.encoding, "bgr8");
    EXPECT_EQ(img.width, static_cast<uint32_t>(kWidth));
    EXPECT_EQ(img.height, static_cast<uint32_t>(kHeight));
    EXPECT_EQ(img.step, static_cast<uint32_t>(3 * kWidth));
    ASSERT_EQ(img.data.size(), static_cast<size_t>(3 * kWidth * kHeight));
    // The pixels are this photo's (JPEG q95 of its texture).
    const cv::Mat got(kHeight, kWidth, CV_8UC3, const_cast<uint8_t*>(img.data.data()));
    EXPECT_LT(capture_test::MeanAbsDiff(
                  got, capture_test::TexturedImage(kWidth, kHeight, 3, static_cast<int>(i))),
              12.0)
        << p.name;

    const sensor_msgs::CameraInfo& info = infos[i];
    EXPECT_EQ(info.header.stamp, img.header.stamp);
    EXPECT_EQ(info.header.frame_id, "uav_optical");
    EXPECT_EQ(info.width, static_cast<uint32_t>(kWidth));
    EXPECT_EQ(info.height, static_cast<uint32_t>(kHeight));
    EXPECT_EQ(info.distortion_model, "plumb_bob");
    for (int k = 0; k < 9; ++k) EXPECT_DOUBLE_EQ(info.K[k], K[k]) << "K[" << k << "]";
    ASSERT_EQ(info.D.size(), D.size());
    for (size_t k = 0; k < D.size(); ++k) EXPECT_DOUBLE_EQ(info.D[k], D[k]) << "D[" << k << "]";

    const sensor_msgs::NavSatFix& fix = fixes[i];
    EXPECT_EQ(fix.header.stamp, img.header.stamp);
    EXPECT_NEAR(fix.latitude, p.lat, 1e-7) << p.name;  // EXIF seconds are stored to 1e-4"
    EXPECT_NEAR(fix.longitude, p.lon, 1e-7) << p.name;
    EXPECT_NEAR(fix.altitude, p.alt + geoid, 1e-3) << p.name;
    EXPECT_EQ(fix.status.status, sensor_msgs::NavSatStatus::STATUS_FIX);
  }
  // Epochs: 7 = the three photos of 10:00 (the truncated one is not counted),
  // 8 = the photo of 10:30.
  const auto epochs = rec.epochs();
  ASSERT_EQ(epochs.size(), 4u);
  const double t0 = kMay1st10h + clock_offset;
  const std::vector<std::tuple<bool, uint32_t, uint32_t, double>> expected = {
      {false, 7, 0, t0},
      {true, 7, 3, t0 + 3.25},
      {false, 8, 0, t0 + 1800.0},
      {true, 8, 1, t0 + 1800.0}};
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(epochs[i].end, std::get<0>(expected[i])) << i;
    EXPECT_EQ(epochs[i].epoch, std::get<1>(expected[i])) << i;
    if (epochs[i].end) {
      EXPECT_EQ(epochs[i].count, std::get<2>(expected[i])) << i;
    }
    EXPECT_NEAR(epochs[i].header.stamp.toSec(), std::get<3>(expected[i]), 1e-6) << i;
    EXPECT_EQ(epochs[i].source, "uav");  // the camera of ns /uav/camera (ros/uav_topics.h)
  }
  // The truncated photo: skipped, counted and named, and the stream went on.
  const auto diags = rec.Diagnostics(hw);
  ASSERT_FALSE(diags.empty()) << "no diagnostics with hardware_id '" << hw << "'";
  const auto& d = diags.back().status;
  EXPECT_EQ(d.level, diagnostic_msgs::DiagnosticStatus::WARN) << d.message;
  EXPECT_EQ(Value(d, "skipped"), "1");
  EXPECT_EQ(Value(d, "published"), "4");
  EXPECT_TRUE(Contains(Value(d, "last warning"), "img_cut.jpg")) << Value(d, "last warning");
  EXPECT_TRUE(Contains(Value(d, "last warning"), "truncated")) << Value(d, "last warning");
  int skip_logs = 0, calibration_logs = 0;
  const auto logs = rec.logs();
  for (const auto& l : logs) {
    if (Contains(l.msg, "img_cut.jpg")) ++skip_logs;
    if (Contains(l.msg, "calibration inconsistent")) ++calibration_logs;
  }
  EXPECT_EQ(skip_logs, 1) << "one warning naming the truncated file in /rosout (of " << logs.size()
                          << " messages)";
  EXPECT_EQ(calibration_logs, 0)
      << "the plumb_bob calibration is representable by the collinearity model";
  UnloadCapture("/uav/camera/camera_capture");
}

// ---------------------------------------------------------------------------
// (b) A video file: frame i stamped video_start_time + i / fps, in order.
TEST(CameraCaptureLive, VideoFile) {
  capture_test::TempDir dir("live_video");
  constexpr int kFrames = 12;
  constexpr double kFps = 10.0;
  const std::string clip = WriteClip(dir, "clip.avi", kFrames, 20, kFps);
  const double start = kMay1st10h + 0.25;
  Recorder rec("/video/camera");
  ros::WallDuration(0.5).sleep();
  LoadCapture("/video/camera/camera_capture", {{"source", "video"},
                                               {"video_file", clip},
                                               {"video_start_time", start},
                                               {"camera_name", "video"},
                                               {"rate", 30.0},
                                               {"start_delay", 1.5}});
  ASSERT_TRUE(WaitFor([&] { return rec.HasEpochEnd(0); }, 30.0)) << "no end marker";
  ros::WallDuration(0.3).sleep();
  const auto images = rec.images();
  const auto infos = rec.infos();
  ASSERT_EQ(images.size(), static_cast<size_t>(kFrames));
  ASSERT_EQ(infos.size(), static_cast<size_t>(kFrames));
  for (int i = 0; i < kFrames; ++i) {
    const sensor_msgs::Image& img = *images[i];
    EXPECT_NEAR(img.header.stamp.toSec(), start + i / kFps, 1e-6) << i;
    EXPECT_EQ(img.header.frame_id, "video_optical");
    EXPECT_EQ(img.encoding, "bgr8");
    EXPECT_EQ(img.width, static_cast<uint32_t>(kWidth));
    EXPECT_EQ(img.height, static_cast<uint32_t>(kHeight));
    EXPECT_NEAR(MeanLevel(img), 20.0 * i, 3.0) << "frame " << i;
    // No calibration given and no EXIF: uncalibrated camera_info (size, K = 0).
    EXPECT_EQ(infos[i].header.stamp, img.header.stamp);
    EXPECT_EQ(infos[i].width, static_cast<uint32_t>(kWidth));
    EXPECT_EQ(infos[i].height, static_cast<uint32_t>(kHeight));
    EXPECT_EQ(infos[i].K[0], 0.0);
  }
  EXPECT_TRUE(rec.fixes().empty());
  const auto epochs = rec.epochs();
  ASSERT_EQ(epochs.size(), 2u);
  EXPECT_FALSE(epochs[0].end);
  EXPECT_NEAR(epochs[0].header.stamp.toSec(), start, 1e-6);
  EXPECT_TRUE(epochs[1].end);
  EXPECT_EQ(epochs[1].count, static_cast<uint32_t>(kFrames));
  EXPECT_NEAR(epochs[1].header.stamp.toSec(), start + (kFrames - 1) / kFps, 1e-6);
  UnloadCapture("/video/camera/camera_capture");
}

// ---------------------------------------------------------------------------
// The fixed-camera path without a device: device_api "any" reads a video file
// as the camera. One camera inside its daily window captures every interval
// (aligned to multiples of it, one epoch each); one outside its window
// captures nothing until the trigger service asks for an epoch.
std::string Window(int begin_minute, int end_minute) {
  auto hm = [](int m) {
    m = ((m % 1440) + 1440) % 1440;
    char buf[8];
    std::snprintf(buf, sizeof(buf), "%02d:%02d", m / 60, m % 60);
    return std::string(buf);
  };
  return hm(begin_minute) + "-" + hm(end_minute);
}

TEST(CameraCaptureLive, FixedCameraScheduleWindowsAndTrigger) {
  capture_test::TempDir dir("live_schedule");
  const std::string clip = WriteClip(dir, "mast.avi", 30, 8, 10.0);
  const time_t now = time(nullptr);
  struct tm utc {};
  gmtime_r(&now, &utc);
  const int minute = utc.tm_hour * 60 + utc.tm_min;
  const double interval = 1.0;
  Recorder open_rec("/open/camera"), closed_rec("/closed/camera");
  ros::WallDuration(0.5).sleep();
  auto params = [&](const std::string& window, int frames) {
    return std::map<std::string, XmlRpc::XmlRpcValue>{{"source", "device"},
                                                      {"device_api", "any"},
                                                      {"device", clip},
                                                      {"start_delay", 0.5},
                                                      {"retry_interval", 0.5},
                                                      {"schedule/interval", interval},
                                                      {"schedule/windows", Strings({window})},
                                                      {"schedule/utc_offset", 0.0},
                                                      {"schedule/frames_per_epoch", frames}};
  };
  const double loaded = ros::WallTime::now().toSec();
  LoadCapture("/open/camera/camera_capture", params(Window(minute - 60, minute + 60), 1));
  LoadCapture("/closed/camera/camera_capture", params(Window(minute + 120, minute + 180), 2));
  ASSERT_TRUE(WaitFor([&] { return open_rec.image_count() >= 4; }, 20.0))
      << "the camera inside its window captured " << open_rec.image_count() << " images";
  const double waited = ros::WallTime::now().toSec() - loaded;
  EXPECT_EQ(closed_rec.image_count(), 0u) << "captures outside the daily window";

  // Inside the window: one frame per interval, stamped just after a multiple
  // of the interval, frames of the clip in order, one epoch per capture.
  const auto images = open_rec.images();
  ASSERT_GE(images.size(), 4u);
  for (size_t i = 0; i < images.size(); ++i) {
    const double t = images[i]->header.stamp.toSec();
    const double late = t - std::floor(t / interval) * interval;
    EXPECT_LT(late, 0.5) << "capture " << i << " at " << std::fixed << t
                         << " is not on the schedule";
    if (i > 0) {
      EXPECT_GE(t - images[i - 1]->header.stamp.toSec(), 0.5 * interval) << i;
    }
    if (i < 10) {
      EXPECT_NEAR(MeanLevel(*images[i]), 8.0 * i, 3.0)
          << "capture " << i << " is frame " << i << " of the clip";
    }
  }
  EXPECT_LE(images.size(), static_cast<size_t>(waited / interval) + 2)
      << "more captures than the interval allows";
  ASSERT_TRUE(WaitFor([&] { return open_rec.epochs().size() >= 2 * images.size(); }, 3.0));
  const auto open_epochs = open_rec.epochs();
  for (size_t i = 0; i + 1 < 2 * images.size(); i += 2) {
    EXPECT_FALSE(open_epochs[i].end);
    EXPECT_TRUE(open_epochs[i + 1].end);
    EXPECT_EQ(open_epochs[i].epoch, open_epochs[i + 1].epoch);
    EXPECT_EQ(open_epochs[i + 1].count, 1u);
    if (i > 0) {
      EXPECT_EQ(open_epochs[i].epoch, open_epochs[i - 2].epoch + 1);
    }
  }

  // Outside the window the trigger still captures one epoch of frames_per_epoch frames.
  std_srvs::Trigger trigger;
  const double asked = ros::WallTime::now().toSec();
  ASSERT_TRUE(rostest_node::CallWithin("/closed/camera/trigger", &trigger, 10.0));
  EXPECT_TRUE(trigger.response.success) << trigger.response.message;
  ASSERT_TRUE(WaitFor([&] { return closed_rec.HasEpochEnd(0); }, 10.0))
      << "no epoch after the trigger";
  ros::WallDuration(0.3).sleep();
  const auto triggered = closed_rec.images();
  ASSERT_EQ(triggered.size(), 2u);
  for (const auto& img : triggered) {
    EXPECT_GE(img->header.stamp.toSec(), asked - 0.1);
    EXPECT_LT(img->header.stamp.toSec(), asked + 5.0);
  }
  const auto closed_epochs = closed_rec.epochs();
  ASSERT_EQ(closed_epochs.size(), 2u);
  EXPECT_FALSE(closed_epochs[0].end);
  EXPECT_TRUE(closed_epochs[1].end);
  EXPECT_EQ(closed_epochs[1].count, 2u);
  UnloadCapture("/open/camera/camera_capture");
  UnloadCapture("/closed/camera/camera_capture");
}

// ---------------------------------------------------------------------------
// (c) A V4L2 device that does not exist (started by the .test through
// camera_capture.launch and the node shim, retry_interval from its overlay).
TEST(CameraCaptureLive, MissingDeviceNodeStaysUpAndRetries) {
  std::string node = "/missing_cam/camera/camera_capture", device = "/dev/video_missing_sm";
  double retry = 0.5;
  ros::param::get("~missing_node", node);
  ros::param::get("~missing_device", device);
  ros::param::get("~retry_interval", retry);
  Recorder rec("/missing_cam/camera");
  const std::string hw = "V4L2 " + device;
  // Two diagnostics at least 2 s apart.
  ASSERT_TRUE(WaitFor([&] { return !rec.Diagnostics(hw).empty(); }, 10.0))
      << "no diagnostics for " << hw;
  const Recorder::Diag first = rec.Diagnostics(hw).front();
  ASSERT_TRUE(WaitFor(
      [&] { return (rec.Diagnostics(hw).back().received - first.received).toSec() >= 2.0; }, 10.0));
  const Recorder::Diag last = rec.Diagnostics(hw).back();
  for (const auto* d : {&first, &last}) {
    EXPECT_EQ(d->status.level, diagnostic_msgs::DiagnosticStatus::ERROR) << d->status.message;
    EXPECT_TRUE(Contains(d->status.message, device)) << d->status.message;
    EXPECT_TRUE(Contains(d->status.message, "does not exist")) << d->status.message;
  }
  const double dt = (last.received - first.received).toSec();
  const int failures0 = std::stoi(Value(first.status, "device open failures"));
  const int failures1 = std::stoi(Value(last.status, "device open failures"));
  EXPECT_GE(failures1 - failures0, 2) << "retries in " << dt << " s";
  // Retries are spaced by retry_interval: no more than dt / retry (+1 for the
  // phase, +1 for the 1 Hz diagnostics' timing).
  EXPECT_LE(failures1 - failures0, static_cast<int>(dt / retry) + 2) << "retries in " << dt << " s";

  // Still up: registered with the master and answering its trigger service.
  std::vector<std::string> nodes;
  ASSERT_TRUE(ros::master::getNodes(nodes));
  EXPECT_NE(std::find(nodes.begin(), nodes.end(), node), nodes.end())
      << node << " is not registered";
  std_srvs::Trigger trigger;
  ASSERT_TRUE(rostest_node::CallWithin("/missing_cam/camera/trigger", &trigger, 10.0))
      << "the node does not answer";
  EXPECT_FALSE(trigger.response.success);
  EXPECT_TRUE(Contains(trigger.response.message, device)) << trigger.response.message;
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "camera_capture_live_test");
}
