// camera_capture's publishing path (FramePublisher, the code the nodelet runs)
// on a folder of JPEGs written by the test with exiv2 EXIF tags, without a ROS
// master: messages, stamps, encodings, camera_info, NavSatFix, position prior,
// epoch markers, and a truncated JPEG skipped with a message and counted.
#include <cmath>
#include <fstream>

#include <gtest/gtest.h>

#include "../core/capture/test_images.h"
#include "capture_test_util.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/target_file.h"
#include "slope_monitor/ros/capture_conversions.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace {

using capture_test::ExifTags;

constexpr double kMay1st10h = 1714557600.0;  // 2024-05-01 10:00:00 UTC
constexpr double kOriginLat = 35.0, kOriginLon = 139.0, kOriginH = 100.0;

using capture_test::Recorded;

ros_adapters::CaptureOutputs Outputs(Recorded* r) { return capture_test::RecordInto(r); }

// Three photos of one flight (the second one 10 m north, 50 m up), a truncated
// photo between them, and a fourth photo 2 h later (a second epoch).
class PublisherFixture : public ::testing::Test {
 protected:
  void SetUp() override {
    Photo("img_001.jpg", 3, "10:00:00", "0", kOriginLat, kOriginLon, kOriginH + 50.0);
    // 10 m north: dlat = 10 / M, M the meridian radius of curvature at 35 deg.
    const double north_deg = ToDeg(10.0 / MeridianRadius(kOriginLat));
    Photo("img_002.jpg", 3, "10:00:02", "5", kOriginLat + north_deg, kOriginLon, kOriginH + 50.0);
    Photo("img_003.jpg", 1, "10:00:04", "", kOriginLat, kOriginLon, kOriginH + 50.0);
    Photo("img_004.jpg", 3, "12:00:00", "", kOriginLat, kOriginLon, kOriginH);
    capture_test::WriteJpeg(dir_.File("full.jpeg"), capture_test::TexturedImage(80, 60, 3, 7),
                            Tags("10:00:03", "", kOriginLat, kOriginLon, kOriginH));
    capture_test::WriteTruncatedCopy(dir_.File("full.jpeg"), dir_.File("img_cut.jpg"), 0.5);
    std::filesystem::remove(dir_.File("full.jpeg"));
  }
  static double ToDeg(double rad) { return rad * 180.0 / M_PI; }
  static double MeridianRadius(double lat_deg) {
    const double e2 = capture::kWgs84F * (2 - capture::kWgs84F);
    const double s = std::sin(lat_deg * M_PI / 180.0);
    return capture::kWgs84A * (1 - e2) / std::pow(1 - e2 * s * s, 1.5);
  }
  static ExifTags Tags(const std::string& hms, const std::string& subsec, double lat, double lon,
                       double alt) {
    return capture_test::UavPhotoTags("S1", hms, subsec, lat, lon, alt);
  }
  void Photo(const std::string& name, int channels, const std::string& hms,
             const std::string& subsec, double lat, double lon, double alt) {
    capture_test::WriteJpeg(dir_.File(name), capture_test::TexturedImage(80, 60, channels, 1),
                            Tags(hms, subsec, lat, lon, alt));
  }

  ros_adapters::FramePublisherOptions Options() const {
    ros_adapters::FramePublisherOptions o;
    o.frame_id = "uav_optical";
    o.source_name = "/uav/camera";
    o.has_site_origin = true;
    o.site_origin = {kOriginLat, kOriginLon, kOriginH};
    o.gnss.sigma_horizontal = 2.0;
    o.gnss.sigma_vertical = 3.0;
    o.pixel_size = 0.1;  // nominal camera_info from EXIF: fx = 8.8 / 0.1 = 88 px
    return o;
  }

  capture_test::TempDir dir_{"publisher"};
};

TEST_F(PublisherFixture, FolderThroughThePublishingPath) {
  Recorded r;
  ros_adapters::FramePublisher publisher(Options(), Outputs(&r));
  capture::FolderSourceOptions fo;
  fo.folder = dir_.path();
  capture::FolderSource source(fo);
  capture::EpochOptions eo;
  eo.gap = 600.0;
  capture::EpochTracker tracker(eo);
  int steps = 0;
  while (publisher.Step(&source, &tracker, true) ==
         ros_adapters::FramePublisher::StepResult::kPublished)
    ++steps;
  EXPECT_EQ(steps, 4);
  EXPECT_EQ(publisher.published(), 4u);

  // Epochs: start before the first image, end right after the last of each.
  EXPECT_EQ(r.order, (std::vector<std::string>{"S0", "I", "I", "I", "E0", "S1", "I", "E1"}));
  ASSERT_EQ(r.epochs.size(), 4u);
  EXPECT_EQ(r.epochs[1].count, 3u);
  EXPECT_EQ(r.epochs[3].count, 1u);
  EXPECT_EQ(r.epochs[0].source, "/uav/camera");
  EXPECT_DOUBLE_EQ(r.epochs[0].header.stamp.toSec(), kMay1st10h);
  EXPECT_NEAR(r.epochs[1].header.stamp.toSec(), kMay1st10h + 4.0, 1e-6);

  // Images: stamps from EXIF (ros::Time has ns resolution), encodings, frame id, content.
  ASSERT_EQ(r.images.size(), 4u);
  const std::vector<double> stamps = {kMay1st10h, kMay1st10h + 2.5, kMay1st10h + 4.0,
                                      kMay1st10h + 7200.0};
  const std::vector<std::string> encodings = {"bgr8", "bgr8", "mono8", "bgr8"};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(r.images[i]->header.stamp.toSec(), stamps[i], 1e-6) << i;
    EXPECT_EQ(r.images[i]->header.frame_id, "uav_optical");
    EXPECT_EQ(r.images[i]->encoding, encodings[i]);
    EXPECT_EQ(r.images[i]->width, 80u);
    EXPECT_EQ(r.images[i]->height, 60u);
    EXPECT_EQ(r.images[i]->step, 80u * (encodings[i] == "mono8" ? 1 : 3));
    EXPECT_EQ(r.images[i]->data.size(), r.images[i]->step * 60u);
    // camera_info: same header, nominal from the EXIF focal length.
    EXPECT_EQ(r.infos[i]->header.stamp, r.images[i]->header.stamp);
    EXPECT_EQ(r.infos[i]->header.frame_id, "uav_optical");
    EXPECT_EQ(r.infos[i]->width, 80u);
    EXPECT_NEAR(r.infos[i]->K[0], 88.0, 1e-9);
    EXPECT_NEAR(r.infos[i]->K[4], 88.0, 1e-9);
    EXPECT_NEAR(r.infos[i]->K[2], 39.5, 1e-12);
    EXPECT_NEAR(r.infos[i]->K[5], 29.5, 1e-12);
    EXPECT_NEAR(r.infos[i]->P[0], 88.0, 1e-9);
    EXPECT_EQ(r.infos[i]->distortion_model, "plumb_bob");
  }
  // Pixel (row 10, col 20) of the first image equals the decoded file.
  const cv::Mat decoded = cv::imread(dir_.File("img_001.jpg"), cv::IMREAD_COLOR);
  const size_t at = 10 * r.images[0]->step + 20 * 3;
  EXPECT_EQ(r.images[0]->data[at], decoded.at<cv::Vec3b>(10, 20)[0]);
  EXPECT_EQ(r.images[0]->data[at + 2], decoded.at<cv::Vec3b>(10, 20)[2]);

  // NavSatFix: EXIF position, same header, covariance from the sigmas.
  ASSERT_EQ(r.fixes.size(), 4u);
  EXPECT_NEAR(r.fixes[0].latitude, kOriginLat, 1e-9);
  EXPECT_NEAR(r.fixes[0].longitude, kOriginLon, 1e-9);
  EXPECT_NEAR(r.fixes[0].altitude, kOriginH + 50.0, 1e-9);
  EXPECT_EQ(r.fixes[0].header.stamp, r.images[0]->header.stamp);
  EXPECT_EQ(r.fixes[0].status.status, sensor_msgs::NavSatStatus::STATUS_FIX);
  EXPECT_DOUBLE_EQ(r.fixes[0].position_covariance[0], 4.0);
  EXPECT_DOUBLE_EQ(r.fixes[0].position_covariance[4], 4.0);
  EXPECT_DOUBLE_EQ(r.fixes[0].position_covariance[8], 9.0);
  EXPECT_EQ(r.fixes[0].position_covariance_type,
            sensor_msgs::NavSatFix::COVARIANCE_TYPE_APPROXIMATED);

  // Position priors in site: (0, 0, 50), (0, 10, 50 - 10^2 / (2 R)) within the
  // 1e-4 arc-second EXIF rounding (3 mm), (0, 0, 50), (0, 0, 0).
  ASSERT_EQ(r.priors.size(), 4u);
  EXPECT_EQ(r.priors[0].header.frame_id, "site");
  EXPECT_NEAR(r.priors[0].pose.pose.position.x, 0.0, 3e-3);
  EXPECT_NEAR(r.priors[0].pose.pose.position.y, 0.0, 3e-3);
  EXPECT_NEAR(r.priors[0].pose.pose.position.z, 50.0, 1e-6);
  EXPECT_NEAR(r.priors[1].pose.pose.position.x, 0.0, 3e-3);
  EXPECT_NEAR(r.priors[1].pose.pose.position.y, 10.0, 3e-3);
  EXPECT_NEAR(r.priors[1].pose.pose.position.z, 50.0, 1e-4);
  EXPECT_NEAR(r.priors[3].pose.pose.position.z, 0.0, 1e-6);
  EXPECT_NEAR(r.priors[0].pose.covariance[0], 4.0, 1e-9);
  EXPECT_NEAR(r.priors[0].pose.covariance[14], 9.0, 1e-9);
  EXPECT_DOUBLE_EQ(r.priors[0].pose.covariance[35], 1e6);
  EXPECT_DOUBLE_EQ(r.priors[0].pose.pose.orientation.w, 1.0);

  // The truncated photo: skipped, counted, named; the stream went on.
  EXPECT_EQ(publisher.skipped(), 1u);
  EXPECT_EQ(source.skipped_count(), 1u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings[0].find("img_cut.jpg"), std::string::npos) << r.warnings[0];
  EXPECT_NE(r.warnings[0].find("truncated"), std::string::npos) << r.warnings[0];
}

// Without a pixel_size (parameter or site entry) the nominal camera takes the
// photo's own pitch from EXIF FocalPlaneXResolution (as process_flight):
// 10 px/mm = 0.1 mm, fx = 8.8 / 0.1 = 88 px; a photo without it gets an
// uncalibrated camera_info (K = 0).
TEST(CapturePixelSize, FromThePhotosExifWhenNotGiven) {
  capture_test::TempDir dir("publisher_exif_pitch");
  ExifTags tags = capture_test::UavPhotoTags("S1", "10:00:00", "", kOriginLat, kOriginLon, 150.0);
  tags.focal_plane_x_resolution = 10;
  capture_test::WriteJpeg(dir.File("a.jpg"), capture_test::TexturedImage(80, 60, 3, 1), tags);
  tags = capture_test::UavPhotoTags("S1", "10:00:02", "", kOriginLat, kOriginLon, 150.0);
  capture_test::WriteJpeg(dir.File("b.jpg"), capture_test::TexturedImage(80, 60, 3, 2), tags);
  ros_adapters::FramePublisherOptions o;
  o.source_name = "uav";
  const Recorded r = capture_test::PublishFolder(dir.path(), o);
  ASSERT_EQ(r.infos.size(), 2u);
  EXPECT_NEAR(r.infos[0]->K[0], 88.0, 1e-9);
  EXPECT_NEAR(r.infos[0]->K[4], 88.0, 1e-9);
  EXPECT_NEAR(r.infos[0]->K[2], 39.5, 1e-12);
  EXPECT_EQ(r.infos[1]->K[0], 0.0);
  EXPECT_EQ(r.infos[1]->width, 80u);
}

// A shifted_crs site (UTM 31N less (500 000, 0)): the position prior in its
// grid, as geodesy_test's SiteFrameOfAShiftedUtmSite works it out by hand
// (0.001 deg north of the equator on the central meridian: 110.530 m).
TEST(CapturePositionPrior, InTheGridOfAShiftedCrsSite) {
  capture_test::TempDir dir("publisher_utm");
  capture_test::WriteJpeg(dir.File("a.jpg"), capture_test::TexturedImage(80, 60, 3, 1),
                          capture_test::UavPhotoTags("S1", "10:00:00", "", 0.001, 3.0, 100.0));
  ros_adapters::FramePublisherOptions o;
  o.source_name = "uav";
  o.has_site_origin = true;
  SiteCrsOptions utm;
  utm.crs = "EPSG:32631";
  utm.origin = Eigen::Vector3d(500000.0, 0.0, 0.0);
  utm.frame = SiteCrsOptions::Frame::kShiftedCrs;
  o.site_crs = utm;
  const Recorded r = capture_test::PublishFolder(dir.path(), o);
  ASSERT_EQ(r.priors.size(), 1u);
  EXPECT_NEAR(r.priors[0].pose.pose.position.x, 0.0, 3e-3);  // EXIF: 1e-4 arc-second steps
  EXPECT_NEAR(r.priors[0].pose.pose.position.y, 110.574 * 0.9996, 5e-3);
  EXPECT_NEAR(r.priors[0].pose.pose.position.z, 100.0, 1e-6);
}

// A site's gcp list: each photo's picks published just before its image,
// with its header, the camera's name, the ID its name gives and the role the
// site gives; a pick in a photo the folder does not have is named at the end.
TEST_F(PublisherFixture, PicksOfTheGcpListBeforeTheirPhotos) {
  const std::string gcp = dir_.File("gcp_list.txt");
  std::ofstream(gcp) << "EPSG:4979\n"
                     << "139.0001 35.0001 100.0 10.25 20.5 img_002.jpg gcp4\n"
                     << "139.0001 35.0001 100.0 30.0 40.0 img_001.jpg gcp4\n"
                     << "139.0002 35.0002 101.0 50.0 10.0 img_002.jpg gcp7\n"
                     << "139.0002 35.0002 101.0 1.0 2.0 img_999.jpg gcp7\n";
  const SiteCrs site = SiteCrs::LocalEnuAtWgs84(kOriginLat, kOriginLon, kOriginH);
  ros_adapters::FramePublisherOptions o = Options();
  o.picks = ros_adapters::PhotoPicks(gcp, io::LoadGcpTargets(gcp, site, {"gcp7"}));
  o.picks_file = gcp;
  const Recorded r = capture_test::PublishFolder(dir_.path(), o);
  EXPECT_EQ(r.order,
            (std::vector<std::string>{"S0", "P", "I", "P", "I", "I", "E0", "S1", "I", "E1"}));
  ASSERT_EQ(r.picks.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(r.picks[k].header.stamp, r.images[k]->header.stamp);
    EXPECT_EQ(r.picks[k].header.frame_id, "uav_optical");
    EXPECT_EQ(r.picks[k].camera_name, "/uav/camera");
    EXPECT_EQ(r.picks[k].image_width, 80u);
  }
  ASSERT_EQ(r.picks[0].observations.size(), 1u);  // img_001: gcp4
  EXPECT_EQ(r.picks[0].observations[0].id, 4);
  EXPECT_EQ(r.picks[0].observations[0].family, "gcp");
  EXPECT_EQ(r.picks[0].observations[0].role, slope_monitor::TargetObservation::ROLE_CONTROL);
  EXPECT_EQ(r.picks[0].observations[0].x, 30.0);
  ASSERT_EQ(r.picks[1].observations.size(), 2u);  // img_002: gcp4, gcp7 (check)
  EXPECT_EQ(r.picks[1].observations[0].x, 10.25);
  EXPECT_EQ(r.picks[1].observations[0].y, 20.5);
  EXPECT_EQ(r.picks[1].observations[1].id, 7);
  EXPECT_EQ(r.picks[1].observations[1].role, slope_monitor::TargetObservation::ROLE_CHECK);
  EXPECT_EQ(r.picks[1].observations[1].covariance[0], io::kGcpPickSigmaPx * io::kGcpPickSigmaPx);
  EXPECT_EQ(r.picks[1].observations[1].covariance[1], 0.0);
  bool named = false;
  for (const std::string& w : r.warnings)
    named = named || (w.find(gcp + ": photo 'img_999.jpg' was not published") == 0 &&
                      w.find("1 pick(s) left out") != std::string::npos);
  EXPECT_TRUE(named) << ::testing::PrintToString(r.warnings);
}

TEST_F(PublisherFixture, CalibrationFromThePackageParameters) {
  std::array<double, camera::kNumInterior> p{};
  p[camera::kC] = 8.0;
  p[camera::kX0] = 0.2;
  p[camera::kK1] = 1e-3;
  const camera::CameraModel model(camera::Sensor{80, 60, 0.1}, camera::DistortionModel::kRadial, p);
  auto o = Options();
  o.has_camera_info = true;
  o.camera_info = ros_adapters::ToMsg(model.ToCameraInfo());
  Recorded r;
  ros_adapters::FramePublisher publisher(o, Outputs(&r));
  capture::FolderSourceOptions fo;
  fo.folder = dir_.path();
  capture::FolderSource source(fo);
  capture::EpochTracker tracker(capture::EpochOptions{});
  ASSERT_EQ(publisher.Step(&source, &tracker, true),
            ros_adapters::FramePublisher::StepResult::kPublished);
  ASSERT_EQ(r.infos.size(), 1u);
  EXPECT_NEAR(r.infos[0]->K[0], 80.0, 1e-9);          // c / pixel = 8 / 0.1
  EXPECT_NEAR(r.infos[0]->K[2], 39.5 + 2.0, 1e-9);    // x0 = 0.2 mm = 2 px
  EXPECT_NEAR(r.infos[0]->D[0], 1e-3 * 64.0, 1e-12);  // k1 c^2
  // Back to the collinearity parameters: the same model.
  const camera::CameraModel back = ros_adapters::CameraModelFromCameraInfo(*r.infos[0], 0.1);
  for (int i = 0; i < camera::kNumInterior; ++i) EXPECT_NEAR(back.interior()[i], p[i], 1e-12) << i;
  EXPECT_TRUE(r.warnings.empty());

  // A calibration for another image size is reported (once) with the reason.
  o.camera_info.width = 640;
  Recorded r2;
  ros_adapters::FramePublisher wrong(o, Outputs(&r2));
  capture::FolderSource source2(fo);
  wrong.Step(&source2, &tracker, true);
  wrong.Step(&source2, &tracker, true);
  ASSERT_EQ(r2.warnings.size(), 1u);
  EXPECT_NE(r2.warnings[0].find("640x60"), std::string::npos) << r2.warnings[0];
}

TEST(CaptureConversions, NavSatFixWithoutAltitudeAndGeoid) {
  capture::ExifInfo exif;
  exif.has_gps = true;
  exif.gps = {-33.5, 151.25, 0.0};
  std_msgs::Header h;
  h.frame_id = "cam";
  ros_adapters::GnssOptions g;
  sensor_msgs::NavSatFix fix = ros_adapters::ToNavSatFix(exif, g, h);
  EXPECT_TRUE(std::isnan(fix.altitude));
  exif.has_gps_altitude = true;
  exif.gps.height_m = 20.0;
  g.geoid_height = 22.5;
  fix = ros_adapters::ToNavSatFix(exif, g, h);
  EXPECT_DOUBLE_EQ(fix.altitude, 42.5);
  EXPECT_DOUBLE_EQ(fix.latitude, -33.5);
  EXPECT_EQ(fix.header.frame_id, "cam");
}

}  // namespace
}  // namespace slope_monitor
