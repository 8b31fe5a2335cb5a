#include "slope_monitor/core/io/image_file.h"

#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

// Sequential, buffered reading of a file that is never held whole in
// memory; positions are byte offsets from the start of the file.
class ImageBytes {
 public:
  ImageBytes(const std::string& path, int64_t size) : path_(path), size_(size), buf_(1 << 16) {
    file_ = std::fopen(path.c_str(), "rb");
    if (!file_) Fail(Message("cannot be opened: ", std::strerror(errno)));
  }
  ~ImageBytes() {
    if (file_) std::fclose(file_);
  }
  ImageBytes(const ImageBytes&) = delete;
  ImageBytes& operator=(const ImageBytes&) = delete;

  int64_t position() const { return pos_; }
  int64_t size() const { return size_; }

  [[noreturn]] void Fail(const std::string& what) const {
    throw IoError(Message("image '", path_, "': ", what));
  }

  // The next byte, or -1 at the end of the file.
  int Get() {
    if (next_ == end_ && !Fill()) return -1;
    ++pos_;
    return buf_[next_++];
  }
  // Reads n bytes into out; false when the file ends first.
  bool Read(uint8_t* out, size_t n) {
    return Consume(n, [&out](const uint8_t* p, size_t k) {
      std::memcpy(out, p, k);
      out += k;
    });
  }
  // Passes the next n bytes to f(pointer, count) piece by piece; false when
  // the file ends first.
  template <typename F>
  bool Consume(uint64_t n, F&& f) {
    while (n > 0) {
      if (next_ == end_ && !Fill()) return false;
      const size_t k = static_cast<size_t>(std::min<uint64_t>(n, end_ - next_));
      f(buf_.data() + next_, k);
      next_ += k;
      pos_ += k;
      n -= k;
    }
    return true;
  }
  bool Skip(uint64_t n) {
    return Consume(n, [](const uint8_t*, size_t) {});
  }
  // Advances past the next byte 0xFF; false at the end of the file.
  bool SkipPastFF() {
    for (;;) {
      if (next_ == end_ && !Fill()) return false;
      const void* p = std::memchr(buf_.data() + next_, 0xFF, end_ - next_);
      if (!p) {
        pos_ += end_ - next_;
        next_ = end_;
        continue;
      }
      const size_t k = static_cast<const uint8_t*>(p) - buf_.data() + 1;
      pos_ += k - next_;
      next_ = k;
      return true;
    }
  }
  // Moves to byte `offset`; false beyond the end of the file.
  bool Seek(uint64_t offset) {
    if (offset > static_cast<uint64_t>(size_)) return false;
    if (fseeko(file_, static_cast<off_t>(offset), SEEK_SET) != 0) return false;
    pos_ = static_cast<int64_t>(offset);
    next_ = end_ = 0;
    return true;
  }

 private:
  bool Fill() {
    end_ = std::fread(buf_.data(), 1, buf_.size(), file_);
    next_ = 0;
    return end_ > 0;
  }

  std::string path_;
  int64_t size_ = 0;
  FILE* file_ = nullptr;
  std::vector<uint8_t> buf_;
  size_t next_ = 0, end_ = 0;
  int64_t pos_ = 0;
};

uint32_t Be32(const uint8_t* p) {
  return (uint32_t(p[0]) << 24) | (uint32_t(p[1]) << 16) | (uint32_t(p[2]) << 8) | p[3];
}

std::string Hex(int byte) {
  char s[8];
  std::snprintf(s, sizeof(s), "%02X", byte & 0xFF);
  return s;
}

// What a file that is none of our formats looks like, from its first bytes.
std::string Unrecognised(const uint8_t* b, size_t n) {
  auto starts = [&](const char* magic, size_t at = 0) {
    const size_t m = std::strlen(magic);
    return n >= at + m && std::memcmp(b + at, magic, m) == 0;
  };
  std::string looks;
  if (starts("GIF8")) {
    looks = "a GIF image";
  } else if (starts("BM")) {
    looks = "a BMP image";
  } else if (starts("RIFF") && starts("WEBP", 8)) {
    looks = "a WebP image";
  } else if (starts("ftyp", 4) && (starts("heic", 8) || starts("heix", 8) || starts("mif1", 8))) {
    looks = "a HEIF/HEIC image";
  } else if (starts("ftyp", 4)) {
    looks = "an ISO media file (video?)";
  } else if (n >= 4 && b[0] == 0xFF && b[1] == 0x4F && b[2] == 0xFF && b[3] == 0x51) {
    looks = "a JPEG 2000 codestream";
  } else if (starts("jP  ", 4)) {
    looks = "a JPEG 2000 image";
  } else if (starts("%PDF")) {
    looks = "a PDF document";
  } else if (starts("PK\x03\x04")) {
    looks = "a ZIP archive";
  } else if (starts("#ROSBAG")) {
    looks = "a ROS bag";
  } else if (std::all_of(b, b + n, [](uint8_t c) { return std::isprint(c) || std::isspace(c); })) {
    looks = "text";
  }
  std::string first;
  for (size_t i = 0; i < std::min<size_t>(n, 8); ++i) first += (i ? " " : "") + Hex(b[i]);
  return Message(
      "not an image format this program reads (JPEG, PNG, TIFF, PGM/PPM): the content ",
      looks.empty() ? "starts with " + first : "looks like " + looks + " (" + first + ")");
}

bool IsJpegSof(int m) { return m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC; }
bool IsStandaloneMarker(int m) { return m == 0x01 || (m >= 0xD0 && m <= 0xD7); }

// "truncated JPEG: ..." with libjpeg's own words, which a user may have seen.
[[noreturn]] void JpegTruncated(const ImageBytes& r, const std::string& where) {
  r.Fail(Message("truncated JPEG: the data ends at byte ", r.position(), " of ", r.size(), " ",
                 where, " (libjpeg: \"Premature end of JPEG file\")"));
}

// The marker of the next segment (after its 0xFF and fill bytes).
int JpegMarker(ImageBytes& r, const char* where) {
  const int c = r.Get();
  if (c < 0) JpegTruncated(r, where);
  if (c != 0xFF)
    r.Fail(Message("corrupt JPEG: byte ", r.position() - 1, " is 0x", Hex(c),
                   " where a marker (FF..) should start"));
  int m;
  do m = r.Get();
  while (m == 0xFF);
  if (m < 0) JpegTruncated(r, where);
  return m;
}

int JpegLength(ImageBytes& r, int marker) {
  const int hi = r.Get(), lo = r.Get();
  if (hi < 0 || lo < 0) JpegTruncated(r, "in a segment header");
  const int len = (hi << 8) | lo;
  if (len < 2)
    r.Fail(Message("corrupt JPEG: segment FF", Hex(marker), " at byte ", r.position() - 4,
                   " has length ", len));
  return len;
}

ImageHeader JpegHeader(ImageBytes& r) {
  r.Skip(2);  // SOI
  for (;;) {
    const int m = JpegMarker(r, "before the frame header (SOF)");
    if (IsStandaloneMarker(m)) continue;
    if (m == 0xD8 || m == 0xD9 || m == 0xDA)
      r.Fail(Message("corrupt JPEG: marker FF", Hex(m), " at byte ", r.position() - 2,
                     " before the frame header (SOF)"));
    const int len = JpegLength(r, m);
    if (IsJpegSof(m)) {
      uint8_t f[6];
      if (len < 8 || !r.Read(f, 6)) JpegTruncated(r, "in the frame header (SOF)");
      ImageHeader h;
      h.format = "jpeg";
      h.bit_depth = f[0];
      h.height = (f[1] << 8) | f[2];
      h.width = (f[3] << 8) | f[4];
      h.channels = f[5];
      if (h.height == 0)
        r.Fail(
            "the JPEG frame header gives the height 0 (a DNL segment), which this program does not "
            "read");
      return h;
    }
    if (!r.Skip(len - 2)) JpegTruncated(r, Message("in segment FF", Hex(m)));
  }
}

// Walks the whole JPEG: segments by their lengths, entropy-coded data up to
// the next marker (0xFF 0x00 stuffing and restart markers are data), until
// the end-of-image marker. Bytes after it are padding.
void CheckJpeg(ImageBytes& r) {
  r.Skip(2);  // SOI
  int m = -1;
  for (;;) {
    if (m < 0) m = JpegMarker(r, "before the end-of-image marker FFD9");
    if (m == 0xD9) return;
    if (m == 0xD8)
      r.Fail(Message("corrupt JPEG: a second start-of-image marker at byte ", r.position() - 2));
    if (IsStandaloneMarker(m)) {
      m = -1;
      continue;
    }
    const int len = JpegLength(r, m);
    if (!r.Skip(len - 2)) JpegTruncated(r, "before the end-of-image marker FFD9");
    if (m != 0xDA) {
      m = -1;
      continue;
    }
    // A scan: its data runs up to the next marker that is not a restart.
    m = -1;
    while (m < 0) {
      if (!r.SkipPastFF()) JpegTruncated(r, "before the end-of-image marker FFD9");
      int b;
      do b = r.Get();
      while (b == 0xFF);
      if (b < 0) JpegTruncated(r, "before the end-of-image marker FFD9");
      if (b != 0x00 && !(b >= 0xD0 && b <= 0xD7)) m = b;
    }
  }
}

ImageHeader PngHeader(ImageBytes& r) {
  uint8_t b[8 + 8 + 13];
  if (!r.Read(b, sizeof(b)))
    r.Fail(Message("truncated PNG: ", r.size(), " bytes, too short for its header"));
  if (Be32(b + 8) != 13 || std::memcmp(b + 12, "IHDR", 4) != 0)
    r.Fail("corrupt PNG: the first chunk is not the 13-byte header IHDR");
  const uint32_t w = Be32(b + 16), h = Be32(b + 20);
  const int depth = b[24], colour = b[25];
  if (w == 0 || h == 0 || w > 0x7FFFFFFFu || h > 0x7FFFFFFFu)
    r.Fail(Message("corrupt PNG: the header gives the size ", w, " x ", h, " px"));
  ImageHeader hd;
  hd.format = "png";
  hd.width = static_cast<int>(w);
  hd.height = static_cast<int>(h);
  switch (colour) {
    case 0:
      hd.channels = 1;
      break;
    case 2:
    case 3:  // palette
      hd.channels = 3;
      break;
    case 4:
      hd.channels = 2;
      break;
    case 6:
      hd.channels = 4;
      break;
    default:
      r.Fail(Message("corrupt PNG: colour type ", colour, " in the header"));
  }
  if (depth != 1 && depth != 2 && depth != 4 && depth != 8 && depth != 16)
    r.Fail(Message("corrupt PNG: bit depth ", depth, " in the header"));
  hd.bit_depth = depth == 16 ? 16 : 8;
  return hd;
}

uint32_t Crc32(uint32_t crc, const uint8_t* p, size_t n) {
  static const std::vector<uint32_t> table = [] {
    std::vector<uint32_t> t(256);
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  for (size_t i = 0; i < n; ++i) crc = table[(crc ^ p[i]) & 0xFF] ^ (crc >> 8);
  return crc;
}

// Every chunk's length and CRC-32, up to IEND.
void CheckPng(ImageBytes& r) {
  r.Skip(8);
  for (;;) {
    const int64_t at = r.position();
    uint8_t head[8];
    if (!r.Read(head, 8))
      r.Fail(Message("truncated PNG: the data ends at byte ", r.position(), " of ", r.size(),
                     " before the end chunk IEND"));
    const uint32_t len = Be32(head);
    const std::string type(reinterpret_cast<const char*>(head + 4), 4);
    if (len > 0x7FFFFFFFu || !std::all_of(type.begin(), type.end(), [](char c) {
          return std::isalpha(static_cast<unsigned char>(c));
        }))
      r.Fail(Message("corrupt PNG: no valid chunk at byte ", at));
    uint32_t crc = Crc32(0xFFFFFFFFu, head + 4, 4);
    uint8_t stored[4];
    if (!r.Consume(len, [&crc](const uint8_t* p, size_t n) { crc = Crc32(crc, p, n); }) ||
        !r.Read(stored, 4))
      r.Fail(Message("truncated PNG: the data ends at byte ", r.position(), " of ", r.size(),
                     " inside chunk '", type, "' (", len, " bytes from byte ", at, ")"));
    if (Be32(stored) != (crc ^ 0xFFFFFFFFu))
      r.Fail(Message("corrupt PNG: CRC error in chunk '", type, "' at byte ", at));
    if (type == "IEND") return;
  }
}

// TIFF and BigTIFF: the first IFD's width, height, samples and bits.
ImageHeader TiffHeader(ImageBytes& r) {
  uint8_t b[16];
  const bool big_endian = r.Read(b, 8) && b[0] == 'M';
  const bool big_tiff = (big_endian ? b[3] : b[2]) == 43;
  auto u = [big_endian](const uint8_t* p, int n) {
    uint64_t v = 0;
    for (int i = 0; i < n; ++i) v |= uint64_t(p[big_endian ? n - 1 - i : i]) << (8 * i);
    return v;
  };
  uint64_t ifd = u(b + 4, 4);
  if (big_tiff) {
    if (!r.Read(b + 8, 8)) r.Fail("truncated TIFF: no first IFD offset");
    ifd = u(b + 8, 8);
  }
  const int count_size = big_tiff ? 8 : 2, entry_size = big_tiff ? 20 : 12,
            field = big_tiff ? 8 : 4;
  if (!r.Seek(ifd) || !r.Read(b, count_size))
    r.Fail(Message("corrupt TIFF: the first IFD offset ", ifd, " is beyond the file's ", r.size(),
                   " bytes"));
  const uint64_t entries = u(b, count_size);
  if (entries == 0 || entries > 4096)
    r.Fail(Message("corrupt TIFF: ", entries, " entries in the first IFD"));
  int64_t width = -1, height = -1, samples = 1, bits = 1;
  uint64_t bits_offset = 0;
  for (uint64_t i = 0; i < entries; ++i) {
    uint8_t e[20];
    if (!r.Read(e, entry_size)) r.Fail("truncated TIFF: the file ends inside the first IFD");
    const int tag = static_cast<int>(u(e, 2)), type = static_cast<int>(u(e + 2, 2));
    const uint64_t n = u(e + 4, big_tiff ? 8 : 4);
    const uint8_t* value = e + 4 + (big_tiff ? 8 : 4);
    const int size = type == 3 ? 2 : type == 4 ? 4 : type == 16 ? 8 : 0;  // SHORT LONG LONG8
    if (size == 0 || n == 0) continue;
    if (n * size > static_cast<uint64_t>(field)) {
      if (tag == 258) bits_offset = u(value, field);  // BitsPerSample, one per sample
      continue;
    }
    const int64_t v = static_cast<int64_t>(u(value, size));
    if (tag == 256) width = v;
    if (tag == 257) height = v;
    if (tag == 258) bits = v;
    if (tag == 277) samples = v;
  }
  if (bits_offset) {
    uint8_t s[2];
    if (r.Seek(bits_offset) && r.Read(s, 2)) bits = static_cast<int64_t>(u(s, 2));
  }
  if (width < 0 || height < 0)
    r.Fail("corrupt TIFF: the first IFD has no ImageWidth or ImageLength");
  if (width == 0 || height == 0 || width > std::numeric_limits<int>::max() ||
      height > std::numeric_limits<int>::max())
    r.Fail(Message("corrupt TIFF: the header gives the size ", width, " x ", height, " px"));
  ImageHeader h;
  h.format = "tiff";
  h.width = static_cast<int>(width);
  h.height = static_cast<int>(height);
  h.channels = static_cast<int>(std::clamp<int64_t>(samples, 1, 65535));
  h.bit_depth = static_cast<int>(std::clamp<int64_t>(bits, 1, 64));
  return h;
}

// Netpbm (P1..P6): the header's numbers; `data_start` the offset of the samples.
ImageHeader PnmHeader(ImageBytes& r, int64_t* data_start, int* kind) {
  r.Skip(1);
  *kind = r.Get() - '0';
  const int fields = (*kind == 1 || *kind == 4) ? 2 : 3;
  int64_t v[3] = {0, 0, fields == 2 ? 1 : 0};  // a bitmap has no maximum
  int c = r.Get();
  for (int k = 0; k < fields; ++k) {
    for (;;) {  // white space and comments
      if (c == '#') {
        while (c >= 0 && c != '\n' && c != '\r') c = r.Get();
      } else if (c >= 0 && std::isspace(c)) {
        c = r.Get();
      } else {
        break;
      }
    }
    if (c < '0' || c > '9')
      r.Fail("corrupt PGM/PPM: the header's width, height or maximum is missing");
    for (; c >= '0' && c <= '9'; c = r.Get()) {
      v[k] = v[k] * 10 + (c - '0');
      if (v[k] > std::numeric_limits<int>::max())
        r.Fail("corrupt PGM/PPM: a header number is too large");
    }
  }
  *data_start = r.position();  // one white-space byte after the last number was read
  if (v[0] == 0 || v[1] == 0 || v[2] == 0 || v[2] > 65535)
    r.Fail(Message("corrupt PGM/PPM: the header gives ", v[0], " x ", v[1], " px, maximum ", v[2]));
  ImageHeader h;
  h.format = "pnm";
  h.width = static_cast<int>(v[0]);
  h.height = static_cast<int>(v[1]);
  h.channels = (*kind == 3 || *kind == 6) ? 3 : 1;
  h.bit_depth = v[2] > 255 ? 16 : 8;
  return h;
}

const char* FormatName(const std::string& format) {
  return format == "jpeg"   ? "JPEG"
         : format == "png"  ? "PNG"
         : format == "tiff" ? "TIFF"
                            : "PGM/PPM";
}

struct Opened {
  ImageHeader header;
  int64_t pnm_data_start = 0;
  int pnm_kind = 0;
};

// Checks the file, recognises its format by the content and reads the
// header, leaving `r` anywhere.
Opened OpenImage(ImageBytes& r, const ImageFileOptions& options) {
  uint8_t b[16] = {0};
  size_t n = 0;
  for (int c; n < sizeof(b) && (c = r.Get()) >= 0;) b[n++] = static_cast<uint8_t>(c);
  r.Seek(0);
  Opened o;
  static const uint8_t kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (n >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) {
    o.header = JpegHeader(r);
  } else if (n >= 8 && std::memcmp(b, kPng, 8) == 0) {
    o.header = PngHeader(r);
  } else if (n >= 8 && ((b[0] == 'I' && b[1] == 'I' && (b[2] == 42 || b[2] == 43) && b[3] == 0) ||
                        (b[0] == 'M' && b[1] == 'M' && b[2] == 0 && (b[3] == 42 || b[3] == 43)))) {
    o.header = TiffHeader(r);
  } else if (n >= 3 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6' && std::isspace(b[2])) {
    o.header = PnmHeader(r, &o.pnm_data_start, &o.pnm_kind);
  } else {
    r.Fail(Unrecognised(b, n));
  }
  const ImageHeader& h = o.header;
  const double mp = double(h.width) * double(h.height) / 1e6;
  if (!(mp <= options.max_megapixels)) {
    char size[32];
    std::snprintf(size, sizeof(size), "%.1f", mp);
    r.Fail(Message("the ", FormatName(h.format), " header claims ", h.width, " x ", h.height,
                   " px (", size, " MP), more than max_megapixels ", options.max_megapixels,
                   "; refused before decoding"));
  }
  return o;
}

int64_t ImageFileSize(const std::string& path) {
  struct stat st;
  if (stat(path.c_str(), &st) != 0) {
    throw IoError(Message("image '", path, "': ",
                          errno == ENOENT ? std::string("no such file") : std::strerror(errno)));
  }
  if (S_ISDIR(st.st_mode)) throw IoError(Message("image '", path, "': is a folder, not a file"));
  if (!S_ISREG(st.st_mode)) throw IoError(Message("image '", path, "': not a regular file"));
  if (st.st_size == 0) throw IoError(Message("image '", path, "': empty file (0 bytes)"));
  return st.st_size;
}

}  // namespace

void ImageFileOptions::Check() const {
  RequireOption("ImageFileOptions", std::isfinite(max_megapixels) && max_megapixels > 0,
                "max_megapixels", Message("must be > 0 (is ", max_megapixels, ")"));
}

ImageHeader ReadImageHeader(const std::string& path, const ImageFileOptions& options) {
  options.Check();
  ImageBytes r(path, ImageFileSize(path));
  return OpenImage(r, options).header;
}

ImageHeader CheckImageFile(const std::string& path, const ImageFileOptions& options) {
  options.Check();
  ImageBytes r(path, ImageFileSize(path));
  const Opened o = OpenImage(r, options);
  r.Seek(0);
  if (o.header.format == "jpeg") CheckJpeg(r);
  if (o.header.format == "png") CheckPng(r);
  if (o.header.format == "pnm" && o.pnm_kind >= 5) {
    const int64_t need = o.pnm_data_start + int64_t(o.header.width) * o.header.height *
                                                o.header.channels * (o.header.bit_depth / 8);
    if (r.size() < need)
      r.Fail(Message("truncated PGM/PPM: ", r.size(), " bytes, the header's ", o.header.width,
                     " x ", o.header.height, " px need ", need));
  }
  return o.header;
}

cv::Mat ReadImageChecked(const std::string& path, int imread_flags,
                         const ImageFileOptions& options) {
  const ImageHeader h = CheckImageFile(path, options);
  cv::Mat image;
  try {
    image = cv::imread(path, imread_flags);
  } catch (const cv::Exception& e) {
    throw IoError(Message("image '", path, "': OpenCV cannot decode this ", FormatName(h.format),
                          " file: ", e.what()));
  }
  if (image.empty())
    throw IoError(Message("image '", path, "': OpenCV cannot decode this ", FormatName(h.format),
                          " file (", h.width, " x ", h.height, " px, ", h.channels, " x ",
                          h.bit_depth, " bit)"));
  return image;
}

std::string FormatNote(const std::string& path, const ImageHeader& header) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  const std::string& f = header.format;
  const bool matches =
      (f == "jpeg" && (ext == ".jpg" || ext == ".jpeg" || ext == ".jpe")) ||
      (f == "png" && ext == ".png") || (f == "tiff" && (ext == ".tif" || ext == ".tiff")) ||
      (f == "pnm" && (ext == ".pgm" || ext == ".ppm" || ext == ".pnm" || ext == ".pbm"));
  if (matches) return "";
  return Message("image '", path, "': the content is ", FormatName(f),
                 ", not what the name says; read as ", FormatName(f));
}

}  // namespace io
}  // namespace slope_monitor
