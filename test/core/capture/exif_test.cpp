// EXIF reading against tags written by the test with exiv2 itself.
#include "slope_monitor/core/capture/exif.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "test_images.h"

namespace slope_monitor {
namespace capture {
namespace {

using capture_test::ExifTags;
using capture_test::kMay1st10h;
using capture_test::TempDir;

TEST(Exif, ParseDateTime) {
  EXPECT_DOUBLE_EQ(ParseExifDateTime("2024:05:01 10:00:00", "", "t"), kMay1st10h);
  EXPECT_DOUBLE_EQ(ParseExifDateTime("2024:05:01 10:00:00", "25", "t"), kMay1st10h + 0.25);
  EXPECT_DOUBLE_EQ(ParseExifDateTime("2024:05:01 10:00:07", "050", "t"), kMay1st10h + 7.05);
  EXPECT_DOUBLE_EQ(ParseExifDateTime("1970:01:01 00:00:00", "", "t"), 0.0);
  EXPECT_THROW(ParseExifDateTime("2024-05-01 10:00:00", "", "t"), InvalidArgument);
  EXPECT_THROW(ParseExifDateTime("2024:13:01 10:00:00", "", "t"), InvalidArgument);
  EXPECT_THROW(ParseExifDateTime("2024:05:01 10:00:00", "2x", "t"), InvalidArgument);
  try {
    ParseExifDateTime("    :  :     :  :  ", "", "photo.jpg DateTimeOriginal");
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("photo.jpg DateTimeOriginal"), std::string::npos);
  }
  EXPECT_DOUBLE_EQ(ParseExifTimeOffset("+09:00", "o"), 32400.0);
  EXPECT_DOUBLE_EQ(ParseExifTimeOffset("-05:30", "o"), -19800.0);
  EXPECT_THROW(ParseExifTimeOffset("9", "o"), InvalidArgument);
}

TEST(Exif, ReadsTagsWrittenByExiv2) {
  TempDir dir("exif");
  const std::string path = dir.File("a.jpg");
  ExifTags t;
  t.date_time = "2024:05:01 19:00:00";
  t.subsec = "125";
  t.offset = "+09:00";  // local JST: 10:00:00.125 UTC
  t.make = "DJI";
  t.model = "FC6310";
  t.focal_num = 88;
  t.focal_den = 10;
  t.gps = true;
  t.lat_deg = 35.3606;
  t.lon_deg = -138.7274;  // west, to check the ref
  t.alt_m = 1234.5;
  capture_test::WriteJpeg(path, capture_test::TexturedImage(64, 48, 3, 1), t);

  const ExifInfo e = ReadExif(path);
  ASSERT_TRUE(e.has_time);
  EXPECT_TRUE(e.time_zone_applied);
  EXPECT_NEAR(e.time, kMay1st10h + 0.125, 1e-9);
  EXPECT_EQ(e.make, "DJI");
  EXPECT_EQ(e.model, "FC6310");
  EXPECT_DOUBLE_EQ(e.focal_length_mm, 8.8);
  ASSERT_TRUE(e.has_gps);
  ASSERT_TRUE(e.has_gps_altitude);
  // Seconds are written to 1e-4 arc-second: < 1e-8 deg.
  EXPECT_NEAR(e.gps.latitude_deg, 35.3606, 1e-7);
  EXPECT_NEAR(e.gps.longitude_deg, -138.7274, 1e-7);
  EXPECT_NEAR(e.gps.height_m, 1234.5, 1e-9);
}

TEST(Exif, SouthBelowSeaLevelAndNoTimeZone) {
  TempDir dir("exif2");
  const std::string path = dir.File("b.jpg");
  ExifTags t;
  t.date_time = "2024:05:01 10:00:00";
  t.gps = true;
  t.lat_deg = -33.5;
  t.lon_deg = 151.25;
  t.alt_m = -12.25;
  capture_test::WriteJpeg(path, capture_test::TexturedImage(32, 32, 1, 2), t);
  const ExifInfo e = ReadExif(path);
  EXPECT_TRUE(e.has_time);
  EXPECT_FALSE(e.time_zone_applied);
  EXPECT_DOUBLE_EQ(e.time, kMay1st10h);
  EXPECT_NEAR(e.gps.latitude_deg, -33.5, 1e-9);
  EXPECT_NEAR(e.gps.longitude_deg, 151.25, 1e-9);
  EXPECT_NEAR(e.gps.height_m, -12.25, 1e-9);
  EXPECT_TRUE(e.make.empty());
  EXPECT_EQ(e.focal_length_mm, 0.0);
}

TEST(Exif, NoExifIsEmptyAndGarbageNamesTheFile) {
  TempDir dir("exif3");
  const std::string plain = dir.File("plain.jpg");
  ASSERT_TRUE(cv::imwrite(plain, capture_test::TexturedImage(32, 32, 1, 3)));
  const ExifInfo e = ReadExif(plain);
  EXPECT_FALSE(e.has_time);
  EXPECT_FALSE(e.has_gps);

  const std::string junk = dir.File("junk.jpg");
  capture_test::WriteText(junk, "this is not an image");
  try {
    ReadExif(junk);
    FAIL() << "no exception";
  } catch (const IoError& err) {
    EXPECT_NE(std::string(err.what()).find(junk), std::string::npos) << err.what();
  }
}

}  // namespace
}  // namespace capture
}  // namespace slope_monitor
