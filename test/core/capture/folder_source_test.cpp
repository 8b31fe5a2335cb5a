// A folder of JPEGs made by the test (cv::imwrite + exiv2 tags): order by EXIF
// time, stamps, encodings, EXIF fields, file-time fallback, and bad files
// (truncated, garbage) skipped with a message naming the file, without
// stopping the stream.
#include <gtest/gtest.h>

#include "slope_monitor/core/capture/sources.h"
#include "slope_monitor/core/capture/timing.h"
#include "slope_monitor/core/common/error.h"
#include "test_images.h"

namespace slope_monitor {
namespace capture {
namespace {

using capture_test::ExifTags;
using capture_test::kMay1st10h;
using capture_test::TempDir;

ExifTags Tags(const std::string& hms, const std::string& subsec) {
  ExifTags t;
  t.date_time = "2024:05:01 " + hms;
  t.subsec = subsec;
  t.make = "TestMake";
  t.model = "TestModel";
  t.focal_num = 24;
  t.gps = true;
  t.lat_deg = 35.0;
  t.lon_deg = 139.0;
  t.alt_m = 500.0;
  return t;
}

class FolderFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    // Names deliberately not in time order. Two epochs: 10:00:00-10:00:06 and 12:00:00-12:00:02.
    Write("z_first.jpg", 3, Tags("10:00:00", "5"), 0);
    Write("a_second.jpg", 1, Tags("10:00:02", ""), 1);
    Write("m_third.jpg", 3, Tags("10:00:06", "75"), 2);
    Write("b_fourth.jpg", 3, Tags("12:00:00", ""), 3);
    Write("c_fifth.jpg", 1, Tags("12:00:02", "0"), 4);
    // A truncated copy of a valid EXIF JPEG (EXIF intact, image data cut), time 10:00:04.
    const std::string full = dir_.File("full_tmp.jpeg");
    capture_test::WriteJpeg(full, capture_test::TexturedImage(160, 120, 3, 9),
                            Tags("10:00:04", ""));
    capture_test::WriteTruncatedCopy(full, dir_.File("truncated.jpg"), 0.6);
    std::filesystem::remove(full);
    // Not an image at all (no EXIF: file time, set to between the epochs).
    capture_test::WriteText(dir_.File("garbage.jpg"), "not a jpeg");
    capture_test::SetFileTime(dir_.File("garbage.jpg"), kMay1st10h + 3600.0);
    // Ignored: wrong extension.
    capture_test::WriteText(dir_.File("notes.txt"), "field notes");
  }

  void Write(const std::string& name, int channels, const ExifTags& tags, int seed) {
    images_[name] = capture_test::TexturedImage(160, 120, channels, seed, 20 * seed);
    capture_test::WriteJpeg(dir_.File(name), images_[name], tags);
  }

  TempDir dir_{"folder"};
  std::map<std::string, cv::Mat> images_;
};

// A flight's folder: three photos of one camera (p0-p2.jpg, 160x120,
// TestMake TestModel f=24 mm, GNSS) and the odd ones given, taken after them.
struct OddPhoto {
  std::string name;
  int width, height;
  ExifTags tags;
};
FolderSourceOptions FlightFolder(const TempDir& dir, const std::vector<OddPhoto>& odd) {
  for (int i = 0; i < 3; ++i)
    capture_test::WriteJpeg(dir.File("p" + std::to_string(i) + ".jpg"),
                            capture_test::TexturedImage(160, 120, 3, i),
                            Tags("10:00:0" + std::to_string(i), ""));
  for (size_t k = 0; k < odd.size(); ++k)
    capture_test::WriteJpeg(
        dir.File(odd[k].name),
        capture_test::TexturedImage(odd[k].width, odd[k].height, 3, 5 + static_cast<int>(k)),
        odd[k].tags);
  FolderSourceOptions o;
  o.folder = dir.path();
  return o;
}

// A flight's folder with a photo of another size and one without a GNSS
// position: both named and left out at the scan, the rest kept in order.
TEST(FolderSource, LeavesOutPhotosOfAnotherSizeAndWithoutPosition) {
  TempDir dir{"odd_photos"};
  ExifTags no_gps = Tags("10:00:06", "");
  no_gps.gps = false;
  FolderSource source(FlightFolder(
      dir, {{"bigger.jpg", 200, 150, Tags("10:00:05", "")}, {"no_gps.jpg", 160, 120, no_gps}}));
  EXPECT_EQ(source.size(), 3u);
  ASSERT_EQ(source.left_out().size(), 2u);
  EXPECT_NE(source.left_out()[0].name.find("bigger.jpg"), std::string::npos);
  EXPECT_NE(source.left_out()[0].reason.find("200x150 px, not the folder's 160x120 px"),
            std::string::npos)
      << source.left_out()[0].reason;
  EXPECT_NE(source.left_out()[1].name.find("no_gps.jpg"), std::string::npos);
  EXPECT_NE(source.left_out()[1].reason.find("no EXIF GNSS position"), std::string::npos);
  Frame f;
  std::vector<std::string> names;
  while (source.Next(&f)) names.push_back(std::filesystem::path(f.name).filename().string());
  EXPECT_EQ(names, (std::vector<std::string>{"p0.jpg", "p1.jpg", "p2.jpg"}));
}

// Photos of a second camera in the flight's folder (the same size: a second
// drone, or the same one zoomed): named and left out by the rule
// process_flight uses (PhotoCamera: make, model, size, focal length).
TEST(FolderSource, LeavesOutPhotosOfAnotherCamera) {
  TempDir dir{"two_cameras"};
  ExifTags other = Tags("10:00:05", "");
  other.model = "OtherModel";
  ExifTags zoomed = Tags("10:00:06", "");
  zoomed.focal_num = 35;
  FolderSource source(
      FlightFolder(dir, {{"other.jpg", 160, 120, other}, {"zoomed.jpg", 160, 120, zoomed}}));
  EXPECT_EQ(source.size(), 3u);
  ASSERT_EQ(source.left_out().size(), 2u);
  EXPECT_NE(source.left_out()[0].name.find("other.jpg"), std::string::npos);
  EXPECT_EQ(source.left_out()[0].reason,
            "another camera (TestMake OtherModel 160x120 f=24 mm) than the folder's 3 photos "
            "(TestMake TestModel 160x120 f=24 mm)");
  EXPECT_NE(source.left_out()[1].name.find("zoomed.jpg"), std::string::npos);
  EXPECT_NE(source.left_out()[1].reason.find("(TestMake TestModel 160x120 f=35 mm)"),
            std::string::npos)
      << source.left_out()[1].reason;
  // The same key as process_flight's (flight_photos.cc).
  EXPECT_EQ(PhotoCamera::Of(ReadExif(dir.File("p0.jpg")), 160, 120).Describe(),
            "TestMake TestModel 160x120 f=24 mm");
}

TEST_F(FolderFixture, PublishesInExifTimeOrderAndSkipsBadFiles) {
  FolderSourceOptions o;
  o.folder = dir_.path();
  o.clock_offset = -2.0;  // camera clock 2 s fast
  FolderSource source(o);
  EXPECT_EQ(source.size(), 7u);                  // 5 good + truncated + garbage (notes.txt ignored)
  ASSERT_EQ(source.exif_warnings().size(), 1u);  // garbage.jpg: exiv2 cannot read it
  EXPECT_NE(source.exif_warnings()[0].name.find("garbage.jpg"), std::string::npos);

  const std::vector<std::string> expected_names = {"z_first.jpg", "a_second.jpg", "m_third.jpg",
                                                   "b_fourth.jpg", "c_fifth.jpg"};
  const std::vector<double> expected_stamps = {kMay1st10h + 0.5 - 2, kMay1st10h + 2 - 2,
                                               kMay1st10h + 6.75 - 2, kMay1st10h + 7200 - 2,
                                               kMay1st10h + 7202 - 2};
  const std::vector<std::string> expected_enc = {"bgr8", "mono8", "bgr8", "bgr8", "mono8"};
  Frame f;
  size_t n = 0;
  std::vector<std::string> skipped_names;
  while (source.Next(&f)) {
    ASSERT_LT(n, expected_names.size());
    EXPECT_EQ(std::filesystem::path(f.name).filename().string(), expected_names[n]);
    EXPECT_DOUBLE_EQ(f.stamp, expected_stamps[n]) << f.name;
    EXPECT_EQ(f.stamp_source, StampSource::kExif);
    EXPECT_EQ(f.encoding, expected_enc[n]);
    EXPECT_EQ(f.image.cols, 160);
    EXPECT_EQ(f.image.rows, 120);
    EXPECT_EQ(f.exif.make, "TestMake");
    EXPECT_EQ(f.exif.model, "TestModel");
    EXPECT_DOUBLE_EQ(f.exif.focal_length_mm, 24.0);
    EXPECT_NEAR(f.exif.gps.latitude_deg, 35.0, 1e-12);
    EXPECT_NEAR(f.exif.gps.height_m, 500.0, 1e-12);
    // Decoded exactly as OpenCV's own reader does, and it is the image written
    // under that name (JPEG q95 with chroma subsampling of a sharp colour
    // checker: mean error < 10 grey levels; the images differ by >= 20 levels).
    EXPECT_EQ(cv::norm(f.image, cv::imread(f.name, cv::IMREAD_UNCHANGED), cv::NORM_INF), 0.0)
        << f.name;
    EXPECT_LT(capture_test::MeanAbsDiff(f.image, images_[expected_names[n]]), 10.0) << f.name;
    for (const auto& s : source.TakeSkipped()) skipped_names.push_back(s.name + ": " + s.reason);
    ++n;
  }
  for (const auto& s : source.TakeSkipped()) skipped_names.push_back(s.name + ": " + s.reason);
  EXPECT_EQ(n, 5u);
  // Both bad files skipped, counted, and named (the stream went on past them).
  EXPECT_EQ(source.skipped_count(), 2u);
  ASSERT_EQ(skipped_names.size(), 2u);
  EXPECT_NE(skipped_names[0].find("truncated.jpg"), std::string::npos) << skipped_names[0];
  EXPECT_NE(skipped_names[0].find("truncated"), std::string::npos);
  EXPECT_NE(skipped_names[1].find("garbage.jpg"), std::string::npos) << skipped_names[1];
  EXPECT_FALSE(source.PeekNextStamp().has_value());
}

TEST_F(FolderFixture, EpochsFromCaptureGaps) {
  FolderSourceOptions o;
  o.folder = dir_.path();
  FolderSource source(o);
  EpochOptions eo;
  eo.gap = 600.0;
  EpochTracker tracker(eo);
  std::vector<std::string> log;  // "S0", "F", "E0/3"...
  Frame f;
  while (source.Next(&f)) {
    for (const auto& e : tracker.BeforeFrame(f.stamp)) {
      log.push_back(e.end ? "E" + std::to_string(e.epoch) + "/" + std::to_string(e.count)
                          : "S" + std::to_string(e.epoch));
    }
    log.push_back("F");
    for (const auto& e : tracker.AfterFrame(source.PeekNextStamp(), true)) {
      log.push_back("E" + std::to_string(e.epoch) + "/" + std::to_string(e.count));
    }
  }
  if (auto e = tracker.Close())
    log.push_back("E" + std::to_string(e->epoch) + "/" + std::to_string(e->count));
  // Epoch 0: 10:00:00.5, :02, :06.75 (the truncated 10:00:04 file is skipped, and
  // the garbage file at 11:00 (file time) is skipped after epoch 0 ended by look-ahead).
  // Epoch 1: 12:00:00, 12:00:02, ended at the end of the folder.
  const std::vector<std::string> expected = {"S0", "F", "F", "F", "E0/3", "S1", "F", "F", "E1/2"};
  EXPECT_EQ(log, expected);
}

TEST(FolderSource, FileTimeFallbackAndEncodingOption) {
  TempDir dir("folder_ft");
  ASSERT_TRUE(cv::imwrite(dir.File("p2.png"), capture_test::TexturedImage(40, 30, 3, 1)));
  ASSERT_TRUE(cv::imwrite(dir.File("p1.png"), capture_test::TexturedImage(40, 30, 3, 2)));
  capture_test::SetFileTime(dir.File("p2.png"), 1000.25);
  capture_test::SetFileTime(dir.File("p1.png"), 2000.5);
  FolderSourceOptions o;
  o.folder = dir.path();
  o.encoding = "mono8";
  o.clock_offset = 50.0;  // applies to EXIF times only
  FolderSource source(o);
  Frame f;
  ASSERT_TRUE(source.Next(&f));
  EXPECT_EQ(std::filesystem::path(f.name).filename(), "p2.png");
  EXPECT_NEAR(f.stamp, 1000.25, 1e-6);
  EXPECT_EQ(f.stamp_source, StampSource::kFile);
  EXPECT_EQ(f.encoding, "mono8");
  EXPECT_EQ(f.image.type(), CV_8UC1);
  ASSERT_TRUE(source.Next(&f));
  EXPECT_NEAR(f.stamp, 2000.5, 1e-6);
  EXPECT_FALSE(source.Next(&f));
  EXPECT_EQ(source.skipped_count(), 0u);
}

TEST(FolderSource, BadFolderAndOptionsNameTheProblem) {
  FolderSourceOptions o;
  o.folder = "/nonexistent/sm_capture_folder";
  try {
    FolderSource s(o);
    FAIL();
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/sm_capture_folder"), std::string::npos);
  }
  TempDir empty("folder_empty");
  o.folder = empty.path();
  EXPECT_THROW(FolderSource s(o), IoError);
  o.time_source = "gps";
  EXPECT_THROW(o.Check(), ConfigError);
  o.time_source = "exif";
  o.encoding = "rgb8";
  EXPECT_THROW(o.Check(), ConfigError);
}

TEST(JpegStructure, CompleteTruncatedAndNotJpeg) {
  std::vector<unsigned char> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", capture_test::TexturedImage(64, 64, 3, 4), bytes));
  EXPECT_EQ(CheckJpegStructure(bytes), "");
  // Any cut before the EOI is detected.
  for (double fraction : {0.01, 0.1, 0.5, 0.9}) {
    std::vector<unsigned char> cut(bytes.begin(),
                                   bytes.begin() + static_cast<long>(bytes.size() * fraction));
    EXPECT_NE(CheckJpegStructure(cut).find("truncated"), std::string::npos) << fraction;
  }
  std::vector<unsigned char> no_eoi(bytes.begin(), bytes.end() - 2);
  EXPECT_NE(CheckJpegStructure(no_eoi), "");
  // Progressive JPEGs (several scans) are complete too.
  std::vector<unsigned char> prog;
  ASSERT_TRUE(cv::imencode(".jpg", capture_test::TexturedImage(64, 64, 3, 5), prog,
                           {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  EXPECT_EQ(CheckJpegStructure(prog), "");
  const std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', 0, 0};
  EXPECT_NE(CheckJpegStructure(png).find("not a JPEG"), std::string::npos);
}

TEST(JpegStructure, FrameHeaderSizeAndComponents) {
  std::vector<unsigned char> colour, grey;
  ASSERT_TRUE(cv::imencode(".jpg", capture_test::TexturedImage(70, 50, 3, 4), colour));
  ASSERT_TRUE(cv::imencode(".jpg", capture_test::TexturedImage(33, 21, 1, 4), grey,
                           {cv::IMWRITE_JPEG_PROGRESSIVE, 1}));
  JpegFrameInfo c, g;
  EXPECT_EQ(CheckJpegStructure(colour, &c), "");
  EXPECT_EQ(CheckJpegStructure(grey, &g), "");
  EXPECT_EQ(c.width, 70);
  EXPECT_EQ(c.height, 50);
  EXPECT_EQ(c.components, 3);
  EXPECT_EQ(c.precision, 8);
  EXPECT_EQ(g.width, 33);
  EXPECT_EQ(g.height, 21);
  EXPECT_EQ(g.components, 1);
}

// The decode-into-the-caller's-memory path gives the same pixels as a plain
// decode, writes them where the buffer says, and is not used when a
// conversion is asked for.
TEST(DecodeImageFile, IntoCallerBufferSamePixelsNoCopy) {
  capture_test::TempDir dir("buffer");
  const cv::Mat img = capture_test::TexturedImage(96, 64, 3, 2);
  capture_test::WriteJpeg(dir.File("c.jpg"), img, capture_test::ExifTags());
  capture_test::WriteJpeg(dir.File("g.jpg"), capture_test::TexturedImage(40, 30, 1, 2),
                          capture_test::ExifTags());
  std::vector<unsigned char> storage;
  int calls = 0;
  ImageBuffer buffer = [&](int rows, int cols, int type) {
    ++calls;
    storage.assign(static_cast<size_t>(rows) * cols * CV_ELEM_SIZE(type), 0);
    return cv::Mat(rows, cols, type, storage.data());
  };
  std::string enc, plain_enc;
  bool in_buffer = false;
  const cv::Mat got = DecodeImageFile(dir.File("c.jpg"), "auto", &enc, buffer, &in_buffer);
  const cv::Mat plain = DecodeImageFile(dir.File("c.jpg"), "auto", &plain_enc);
  EXPECT_TRUE(in_buffer);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(enc, "bgr8");
  EXPECT_EQ(plain_enc, "bgr8");
  EXPECT_EQ(got.data, storage.data());
  ASSERT_EQ(got.size(), plain.size());
  EXPECT_EQ(cv::norm(got, plain, cv::NORM_INF), 0.0);
  EXPECT_LT(capture_test::MeanAbsDiff(got, img), 12.0);  // JPEG q95 (4:2:0 chroma) of the original

  const cv::Mat grey = DecodeImageFile(dir.File("g.jpg"), "auto", &enc, buffer, &in_buffer);
  EXPECT_TRUE(in_buffer);
  EXPECT_EQ(enc, "mono8");
  EXPECT_EQ(grey.type(), CV_8UC1);
  EXPECT_EQ(grey.data, storage.data());

  // mono8 asked of a colour JPEG: converted in a Mat of its own.
  calls = 0;
  const cv::Mat converted = DecodeImageFile(dir.File("c.jpg"), "mono8", &enc, buffer, &in_buffer);
  EXPECT_FALSE(in_buffer);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(enc, "mono8");
  EXPECT_EQ(converted.type(), CV_8UC1);
}

// FolderSource uses the buffer it is given for each frame.
TEST(FolderSource, DecodesIntoTheImageBuffer) {
  capture_test::TempDir dir("folderbuf");
  capture_test::ExifTags t;
  for (int i = 0; i < 3; ++i) {
    t.date_time = "2024:05:01 10:00:0" + std::to_string(i);
    capture_test::WriteJpeg(dir.File("p" + std::to_string(i) + ".jpg"),
                            capture_test::TexturedImage(48, 32, 3, i), t);
  }
  FolderSourceOptions o;
  o.folder = dir.path();
  FolderSource source(o);
  std::vector<std::vector<unsigned char>> stores;
  source.set_image_buffer([&](int rows, int cols, int type) {
    stores.emplace_back(static_cast<size_t>(rows) * cols * CV_ELEM_SIZE(type));
    return cv::Mat(rows, cols, type, stores.back().data());
  });
  stores.reserve(8);
  Frame f;
  int n = 0;
  while (source.Next(&f)) {
    ASSERT_EQ(stores.size(), static_cast<size_t>(n + 1));
    EXPECT_TRUE(f.in_image_buffer);
    EXPECT_EQ(f.image.data, stores.back().data());
    std::string enc;
    EXPECT_EQ(cv::norm(f.image, DecodeImageFile(f.name, "auto", &enc), cv::NORM_INF), 0.0)
        << f.name;
    EXPECT_EQ(f.name, dir.File("p" + std::to_string(n) + ".jpg"));
    ++n;
  }
  EXPECT_EQ(n, 3);
  source.set_image_buffer({});
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
