#include "slope_monitor/core/capture/sources.h"

#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace capture {
namespace fs = std::filesystem;
namespace {

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool IsJpegName(const std::string& path) {
  const std::string ext = Lower(fs::path(path).extension().string());
  return ext == ".jpg" || ext == ".jpeg";
}

// Modification time of a file [s since the Unix epoch].
double FileTime(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw IoError(Message(path, ": cannot stat the file (", std::strerror(errno), ")"));
  return static_cast<double>(st.st_mtim.tv_sec) + 1e-9 * static_cast<double>(st.st_mtim.tv_nsec);
}

double WallClockNow() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

const char* StampSourceName(StampSource s) {
  switch (s) {
    case StampSource::kExif:
      return "exif";
    case StampSource::kFile:
      return "file";
    case StampSource::kVideo:
      return "video";
    case StampSource::kClock:
      return "clock";
  }
  return "unknown";
}

std::vector<SkippedItem> FrameSource::TakeSkipped() {
  std::vector<SkippedItem> out;
  out.swap(skipped_);
  return out;
}

void FrameSource::Skip(const std::string& name, const std::string& reason) {
  ++skipped_count_;
  skipped_.push_back({name, reason});
}

void CheckEncodingOption(const std::string& encoding) {
  if (encoding != "auto" && encoding != "mono8" && encoding != "bgr8") {
    throw ConfigError(Message("encoding '", encoding, "' is not one of: auto, mono8, bgr8"));
  }
}

std::string ConvertEncoding(const std::string& requested, cv::Mat* image) {
  const int ch = image->channels();
  const int depth = image->depth();
  if (depth != CV_8U && depth != CV_16U) {
    throw InvalidArgument(Message("image depth ", depth, " is neither 8 nor 16 bit unsigned"));
  }
  if (ch == 4) {
    cv::cvtColor(*image, *image, cv::COLOR_BGRA2BGR);
  } else if (ch != 1 && ch != 3) {
    throw InvalidArgument(Message("image has ", ch, " channels (1, 3 or 4 expected)"));
  }
  if (requested == "mono8" || requested == "bgr8") {
    if (image->depth() == CV_16U) image->convertTo(*image, CV_8U, 1.0 / 257.0);
    if (requested == "mono8" && image->channels() == 3)
      cv::cvtColor(*image, *image, cv::COLOR_BGR2GRAY);
    if (requested == "bgr8" && image->channels() == 1)
      cv::cvtColor(*image, *image, cv::COLOR_GRAY2BGR);
    return requested;
  }
  const bool mono = image->channels() == 1;
  if (image->depth() == CV_16U) return mono ? "mono16" : "bgr16";
  return mono ? "mono8" : "bgr8";
}

std::string CheckJpegStructure(const std::vector<unsigned char>& b, JpegFrameInfo* info) {
  const size_t n = b.size();
  if (n < 4 || b[0] != 0xFF || b[1] != 0xD8)
    return "not a JPEG: no SOI marker (FF D8) at the start";
  size_t pos = 2;
  while (pos < n) {
    if (b[pos] != 0xFF) return Message("corrupt: expected a marker at byte ", pos);
    while (pos + 1 < n && b[pos + 1] == 0xFF) ++pos;  // fill bytes
    if (pos + 1 >= n) break;
    const unsigned char m = b[pos + 1];
    if (m == 0xD9) return "";  // EOI
    if ((m >= 0xD0 && m <= 0xD7) || m == 0x01) {
      pos += 2;
      continue;
    }
    if (pos + 3 >= n)
      return Message("truncated in the marker FF ", std::hex, int(m), std::dec, " at byte ", pos);
    const size_t len = (size_t(b[pos + 2]) << 8) | b[pos + 3];
    if (len < 2 || pos + 2 + len > n) {
      return Message("truncated: marker segment FF ", std::hex, int(m), std::dec, " at byte ", pos,
                     " needs ", len, " bytes, the file has ", n - pos - 2);
    }
    const bool sof = m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC;
    if (sof && info != nullptr && len >= 8) {
      info->precision = b[pos + 4];
      info->height = (int(b[pos + 5]) << 8) | b[pos + 6];
      info->width = (int(b[pos + 7]) << 8) | b[pos + 8];
      info->components = b[pos + 9];
    }
    pos += 2 + len;
    if (m == 0xDA) {  // start of scan: skip the entropy-coded data
      for (;;) {
        const void* ff = std::memchr(b.data() + pos, 0xFF, n - pos);
        if (ff == nullptr) {
          return Message("truncated: the image data ends at byte ", n, " without an EOI marker");
        }
        pos = static_cast<const unsigned char*>(ff) - b.data();
        if (pos + 1 >= n)
          return Message("truncated: the image data ends at byte ", n, " without an EOI marker");
        const unsigned char next = b[pos + 1];
        if (next == 0x00 || (next >= 0xD0 && next <= 0xD7) || next == 0xFF) {
          pos += (next == 0xFF) ? 1 : 2;
          continue;
        }
        break;  // a real marker
      }
    }
  }
  return Message("truncated: no EOI marker (FF D9) in ", n, " bytes");
}

cv::Mat DecodeImageFile(const std::string& path, const std::string& encoding,
                        std::string* encoding_out, const ImageBuffer& buffer, bool* in_buffer) {
  if (in_buffer != nullptr) *in_buffer = false;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(Message(path, ": cannot open the file"));
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  in.seekg(0, std::ios::beg);
  if (size <= 0) throw IoError(Message(path, ": the file is empty"));
  std::vector<unsigned char> bytes(static_cast<size_t>(size));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), size))
    throw IoError(Message(path, ": read error"));
  // Keep the sensor's pixel layout (no EXIF rotation): the calibration refers to it.
  const int flags = cv::IMREAD_ANYCOLOR | cv::IMREAD_ANYDEPTH | cv::IMREAD_IGNORE_ORIENTATION;
  cv::Mat image;
  if (IsJpegName(path)) {
    JpegFrameInfo info;
    const std::string why = CheckJpegStructure(bytes, &info);
    if (!why.empty()) throw IoError(Message(path, ": unreadable JPEG, ", why));
    // 8-bit grey or YCbCr JPEGs decode to mono8 / bgr8 (IMREAD_ANYCOLOR):
    // straight into the caller's buffer when that is the requested encoding.
    const bool mono = info.components == 1, colour = info.components == 3;
    if (buffer && info.precision == 8 && info.width > 0 && info.height > 0 &&
        ((mono && encoding != "bgr8") || (colour && encoding != "mono8"))) {
      image = buffer(info.height, info.width, mono ? CV_8UC1 : CV_8UC3);
      const unsigned char* target = image.data;
      cv::imdecode(bytes, flags, &image);
      if (image.empty()) throw IoError(Message(path, ": OpenCV cannot decode the image"));
      if (image.data == target) {
        if (in_buffer != nullptr) *in_buffer = true;
        *encoding_out = mono ? "mono8" : "bgr8";
        return image;
      }
      // The decoder chose another layout (it reallocated): convert below.
    }
  }
  if (image.empty()) image = cv::imdecode(bytes, flags);
  if (image.empty()) throw IoError(Message(path, ": OpenCV cannot decode the image"));
  try {
    *encoding_out = ConvertEncoding(encoding, &image);
  } catch (const InvalidArgument& e) {
    throw IoError(Message(path, ": ", e.what()));
  }
  return image;
}

// ---------------------------------------------------------------------------
void FolderSourceOptions::Check() const {
  if (folder.empty()) throw ConfigError("folder: the image folder path is empty");
  if (extensions.empty())
    throw ConfigError("extensions: the list of image file extensions is empty");
  if (time_source != "exif" && time_source != "file") {
    throw ConfigError(Message("time_source '", time_source, "' is not one of: exif, file"));
  }
  if (!std::isfinite(clock_offset)) throw ConfigError("clock_offset must be finite");
  CheckEncodingOption(encoding);
}

FolderSource::FolderSource(const FolderSourceOptions& options) : options_(options) {
  options_.Check();
  std::error_code ec;
  if (!fs::is_directory(options_.folder, ec)) {
    throw IoError(
        Message("image folder '", options_.folder, "' does not exist or is not a directory"));
  }
  std::vector<std::string> exts;
  for (const auto& e : options_.extensions) exts.push_back(Lower(e));
  for (const auto& de : fs::directory_iterator(options_.folder, ec)) {
    if (!de.is_regular_file()) continue;
    const std::string ext = Lower(de.path().extension().string());
    if (std::find(exts.begin(), exts.end(), ext) == exts.end()) continue;
    Entry entry;
    entry.path = de.path().string();
    bool stamped = false;
    if (options_.time_source == "exif") {
      try {
        entry.exif = ReadExif(entry.path);
        if (entry.exif.has_time) {
          entry.stamp = entry.exif.time + options_.clock_offset;
          entry.stamp_source = StampSource::kExif;
          stamped = true;
        }
      } catch (const Error& e) {
        exif_warnings_.push_back({entry.path, e.what()});
        entry.exif = ExifInfo();
      }
    } else {
      try {
        entry.exif = ReadExif(entry.path);
      } catch (const Error& e) {
        exif_warnings_.push_back({entry.path, e.what()});
      }
    }
    if (!stamped) {
      try {
        entry.stamp = FileTime(entry.path);
      } catch (const IoError& e) {
        exif_warnings_.push_back({entry.path, e.what()});
        continue;
      }
      entry.stamp_source = StampSource::kFile;
    }
    try {
      entry.attitude = ReadPhotoAttitude(entry.path);  // XMP attitude and the header's size
    } catch (const Error&) {
      entry.attitude = PhotoAttitude();  // unreadable: decoding names it (skipped then)
    }
    entries_.push_back(std::move(entry));
  }
  if (ec) throw IoError(Message("image folder '", options_.folder, "': ", ec.message()));
  if (entries_.empty()) {
    throw IoError(
        Message("image folder '", options_.folder, "' holds no file with a listed extension"));
  }
  LeaveOutOddPhotos();
  std::sort(entries_.begin(), entries_.end(), [](const Entry& a, const Entry& b) {
    return a.stamp != b.stamp ? a.stamp < b.stamp : a.path < b.path;
  });
}

void FolderSource::LeaveOutOddPhotos() {
  // One camera per flight (PhotoCamera: make, model, size, focal length), the
  // folder's most common; photos whose header could not be read are kept
  // here and named by the decoder.
  std::vector<PhotoCamera> cameras;  // per entry
  std::vector<PhotoCamera> readable;
  size_t with_gps = 0;
  for (const Entry& e : entries_) {
    cameras.push_back(PhotoCamera::Of(e.exif, e.attitude.width, e.attitude.height));
    if (e.attitude.width > 0) readable.push_back(cameras.back());
    if (e.exif.has_gps) ++with_gps;
  }
  const auto [common, most] = MostCommonCamera(readable);
  const bool gnss_folder = 2 * with_gps > entries_.size();
  std::vector<Entry> kept;
  for (size_t i = 0; i < entries_.size(); ++i) {
    Entry& e = entries_[i];
    const PhotoCamera& camera = cameras[i];
    if (e.attitude.width > 0 && camera != common) {
      const bool size = camera.width != common.width || camera.height != common.height;
      left_out_.push_back(
          {e.path, size ? Message(camera.width, "x", camera.height, " px, not the folder's ",
                                  common.width, "x", common.height, " px (", most, " photos)")
                        : Message("another camera (", camera.Describe(), ") than the folder's ",
                                  most, " photos (", common.Describe(), ")")});
    } else if (gnss_folder && !e.exif.has_gps &&
               e.attitude.width > 0) {  // (unreadable: the decoder names it)
      left_out_.push_back({e.path, Message("no EXIF GNSS position (", with_gps, " of ",
                                           entries_.size(), " photos of the folder have one)")});
    } else {
      kept.push_back(std::move(e));
    }
  }
  entries_ = std::move(kept);
}

bool FolderSource::Next(Frame* frame) {
  while (next_ < entries_.size()) {
    const Entry& e = entries_[next_];
    const uint64_t index = next_++;
    try {
      frame->image = DecodeImageFile(e.path, options_.encoding, &frame->encoding, image_buffer_,
                                     &frame->in_image_buffer);
    } catch (const IoError& err) {
      Skip(e.path, err.what());
      continue;
    }
    frame->stamp = e.stamp;
    frame->stamp_source = e.stamp_source;
    frame->name = e.path;
    frame->index = index;
    frame->exif = e.exif;
    frame->attitude = e.attitude;
    return true;
  }
  return false;
}

std::optional<double> FolderSource::PeekNextStamp() const {
  if (next_ >= entries_.size()) return std::nullopt;
  return entries_[next_].stamp;
}

std::string FolderSource::Describe() const {
  return Message("image folder '", options_.folder, "' (", entries_.size(), " files)");
}

std::vector<std::string> FolderSource::Files() const {
  std::vector<std::string> out;
  for (const auto& e : entries_) out.push_back(e.path);
  return out;
}

// ---------------------------------------------------------------------------
void VideoSourceOptions::Check() const {
  if (path.empty()) throw ConfigError("video_file: the video file path is empty");
  if (!std::isfinite(start_time)) throw ConfigError("video_start_time must be finite");
  if (!std::isfinite(fps) || fps < 0.0 || fps > 1000.0) {
    throw ConfigError(Message("video_fps = ", fps, " Hz is outside [0, 1000]"));
  }
  if (frame_step < 1) throw ConfigError(Message("frame_step = ", frame_step, " must be >= 1"));
  CheckEncodingOption(encoding);
}

VideoSource::VideoSource(const VideoSourceOptions& options) : options_(options) {
  options_.Check();
  std::error_code ec;
  if (!fs::is_regular_file(options_.path, ec)) {
    throw IoError(Message("video file '", options_.path, "' does not exist"));
  }
  if (!capture_.open(options_.path)) {
    throw IoError(Message("video file '", options_.path,
                          "' cannot be opened by OpenCV (unsupported container or codec?)"));
  }
  fps_ = options_.fps > 0.0 ? options_.fps : capture_.get(cv::CAP_PROP_FPS);
  if (!(fps_ > 0.0) || !std::isfinite(fps_)) {
    throw IoError(Message("video file '", options_.path, "' has no frame rate; set video_fps"));
  }
  const double count = capture_.get(cv::CAP_PROP_FRAME_COUNT);
  frame_count_ = count > 0 ? static_cast<int64_t>(count) : -1;
  start_time_ = options_.start_time >= 0.0 ? options_.start_time : FileTime(options_.path);
}

bool VideoSource::Next(Frame* frame) {
  if (ended_) return false;
  cv::Mat image;
  // Skip to the next frame we publish (grab() does not decode).
  while (next_index_ % options_.frame_step != 0) {
    if (!capture_.grab()) {
      ended_ = true;
      return false;
    }
    ++next_index_;
  }
  if (!capture_.read(image) || image.empty()) {
    ended_ = true;
    return false;
  }
  const int64_t index = next_index_++;
  frame->image = image;
  frame->encoding = ConvertEncoding(options_.encoding, &frame->image);
  frame->stamp = start_time_ + static_cast<double>(index) / fps_;
  frame->stamp_source = StampSource::kVideo;
  frame->name = Message(options_.path, "#", index);
  frame->index = static_cast<uint64_t>(index);
  frame->exif = ExifInfo();
  frame->in_image_buffer = false;
  return true;
}

std::optional<double> VideoSource::PeekNextStamp() const {
  if (ended_) return std::nullopt;
  int64_t i = next_index_;
  while (i % options_.frame_step != 0) ++i;
  if (frame_count_ >= 0 && i >= frame_count_) return std::nullopt;
  return start_time_ + static_cast<double>(i) / fps_;
}

std::string VideoSource::Describe() const {
  return Message("video file '", options_.path, "' (", fps_, " fps, ", frame_count_, " frames)");
}

// ---------------------------------------------------------------------------
void DeviceSourceOptions::Check() const {
  if (device.empty()) throw ConfigError("device: the V4L2 device path is empty");
  if (api != "v4l2" && api != "any")
    throw ConfigError(Message("device_api '", api, "' is not one of: v4l2, any"));
  if (width < 0 || width > 20000)
    throw ConfigError(Message("width = ", width, " px is outside [0, 20000]"));
  if (height < 0 || height > 20000)
    throw ConfigError(Message("height = ", height, " px is outside [0, 20000]"));
  if (!std::isfinite(fps) || fps < 0.0 || fps > 1000.0)
    throw ConfigError(Message("fps = ", fps, " Hz is outside [0, 1000]"));
  if (!std::isfinite(exposure)) throw ConfigError("exposure must be finite");
  CheckEncodingOption(encoding);
}

DeviceSource::DeviceSource(const DeviceSourceOptions& options) : options_(options) {
  options_.Check();
}

void DeviceSource::Open() {
  warnings_.clear();
  const std::string name = Describe();
  if (options_.api == "v4l2") {
    std::error_code ec;
    if (!fs::exists(options_.device, ec)) {
      throw IoError(Message(name, " does not exist (no camera connected?)"));
    }
    if (!capture_.open(options_.device, cv::CAP_V4L2)) {
      throw IoError(
          Message(name, " cannot be opened (busy, no permission, or not a capture device)"));
    }
  } else if (!capture_.open(options_.device, cv::CAP_ANY)) {
    throw IoError(
        Message(name, " cannot be opened by OpenCV (unreachable, or no backend reads it)"));
  }
  auto set = [this, &name](int prop, double value, const char* what) {
    if (!capture_.set(prop, value)) {
      warnings_.push_back(Message(name, " refused ", what, " = ", value));
    }
  };
  if (options_.width > 0) set(cv::CAP_PROP_FRAME_WIDTH, options_.width, "width");
  if (options_.height > 0) set(cv::CAP_PROP_FRAME_HEIGHT, options_.height, "height");
  if (options_.fps > 0.0) set(cv::CAP_PROP_FPS, options_.fps, "fps");
  if (options_.exposure >= 0.0) {
    set(cv::CAP_PROP_AUTO_EXPOSURE, 1.0, "manual exposure mode (auto_exposure = 1)");
    set(cv::CAP_PROP_EXPOSURE, options_.exposure, "exposure");
  } else if (options_.api == "v4l2") {
    set(cv::CAP_PROP_AUTO_EXPOSURE, 3.0, "auto exposure mode (auto_exposure = 3)");
  }
}

bool DeviceSource::Next(Frame* frame) {
  if (!capture_.isOpened()) throw IoError(Message(Describe(), " is not open"));
  cv::Mat image;
  if (!capture_.read(image) || image.empty()) {
    capture_.release();
    throw IoError(
        Message(Describe(), " returned no frame (disconnected, or the end of a file?); closed it"));
  }
  frame->stamp = WallClockNow();
  frame->image = image;
  frame->encoding = ConvertEncoding(options_.encoding, &frame->image);
  frame->stamp_source = StampSource::kClock;
  frame->name = options_.device;
  frame->index = next_index_++;
  frame->exif = ExifInfo();
  frame->in_image_buffer = false;
  return true;
}

std::string DeviceSource::Describe() const {
  return Message(options_.api == "v4l2" ? "V4L2 device '" : "camera '", options_.device, "'");
}

}  // namespace capture
}  // namespace slope_monitor
