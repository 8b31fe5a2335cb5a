// Pair planning of a flight (flight::PlanFlightPairs) beyond the exhaustive
// limit, with hand-checkable footprints: photos 20 m apart along one strip,
// 4000 x 3000 px of 0.004 mm behind 10 mm (a footprint of 1.6 x 1.2 m per
// metre of flying height). The flying height comes from the photo's XMP
// (DJI RelativeAltitude) where it has one, else from the option; the XMP tag
// is read back from a JPEG written here with exiv2.
#include <cmath>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>
#pragma GCC diagnostic pop
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/capture/photo_attitude.h"
#include "slope_monitor/core/flight/flight_matching.h"

namespace slope_monitor {
namespace flight {
namespace {

// n photos flown north along one strip, `spacing` m apart, heading 0.
FlightPhotos Strip(int n, double spacing, double xmp_height) {
  FlightPhotos s;
  const double metres_per_deg = 111320.0;
  for (int k = 0; k < n; ++k) {
    FlightPhoto p;
    p.name = "P" + std::to_string(1000 + k) + ".jpg";
    p.width = 4000;
    p.height = 3000;
    p.exif.has_gps = true;
    p.exif.gps.latitude_deg = 35.0 + k * spacing / metres_per_deg;
    p.exif.gps.longitude_deg = 139.0;
    p.exif.focal_length_mm = 10.0;
    p.attitude.has_pixel_size = true;
    p.attitude.pixel_size_mm = 0.004;
    p.attitude.has_yaw = true;
    p.attitude.yaw_deg = 0.0;
    p.attitude.has_height_above_ground = xmp_height > 0.0;
    p.attitude.height_above_ground_m = xmp_height;
    s.photos.push_back(p);
  }
  return s;
}

// Partners of the middle photo.
int PartnersOf(const std::vector<std::pair<int, int>>& pairs, int photo) {
  int n = 0;
  for (const auto& [a, b] : pairs) n += a == photo || b == photo;
  return n;
}

TEST(FlightPairs, UpToTheExhaustiveLimitEveryPairIsTried) {
  const auto pairs = PlanFlightPairs(Strip(12, 20.0, 0.0), FlightMatchingOptions{});
  EXPECT_EQ(pairs.size(), 12u * 11u / 2u);
}

TEST(FlightPairs, BeyondItTheFootprintsAtTheXmpHeightChooseThePartners) {
  FlightMatchingOptions o;  // height_above_ground 150 m unless the XMP says
  ASSERT_EQ(o.footprint.height_above_ground, 150.0);
  // At 150 m the footprint is 180 m along the strip: photos up to 8 apart
  // (160 m) overlap by more than 5 %, 9 apart (180 m) do not.
  const auto at_150 = PlanFlightPairs(Strip(70, 20.0, 0.0), o);
  EXPECT_EQ(PartnersOf(at_150, 35), 2 * 8);
  // At 50 m (XMP): 60 m along: only the next two (40 m apart: 33 % overlap).
  const auto at_50 = PlanFlightPairs(Strip(70, 20.0, 50.0), o);
  EXPECT_EQ(PartnersOf(at_50, 35), 2 * 2);
}

// A small JPEG at `path` with these XMP properties (written by exiv2).
void WriteXmpPhoto(const std::string& path,
                   const std::vector<std::pair<std::string, std::string>>& properties) {
  ASSERT_TRUE(cv::imwrite(path, cv::Mat(30, 40, CV_8UC1, cv::Scalar(90))));
  Exiv2::XmpProperties::registerNs("http://www.dji.com/drone-dji/1.0/", "drone-dji");
  Exiv2::XmpProperties::registerNs("http://www.sensefly.com/xmp/1.0/", "sensefly");
  auto image = Exiv2::ImageFactory::open(path);
  image->readMetadata();
  Exiv2::XmpData xmp;
  for (const auto& [key, value] : properties) xmp[key] = value;
  image->setXmpData(xmp);
  image->writeMetadata();
}

TEST(FlightPairs, TheRelativeAltitudeIsReadFromTheXmp) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "sm_flight_pairs_xmp.jpg").string();
  WriteXmpPhoto(path, {{"Xmp.drone-dji.RelativeAltitude", "+68.20"},
                       {"Xmp.drone-dji.FlightYawDegree", "-12.5"}});
  const capture::PhotoAttitude a = capture::ReadPhotoAttitude(path);
  EXPECT_TRUE(a.has_height_above_ground);
  EXPECT_DOUBLE_EQ(a.height_above_ground_m, 68.2);
  EXPECT_TRUE(a.has_yaw);
  EXPECT_DOUBLE_EQ(a.yaw_deg, -12.5);
  std::filesystem::remove(path);
}

// The older senseFly schema (eMotion, e.g. the real seneca flight of
// OpenDroneMap's data sets: Heading 30.44, PitchAngle -1.40, RollAngle
// -2.65, Height 67.87 m above take-off).
TEST(FlightPairs, TheOlderSenseFlyHeadingAndHeightAreRead) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "sm_flight_pairs_sensefly.jpg").string();
  WriteXmpPhoto(path, {{"Xmp.sensefly.Heading", "30.438629150000001"},
                       {"Xmp.sensefly.PitchAngle", "-1.403483152000000"},
                       {"Xmp.sensefly.RollAngle", "-2.652293205000000"},
                       {"Xmp.sensefly.Height", "67.874511720000001"},
                       // not a height above ground:
                       {"Xmp.sensefly.AltitudeWGS84", "283.824005100000022"}});
  const capture::PhotoAttitude a = capture::ReadPhotoAttitude(path);
  EXPECT_TRUE(a.has_yaw);
  EXPECT_DOUBLE_EQ(a.yaw_deg, 30.438629150000001);
  EXPECT_TRUE(a.has_pitch_roll);
  EXPECT_DOUBLE_EQ(a.pitch_deg, -1.403483152);
  EXPECT_DOUBLE_EQ(a.roll_deg, -2.652293205);
  EXPECT_TRUE(a.has_height_above_ground);
  EXPECT_DOUBLE_EQ(a.height_above_ground_m, 67.874511720000001);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace flight
}  // namespace slope_monitor
