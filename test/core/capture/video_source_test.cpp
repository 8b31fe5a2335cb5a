// A video file made by the test (cv::VideoWriter, MJPG in .avi — the Debian
// OpenCV build writes it with its built-in MJPEG encoder and reads it back
// through FFmpeg): frame count, stamps start + i / fps, frame step, content.
#include <chrono>

#include <gtest/gtest.h>

#include <opencv2/videoio.hpp>

#include "slope_monitor/core/capture/sources.h"
#include "slope_monitor/core/capture/timing.h"
#include "slope_monitor/core/common/error.h"
#include "test_images.h"

namespace slope_monitor {
namespace capture {
namespace {

constexpr int kFrames = 12;
constexpr double kFps = 5.0;

// Frame i is a flat grey of level 20 * i (so each frame is identifiable after compression).
std::string MakeVideo(const capture_test::TempDir& dir) {
  const std::string path = dir.File("clip.avi");
  cv::VideoWriter writer(path, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), kFps, cv::Size(64, 48),
                         true);
  if (!writer.isOpened()) throw std::runtime_error("VideoWriter cannot write MJPG .avi");
  for (int i = 0; i < kFrames; ++i)
    writer.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(20 * i, 20 * i, 20 * i)));
  writer.release();
  return path;
}

TEST(VideoSource, StampsFromStartTimeAndFrameIndex) {
  capture_test::TempDir dir("video");
  VideoSourceOptions o;
  o.path = MakeVideo(dir);
  o.start_time = 1714557600.0;
  VideoSource source(o);
  EXPECT_DOUBLE_EQ(source.fps(), kFps);
  Frame f;
  int n = 0;
  std::optional<double> peek = source.PeekNextStamp();
  while (source.Next(&f)) {
    ASSERT_TRUE(peek.has_value());
    EXPECT_DOUBLE_EQ(*peek, f.stamp);
    EXPECT_EQ(f.index, static_cast<uint64_t>(n));
    EXPECT_DOUBLE_EQ(f.stamp, 1714557600.0 + n / kFps);
    EXPECT_EQ(f.stamp_source, StampSource::kVideo);
    EXPECT_EQ(f.encoding, "bgr8");
    EXPECT_EQ(f.image.cols, 64);
    EXPECT_EQ(f.image.rows, 48);
    EXPECT_NEAR(cv::mean(f.image)[0], 20.0 * n, 3.0) << "frame " << n;
    EXPECT_NE(f.name.find("clip.avi#" + std::to_string(n)), std::string::npos);
    peek = source.PeekNextStamp();
    ++n;
  }
  EXPECT_EQ(n, kFrames);
  EXPECT_FALSE(peek.has_value());
  EXPECT_EQ(source.skipped_count(), 0u);
}

TEST(VideoSource, FrameStepFpsOverrideMonoAndEpochSplit) {
  capture_test::TempDir dir("video2");
  VideoSourceOptions o;
  o.path = MakeVideo(dir);
  o.start_time = 100.0;
  o.fps = 10.0;  // override: the clip was really taken at 10 Hz
  o.frame_step = 4;
  o.encoding = "mono8";
  VideoSource source(o);
  EpochOptions eo;
  eo.gap = 5.0;
  eo.max_duration = 0.5;  // split the continuous clip into 0.5 s epochs
  EpochTracker tracker(eo);
  std::vector<uint64_t> indices;
  std::vector<std::string> log;
  Frame f;
  while (source.Next(&f)) {
    for (const auto& e : tracker.BeforeFrame(f.stamp))
      log.push_back((e.end ? "E" : "S") + std::to_string(e.epoch));
    indices.push_back(f.index);
    EXPECT_DOUBLE_EQ(f.stamp, 100.0 + f.index / 10.0);
    EXPECT_EQ(f.encoding, "mono8");
    EXPECT_NEAR(cv::mean(f.image)[0], 20.0 * f.index, 3.0);
    for (const auto& e : tracker.AfterFrame(source.PeekNextStamp(), true))
      log.push_back("E" + std::to_string(e.epoch));
  }
  EXPECT_EQ(indices, (std::vector<uint64_t>{0, 4, 8}));
  // 0.0 and 0.4 s in epoch 0; 0.8 s is 0.8 s after the epoch's first frame: epoch 1.
  EXPECT_EQ(log, (std::vector<std::string>{"S0", "E0", "S1", "E1"}));
}

TEST(VideoSource, MissingOrBadFileNamesIt) {
  capture_test::TempDir dir("video3");
  VideoSourceOptions o;
  o.path = dir.File("missing.avi");
  try {
    VideoSource s(o);
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.avi"), std::string::npos);
  }
  o.path = dir.File("junk.avi");
  capture_test::WriteText(o.path, "not a video");
  try {
    VideoSource s(o);
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("junk.avi"), std::string::npos) << e.what();
  }
  o.frame_step = 0;
  EXPECT_THROW(o.Check(), ConfigError);
}

TEST(DeviceSource, MissingDeviceNamesIt) {
  DeviceSourceOptions o;
  o.device = "/dev/video_sm_capture_test_absent";
  DeviceSource source(o);
  try {
    source.Open();
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/video_sm_capture_test_absent"), std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(source.IsOpen());
  Frame f;
  EXPECT_THROW(source.Next(&f), IoError);
  // A path that exists but is not a video device.
  o.device = "/dev/null";
  DeviceSource null_source(o);
  try {
    null_source.Open();
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/null"), std::string::npos) << e.what();
  }
  o.width = -1;
  EXPECT_THROW(DeviceSource bad(o), ConfigError);
}

// device_api "any": a video file opened as a live camera (the stand-in for a
// network camera in tests): wall-clock stamps, frames in order, and at its
// end the source closes with a message naming it, like an unplugged device.
TEST(DeviceSource, AnyApiReadsAVideoFileAsACamera) {
  capture_test::TempDir dir("device_any");
  DeviceSourceOptions o;
  o.api = "any";
  o.device = MakeVideo(dir);
  DeviceSource source(o);
  EXPECT_NE(source.Describe().find("camera '" + o.device + "'"), std::string::npos)
      << source.Describe();
  source.Open();
  ASSERT_TRUE(source.IsOpen());
  const double before =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  Frame f;
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(source.Next(&f)) << i;
    EXPECT_EQ(f.stamp_source, StampSource::kClock);
    EXPECT_GE(f.stamp, before);
    EXPECT_EQ(f.encoding, "bgr8");
    EXPECT_NEAR(cv::mean(f.image)[0], 20.0 * i, 3.0) << "frame " << i;
  }
  try {
    source.Next(&f);
    FAIL() << "no exception at the end of the file";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(o.device), std::string::npos) << e.what();
  }
  EXPECT_FALSE(source.IsOpen());
  source.Open();  // reopens from the start
  ASSERT_TRUE(source.Next(&f));
  EXPECT_NEAR(cv::mean(f.image)[0], 0.0, 3.0);

  o.api = "v4l3";
  EXPECT_THROW(DeviceSource bad(o), ConfigError);
  o.api = "any";
  o.device = dir.File("absent.avi");
  DeviceSource absent(o);
  try {
    absent.Open();
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.avi"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
