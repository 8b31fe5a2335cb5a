// Image sources for camera_capture: a folder of photos (UAV survey sets or a
// fixed camera's uploads), a video file, and a live V4L2 device (through
// OpenCV's cv::VideoCapture). All give Frames with a UTC stamp in seconds.
//
// Bad items never stop a stream: an unreadable or truncated image is skipped,
// counted (skipped_count()) and reported with a message naming the file
// (TakeSkipped()); Next() moves on to the next item.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/capture/photo_attitude.h"

namespace slope_monitor {
namespace capture {

// Where a frame's stamp came from.
enum class StampSource { kExif, kFile, kVideo, kClock };
const char* StampSourceName(StampSource s);

struct Frame {
  cv::Mat image;         // 8-bit: CV_8UC1 (mono8) or CV_8UC3 (bgr8); 16-bit likewise (mono16/bgr16)
  std::string encoding;  // sensor_msgs encoding name of `image`
  double stamp = 0.0;    // [s] since the Unix epoch, UTC
  StampSource stamp_source = StampSource::kClock;
  std::string name;              // file path, "video.avi#17" or device path
  uint64_t index = 0;            // position in the source (0-based, counts skipped items)
  ExifInfo exif;                 // folder sources only (empty otherwise)
  PhotoAttitude attitude;        // folder sources only: the XMP attitude (photo_attitude.h)
  bool in_image_buffer = false;  // `image` lies in memory from the source's ImageBuffer (see below)
};

// Caller-owned pixel storage: returns a continuous Mat header of rows x cols
// of `type` over memory the caller owns (e.g. a ROS message's data vector),
// so a source can decode straight into it instead of decoding into its own
// Mat that the caller then copies. Sources that cannot use it ignore it.
using ImageBuffer = std::function<cv::Mat(int rows, int cols, int type)>;

struct SkippedItem {
  std::string name;    // the file (or frame) that was skipped
  std::string reason;  // why, e.g. "truncated JPEG: no EOI marker ..."
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // The next frame; false at the end of the stream (or when a live device has
  // no frame now). Bad items are skipped (see above).
  virtual bool Next(Frame* frame) = 0;
  // The stamp of the next item when known in advance (folders, video files);
  // nullopt at the end or for live sources.
  virtual std::optional<double> PeekNextStamp() const { return std::nullopt; }
  virtual std::string Describe() const = 0;

  uint64_t skipped_count() const { return skipped_count_; }
  // Items skipped since the last call (for logging).
  std::vector<SkippedItem> TakeSkipped();

  // Where the next Next() may put the pixels (an empty function: the source
  // allocates). When used, the returned Frame has in_image_buffer = true.
  void set_image_buffer(ImageBuffer buffer) { image_buffer_ = std::move(buffer); }

 protected:
  void Skip(const std::string& name, const std::string& reason);
  ImageBuffer image_buffer_;

 private:
  uint64_t skipped_count_ = 0;
  std::vector<SkippedItem> skipped_;
};

// Output encoding: "auto" keeps what the file holds (mono or colour, 8 or 16
// bit), "mono8" / "bgr8" convert.
// Throws ConfigError naming the value for anything else.
void CheckEncodingOption(const std::string& encoding);
// Converts a decoded image to the requested encoding; returns its name.
std::string ConvertEncoding(const std::string& requested, cv::Mat* image);

// The frame header (SOFn segment) of a JPEG.
struct JpegFrameInfo {
  int width = 0, height = 0;  // [px]; 0 when no SOFn segment was seen
  int components = 0;         // 1 grey, 3 YCbCr/RGB, 4 CMYK/YCCK
  int precision = 0;          // bits per sample (8 or 12)
};

// Checks that a JPEG byte stream is complete: starts with SOI, its marker
// segments are intact, and the entropy-coded data ends with an EOI marker.
// Returns "" when complete, otherwise why not (e.g. "truncated: ...").
// `info` (optional) receives the frame header.
std::string CheckJpegStructure(const std::vector<unsigned char>& bytes,
                               JpegFrameInfo* info = nullptr);

// Reads and decodes one image file (JPEG structure checked first). Throws
// IoError naming the file when it cannot be read, is truncated or does not decode.
// With `buffer`, an 8-bit grey or colour JPEG whose stored layout is the
// requested encoding is decoded straight into the buffer's memory (no copy);
// *in_buffer tells whether that happened.
cv::Mat DecodeImageFile(const std::string& path, const std::string& encoding,
                        std::string* encoding_out, const ImageBuffer& buffer = {},
                        bool* in_buffer = nullptr);

// ---------------------------------------------------------------------------
struct FolderSourceOptions {
  std::string folder;  // directory of images
  std::vector<std::string> extensions = {".jpg", ".jpeg", ".png", ".tif",
                                         ".tiff"};  // case-insensitive
  std::string time_source =
      "exif";  // "exif": EXIF capture time, file time as fallback; "file": file time only
  double clock_offset = 0.0;  // [s] added to EXIF times (camera clock error / time zone), any value
  std::string encoding = "auto";  // see CheckEncodingOption
  void Check() const;             // throws ConfigError naming the key
};

// Photos in a folder, sorted by capture time (EXIF DateTimeOriginal +
// SubSecTimeOriginal (+ OffsetTimeOriginal) + clock_offset; the file's
// modification time when the EXIF time is missing or unreadable), then by name.
class FolderSource : public FrameSource {
 public:
  // Scans the folder and reads every file's EXIF. Throws IoError naming the
  // folder when it does not exist or holds no image with a listed extension.
  explicit FolderSource(const FolderSourceOptions& options);

  bool Next(Frame* frame) override;
  std::optional<double> PeekNextStamp() const override;
  std::string Describe() const override;

  size_t size() const { return entries_.size(); }
  // The files in publishing order (for tools and tests).
  std::vector<std::string> Files() const;
  // Files whose EXIF could not be read at the scan (they fall back to file time).
  const std::vector<SkippedItem>& exif_warnings() const { return exif_warnings_; }
  // Files left out at the scan, each with the reason: a photo whose size
  // (image header) is not the folder's most common one, and, in a folder
  // where most photos carry an EXIF GNSS position, a photo without one (a
  // flight's photos belong to one camera and are placed by their GNSS).
  const std::vector<SkippedItem>& left_out() const { return left_out_; }

 private:
  struct Entry {
    std::string path;
    double stamp = 0.0;
    StampSource stamp_source = StampSource::kFile;
    ExifInfo exif;
    PhotoAttitude attitude;
  };
  // Moves the entries of another camera or size than the folder's most
  // common (PhotoCamera) or (in a GNSS-tagged folder) without a position to
  // left_out_.
  void LeaveOutOddPhotos();
  FolderSourceOptions options_;
  std::vector<Entry> entries_;
  std::vector<SkippedItem> exif_warnings_, left_out_;
  size_t next_ = 0;
};

// ---------------------------------------------------------------------------
struct VideoSourceOptions {
  std::string path;  // video file (any container/codec the OpenCV build reads, e.g. MJPG in .avi)
  double start_time = -1.0;  // [s] UTC stamp of frame 0; < 0: the file's modification time
  double fps = 0.0;          // [Hz] override of the container's frame rate; 0: use the container's
  int frame_step = 1;        // publish every n-th frame, >= 1
  std::string encoding = "auto";
  void Check() const;
};

// A video file; frame i is stamped start_time + i / fps.
class VideoSource : public FrameSource {
 public:
  // Throws IoError naming the file when it cannot be opened or has no frame rate.
  explicit VideoSource(const VideoSourceOptions& options);

  bool Next(Frame* frame) override;
  std::optional<double> PeekNextStamp() const override;
  std::string Describe() const override;
  double fps() const { return fps_; }
  double start_time() const { return start_time_; }

 private:
  VideoSourceOptions options_;
  cv::VideoCapture capture_;
  double fps_ = 0.0;
  double start_time_ = 0.0;
  int64_t frame_count_ = -1;  // from the container (may be approximate), -1 unknown
  int64_t next_index_ = 0;
  bool ended_ = false;
};

// ---------------------------------------------------------------------------
struct DeviceSourceOptions {
  std::string device =
      "/dev/video0";  // V4L2 device path (api "v4l2"), else what cv::VideoCapture opens
  // "v4l2": a V4L2 device through OpenCV's V4L2 backend; "any": anything
  // cv::VideoCapture opens with its default backends (a network camera's
  // RTSP/HTTP URL, a GStreamer pipeline, a video file replayed as a live
  // camera: at its end it is reopened like a disconnected device).
  std::string api = "v4l2";
  int width = 0;           // [px] requested; 0: device default
  int height = 0;          // [px] requested; 0: device default
  double fps = 0.0;        // [Hz] requested; 0: device default
  double exposure = -1.0;  // device units (V4L2 exposure_absolute, 100 us); < 0: auto exposure
  std::string encoding = "auto";
  void Check() const;
};

// A live camera. Stamps are the system clock (UTC) when the frame is grabbed.
// Messages name the device ("V4L2 device '/dev/video0'" or "camera 'rtsp://...'").
class DeviceSource : public FrameSource {
 public:
  explicit DeviceSource(const DeviceSourceOptions& options);
  // Opens the device and applies the settings. Throws IoError naming the
  // device when it does not exist or cannot be opened; settings the device
  // refuses are listed in warnings() (the stream still runs).
  void Open();
  bool IsOpen() const { return capture_.isOpened(); }
  void Close() { capture_.release(); }

  // Grabs one frame; on a read failure the device is closed and IoError is
  // thrown naming it (the caller reopens later).
  bool Next(Frame* frame) override;
  std::string Describe() const override;
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  DeviceSourceOptions options_;
  cv::VideoCapture capture_;
  std::vector<std::string> warnings_;
  uint64_t next_index_ = 0;
};

}  // namespace capture
}  // namespace slope_monitor
