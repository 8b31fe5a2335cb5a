// Photos read without trusting them (issue 38): the header tells the size
// and the format by the content; a truncated JPEG (which OpenCV decodes with
// only libjpeg's warning "Premature end of JPEG file"), a truncated or
// damaged PNG, an empty, missing or non-image file is refused with the path
// and the reason; a header forged to claim 20000 x 20000 px is refused from
// the header, before anything of that size is allocated.
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_file.h"

namespace slope_monitor {
namespace io {
namespace {

namespace fs = std::filesystem;

class ImageFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sm_image_file_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  // A 320 x 240 colour photo with detail (so the JPEG has entropy-coded data
  // throughout), written by OpenCV.
  std::string Photo(const std::string& name, const std::string& ext) const {
    cv::Mat photo(240, 320, CV_8UC3);
    cv::RNG rng(38);
    rng.fill(photo, cv::RNG::UNIFORM, 0, 255);
    const std::string tmp = Path("tmp" + ext);
    EXPECT_TRUE(cv::imwrite(tmp, photo));
    fs::rename(tmp, Path(name));
    return Path(name);
  }

  static std::vector<char> Bytes(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::vector<char>(std::istreambuf_iterator<char>(in), {});
  }
  static void Write(const std::string& path, const std::vector<char>& bytes) {
    std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), bytes.size());
  }

  // The IoError's text, or "" when nothing was thrown.
  static std::string Refusal(const std::string& path, const ImageFileOptions& options = {}) {
    try {
      ReadImageChecked(path, cv::IMREAD_UNCHANGED, options);
    } catch (const IoError& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

TEST_F(ImageFileTest, GoodJpegAndPngAreRead) {
  for (const std::string ext : {".jpg", ".png"}) {
    const std::string path = Photo("good" + ext, ext);
    const ImageHeader h = ReadImageHeader(path);
    EXPECT_EQ(h.format, ext == ".jpg" ? "jpeg" : "png");
    EXPECT_EQ(h.width, 320);
    EXPECT_EQ(h.height, 240);
    EXPECT_EQ(h.channels, 3);
    EXPECT_EQ(h.bit_depth, 8);
    EXPECT_EQ(FormatNote(path, h), "");
    const cv::Mat image = ReadImageChecked(path, cv::IMREAD_COLOR);
    EXPECT_EQ(image.cols, 320);
    EXPECT_EQ(image.rows, 240);
    EXPECT_EQ(image.type(), CV_8UC3);
  }
}

TEST_F(ImageFileTest, JpegTruncatedToHalfIsRefused) {
  const std::string path = Photo("half.jpg", ".jpg");
  std::vector<char> bytes = Bytes(path);
  bytes.resize(bytes.size() / 2);
  Write(path, bytes);
  // What the tools did before: OpenCV decodes it (libjpeg only warns).
  EXPECT_FALSE(cv::imread(path, cv::IMREAD_COLOR).empty());
  EXPECT_EQ(ReadImageHeader(path).width, 320);  // the header is whole
  const std::string why = Refusal(path);
  EXPECT_NE(why.find("image '" + path + "': truncated JPEG"), std::string::npos) << why;
  EXPECT_NE(why.find("before the end-of-image marker FFD9"), std::string::npos) << why;
  EXPECT_NE(why.find("Premature end of JPEG file"), std::string::npos) << why;
}

TEST_F(ImageFileTest, JpegWithPaddingAfterTheEndMarkerIsRead) {
  const std::string path = Photo("padded.jpg", ".jpg");
  std::vector<char> bytes = Bytes(path);
  bytes.insert(bytes.end(), 4096, '\0');
  Write(path, bytes);
  EXPECT_EQ(Refusal(path), "");
}

TEST_F(ImageFileTest, PngTruncatedOrDamagedIsRefused) {
  const std::string path = Photo("half.png", ".png");
  const std::vector<char> whole = Bytes(path);
  std::vector<char> bytes(whole.begin(), whole.begin() + whole.size() / 2);
  Write(path, bytes);
  std::string why = Refusal(path);
  EXPECT_NE(why.find("image '" + path + "': truncated PNG"), std::string::npos) << why;
  EXPECT_NE(why.find("inside chunk 'IDAT'"), std::string::npos) << why;

  bytes = whole;
  bytes[whole.size() / 2] ^= 0x55;  // a flipped byte in the image data
  Write(path, bytes);
  why = Refusal(path);
  EXPECT_NE(why.find("image '" + path + "': corrupt PNG: CRC error in chunk 'IDAT'"),
            std::string::npos)
      << why;
}

TEST_F(ImageFileTest, PngNamedJpgIsReadAsPng) {
  const std::string path = Photo("really_a_png.jpg", ".png");
  const ImageHeader h = ReadImageHeader(path);
  EXPECT_EQ(h.format, "png");
  EXPECT_EQ(FormatNote(path, h),
            "image '" + path + "': the content is PNG, not what the name says; read as PNG");
  const cv::Mat image = ReadImageChecked(path, cv::IMREAD_COLOR);
  EXPECT_EQ(image.size(), cv::Size(320, 240));
}

TEST_F(ImageFileTest, EmptyMissingAndNonImageFilesAreNamed) {
  const std::string empty = Path("empty.jpg");
  Write(empty, {});
  EXPECT_EQ(Refusal(empty), "image '" + empty + "': empty file (0 bytes)");
  const std::string missing = Path("missing.jpg");
  EXPECT_EQ(Refusal(missing), "image '" + missing + "': no such file");
  EXPECT_EQ(Refusal(dir_.string()), "image '" + dir_.string() + "': is a folder, not a file");
  const std::string text = Path("notes.jpg");
  std::ofstream(text) << "not a photo\n";
  std::string why = Refusal(text);
  EXPECT_NE(why.find("image '" + text + "': not an image format this program reads"),
            std::string::npos)
      << why;
  EXPECT_NE(why.find("looks like text"), std::string::npos) << why;
  const std::string gif = Path("anim.png");
  std::ofstream(gif) << "GIF89a\x01\x00\x01\x00";
  why = Refusal(gif);
  EXPECT_NE(why.find("looks like a GIF image"), std::string::npos) << why;
}

// Peak resident memory of this process [kB].
long PeakKb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss;
}

TEST_F(ImageFileTest, ForgedHeaderOf20000x20000IsRefusedBeforeDecoding) {
  // The JPEG frame header (SOF0, FF C0 len prec H H W W) and the PNG IHDR
  // (width and height at bytes 16 and 20) of small files edited to claim
  // 20000 x 20000 px: 400 MP, 1.2 GB as 8-bit BGR.
  const std::string jpg = Photo("forged.jpg", ".jpg");
  std::vector<char> bytes = Bytes(jpg);
  size_t sof = 2;
  while (sof + 1 < bytes.size() &&
         !(uint8_t(bytes[sof]) == 0xFF && uint8_t(bytes[sof + 1]) == 0xC0))
    ++sof;
  ASSERT_LT(sof + 9, bytes.size());
  for (size_t k : {sof + 5, sof + 7}) {
    bytes[k] = char(20000 >> 8);
    bytes[k + 1] = char(20000 & 0xFF);
  }
  Write(jpg, bytes);
  const std::string png = Photo("forged.png", ".png");
  bytes = Bytes(png);
  for (size_t k : {16, 20}) {
    bytes[k] = bytes[k + 1] = 0;
    bytes[k + 2] = char(20000 >> 8);
    bytes[k + 3] = char(20000 & 0xFF);
  }
  Write(png, bytes);  // the IHDR CRC is now wrong too: the size is refused first

  const long peak_before = PeakKb();
  const auto start = std::chrono::steady_clock::now();
  const std::string why_jpg = Refusal(jpg), why_png = Refusal(png);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(why_jpg, "image '" + jpg +
                         "': the JPEG header claims 20000 x 20000 px (400.0 MP), more than "
                         "max_megapixels 100; refused before decoding");
  EXPECT_EQ(why_png, "image '" + png +
                         "': the PNG header claims 20000 x 20000 px (400.0 MP), more than "
                         "max_megapixels 100; refused before decoding");
  EXPECT_LT(seconds, 0.5);
  EXPECT_LT(PeakKb() - peak_before, 16 * 1024) << "kB more at the peak";

  // The header itself is read right: a larger budget accepts it.
  ImageFileOptions big;
  big.max_megapixels = 500;
  const ImageHeader h = ReadImageHeader(jpg, big);
  EXPECT_EQ(h.width, 20000);
  EXPECT_EQ(h.height, 20000);
}

TEST_F(ImageFileTest, SixteenBitPng) {
  cv::Mat depth(48, 64, CV_16UC1);
  for (int r = 0; r < depth.rows; ++r)
    for (int c = 0; c < depth.cols; ++c)
      depth.at<uint16_t>(r, c) = static_cast<uint16_t>(1000 * r + c);
  const std::string path = Path("depth.png");
  ASSERT_TRUE(cv::imwrite(path, depth));
  const ImageHeader h = ReadImageHeader(path);
  EXPECT_EQ(h.format, "png");
  EXPECT_EQ(h.bit_depth, 16);
  EXPECT_EQ(h.channels, 1);
  const cv::Mat read = ReadImageChecked(path, cv::IMREAD_UNCHANGED);
  ASSERT_EQ(read.type(), CV_16UC1);
  EXPECT_EQ(read.at<uint16_t>(47, 63), 47063);
}

TEST_F(ImageFileTest, PgmAndTiffHeaders) {
  cv::Mat gray(30, 40, CV_8UC1, cv::Scalar(7));
  ASSERT_TRUE(cv::imwrite(Path("a.pgm"), gray));
  ASSERT_TRUE(cv::imwrite(Path("a.tif"), gray));
  for (const char* name : {"a.pgm", "a.tif"}) {
    const ImageHeader h = ReadImageHeader(Path(name));
    EXPECT_EQ(h.width, 40) << name;
    EXPECT_EQ(h.height, 30) << name;
    EXPECT_EQ(h.channels, 1) << name;
    EXPECT_EQ(h.bit_depth, 8) << name;
    EXPECT_EQ(ReadImageChecked(Path(name), cv::IMREAD_UNCHANGED).at<uint8_t>(29, 39), 7) << name;
  }
  std::vector<char> bytes = Bytes(Path("a.pgm"));
  bytes.resize(bytes.size() - 100);
  Write(Path("a.pgm"), bytes);
  const std::string why = Refusal(Path("a.pgm"));
  EXPECT_NE(why.find("truncated PGM/PPM"), std::string::npos) << why;
}

// Every photo of the test data (real cameras: JPEG with EXIF thumbnails,
// TIFF, PNG) passes the checks and has the header's size.
TEST_F(ImageFileTest, RealPhotosOfTheTestDataPass) {
  int n = 0;
  for (const auto& e : fs::recursive_directory_iterator(SM_TEST_DATA_DIR)) {
    std::string ext = e.path().extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".jpg" && ext != ".png" && ext != ".tif") continue;
    const std::string path = e.path().string();
    const ImageHeader h = ReadImageHeader(path);
    cv::Mat image;
    ASSERT_NO_THROW(image = ReadImageChecked(path, cv::IMREAD_UNCHANGED)) << path;
    EXPECT_EQ(image.cols, h.width) << path;
    EXPECT_EQ(image.rows, h.height) << path;
    ++n;
  }
  EXPECT_GE(n, 15);
}

TEST(ImageFileOptionsCheck, MaxMegapixelsMustBePositive) {
  ImageFileOptions o;
  o.max_megapixels = 0;
  try {
    o.Check();
    FAIL() << "accepted max_megapixels 0";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'max_megapixels' must be > 0"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
