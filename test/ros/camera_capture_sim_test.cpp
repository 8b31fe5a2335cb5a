// camera_capture's publishing path (FramePublisher, the code the nodelet
// runs) on the simulator's images: the tiny site (test/data/sim) is rendered,
// each camera's images are written as JPEGs with EXIF (exposure time, and for
// the UAV the GNSS position it recorded), and the folder is published with
// the simulator's nominal calibration. Checked against the simulator's truth:
// count, stamps, encodings, pixels, camera_info, NavSatFix, position prior,
// epochs.
#include <time.h>

#include <cmath>
#include <map>

#include <gtest/gtest.h>

#include "../core/capture/test_images.h"
#include "capture_test_util.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/sim/survey.h"
#include "slope_monitor/ros/capture_conversions.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace {

using Published = capture_test::Recorded;

// EXIF DateTimeOriginal + SubSecTimeOriginal (ms) of a UTC stamp.
void SetExifTime(double stamp, capture_test::ExifTags* t) {
  const time_t whole = static_cast<time_t>(std::floor(stamp));
  struct tm utc {};
  gmtime_r(&whole, &utc);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y:%m:%d %H:%M:%S", &utc);
  t->date_time = buf;
  std::snprintf(buf, sizeof(buf), "%03d",
                static_cast<int>(std::lround((stamp - std::floor(stamp)) * 1000.0)) % 1000);
  t->subsec = buf;
}

class SimImages : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const sim::SurveyConfig config =
        sim::SurveyConfig::Load(std::string(SM_TEST_DATA_DIR) + "/sim/tiny_site.yaml");
    survey_ = new sim::Survey(sim::SurveyGenerator(config).Generate());
  }
  static void TearDownTestSuite() {
    delete survey_;
    survey_ = nullptr;
  }

  // Writes camera `name`'s images to a folder and publishes it.
  Published Publish(const std::string& name, const capture_test::TempDir& dir) {
    const sim::SurveyTruth& truth = survey_->truth;
    int index = -1;
    for (size_t c = 0; c < truth.cameras.size(); ++c) {
      if (truth.cameras[c].name == name) index = static_cast<int>(c);
    }
    EXPECT_GE(index, 0) << name;
    const sim::CameraTruth& cam = truth.cameras[index];
    const capture::LocalTangentPlane site({truth.origin.x(), truth.origin.y(), truth.origin.z()});
    for (const sim::SurveyImage& img : survey_->images) {
      if (img.camera != index) continue;
      const sim::ImageTruth& t = cam.images[img.image];
      capture_test::ExifTags tags;
      SetExifTime(img.stamp, &tags);
      tags.make = "slope_monitor_sim";
      tags.model = name;
      if (t.gnss) {
        const capture::Geodetic g = site.ToGeodetic(*t.gnss);
        tags.gps = true;
        tags.lat_deg = g.latitude_deg;
        tags.lon_deg = g.longitude_deg;
        tags.alt_m = g.height_m;  // geoid_height 0: the EXIF altitude is taken as ellipsoidal
      }
      char file[64];
      std::snprintf(file, sizeof(file), "%s_%03d.jpg", name.c_str(), img.image);
      capture_test::WriteJpeg(dir.File(file), img.pixels, tags);
    }
    ros_adapters::FramePublisherOptions o;
    o.frame_id = name + "_optical";
    o.source_name = "/" + name + "/camera";
    o.has_camera_info = true;
    o.camera_info = ros_adapters::ToMsg(cam.nominal.ToCameraInfo());
    o.pixel_size = cam.nominal.sensor().pixel_size;
    o.has_site_origin = true;
    o.site_origin = {truth.origin.x(), truth.origin.y(), truth.origin.z()};
    o.gnss.sigma_horizontal = 0.03;
    o.gnss.sigma_vertical = 0.05;
    // Epochs by the default 600 s gap: they are an hour apart, images within
    // one a few seconds.
    return capture_test::PublishFolder(dir.path(), o);
  }

  // Checks what was published against camera `name`'s truth.
  void Check(const std::string& name, const Published& p) {
    const sim::SurveyTruth& truth = survey_->truth;
    const sim::CameraTruth* cam = truth.FindCamera(name);
    ASSERT_NE(cam, nullptr);
    std::vector<const sim::SurveyImage*> images;
    for (const sim::SurveyImage& img : survey_->images) {
      if (truth.cameras[img.camera].name == name) images.push_back(&img);
    }
    ASSERT_FALSE(images.empty());
    ASSERT_EQ(p.images.size(), images.size()) << name;
    EXPECT_TRUE(p.warnings.empty()) << p.warnings.front();
    const sensor_msgs::CameraInfo expected_info = ros_adapters::ToMsg(cam->nominal.ToCameraInfo());
    const capture::LocalTangentPlane site({truth.origin.x(), truth.origin.y(), truth.origin.z()});
    std::map<int, uint32_t> per_epoch;
    size_t fix = 0;
    for (size_t i = 0; i < images.size(); ++i) {
      const sim::SurveyImage& img = *images[i];
      const sim::ImageTruth& t = cam->images[img.image];
      ++per_epoch[img.epoch];
      const sensor_msgs::Image& m = *p.images[i];
      EXPECT_NEAR(m.header.stamp.toSec(), t.stamp, 1e-3)
          << name << " image " << i;  // EXIF keeps ms
      EXPECT_EQ(m.encoding, cam->encoding);
      ASSERT_EQ(m.width, static_cast<uint32_t>(img.pixels.cols));
      ASSERT_EQ(m.height, static_cast<uint32_t>(img.pixels.rows));
      const cv::Mat got(img.pixels.rows, img.pixels.cols, img.pixels.type(),
                        const_cast<uint8_t*>(m.data.data()));
      EXPECT_LT(capture_test::MeanAbsDiff(got, img.pixels), 4.0)
          << name << " image " << i << " (JPEG q95)";
      const sensor_msgs::CameraInfo& info = *p.infos[i];
      EXPECT_EQ(info.header.stamp, m.header.stamp);
      EXPECT_EQ(info.width, expected_info.width);
      EXPECT_EQ(info.height, expected_info.height);
      for (int k = 0; k < 9; ++k)
        EXPECT_DOUBLE_EQ(info.K[k], expected_info.K[k]) << "K[" << k << "]";
      ASSERT_EQ(info.D.size(), expected_info.D.size());
      for (size_t k = 0; k < info.D.size(); ++k) EXPECT_DOUBLE_EQ(info.D[k], expected_info.D[k]);
      if (t.gnss) {
        ASSERT_LT(fix, p.fixes.size());
        const sensor_msgs::NavSatFix& f = p.fixes[fix];
        EXPECT_EQ(f.header.stamp, m.header.stamp);
        const Eigen::Vector3d x = site.ToSite({f.latitude, f.longitude, f.altitude});
        // EXIF keeps 1e-4 arc seconds (3 mm) and mm altitudes.
        EXPECT_LT((x - *t.gnss).norm(), 0.01)
            << name << " image " << i << ": " << x.transpose() << " vs " << t.gnss->transpose();
        const auto& prior = p.priors[fix].pose.pose.position;
        EXPECT_LT((Eigen::Vector3d(prior.x, prior.y, prior.z) - *t.gnss).norm(), 0.01)
            << name << " image " << i;
        EXPECT_NEAR(p.priors[fix].pose.covariance[0], 0.03 * 0.03, 1e-9);
        ++fix;
      }
    }
    EXPECT_EQ(p.fixes.size(), fix);
    EXPECT_EQ(p.priors.size(), fix);
    // One epoch (start + end with its image count) per simulated epoch with images.
    ASSERT_EQ(p.epochs.size(), 2 * per_epoch.size()) << name;
    size_t k = 0;
    for (const auto& [epoch, count] : per_epoch) {
      EXPECT_FALSE(p.epochs[k].end);
      EXPECT_TRUE(p.epochs[k + 1].end);
      EXPECT_EQ(p.epochs[k + 1].count, count) << name << " epoch " << epoch;
      k += 2;
    }
  }

  static sim::Survey* survey_;
};

sim::Survey* SimImages::survey_ = nullptr;

TEST_F(SimImages, UavPhotosWithGnss) {
  capture_test::TempDir dir("sim_uav");
  const Published p = Publish("uav", dir);
  Check("uav", p);
  EXPECT_FALSE(p.fixes.empty()) << "the simulated UAV records GNSS";
}

TEST_F(SimImages, FixedCameraMono) {
  capture_test::TempDir dir("sim_fixed");
  const Published p = Publish("fixed_cam_1", dir);
  Check("fixed_cam_1", p);
  EXPECT_TRUE(p.fixes.empty());
}

}  // namespace
}  // namespace slope_monitor
