// dense::DrawDisplacementField checked by hand: a nadir camera 100 m above a
// flat ground (c = 50 mm, 10 um pixels: 2 cm per pixel), a grey photo and a
// few probes with known image motions. The arrows start where each probe's
// ground point projects, point along its motion times the exaggeration
// (longest usable arrow 80 px), take the colour of their flag; elsewhere the
// photo is unchanged.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/field_picture.h"

namespace slope_monitor {
namespace dense {
namespace {

constexpr int kPhotoWidth = 640, kPhotoHeight = 480;
constexpr double kAltitude = 100.0;  // [m]
constexpr unsigned char kGrey = 100;

camera::CameraModel Camera() {
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 50.0;  // [mm]
  return camera::CameraModel(camera::Sensor{kPhotoWidth, kPhotoHeight, 0.01},
                             camera::DistortionModel::kNone, interior);
}

camera::ExteriorOrientation Nadir() {
  camera::ExteriorOrientation e;
  e.position = Eigen::Vector3d(0, 0, kAltitude);
  return e;
}

// A probe whose ground point is seen at `tail` and whose match moved by `motion` px.
FieldPoint Probe(const Eigen::Vector2d& tail, const Eigen::Vector2d& motion,
                 const std::string& flag = "", bool stable = false) {
  const camera::Ray ray = Camera().ImageToRay(Nadir(), tail);
  const Eigen::Vector3d d = ray.direction.normalized();
  FieldPoint p;
  p.xa = tail;
  p.x_ref = ray.origin - (ray.origin.z() / d.z()) * d;  // on z = 0
  p.xb = tail + motion;
  p.flag = flag;
  p.stable = stable;
  return p;
}

cv::Vec3b At(const cv::Mat& m, const Eigen::Vector2d& x) {
  return m.at<cv::Vec3b>(cvRound(x.y()), cvRound(x.x()));
}

TEST(FieldPicture, ArrowsWhereTheFieldSaysInTheirFlagsColours) {
  DisplacementField f;
  f.points = {Probe({200, 300}, {4, 0}),                    // usable, the longest: 4 px
              Probe({400, 300}, {0, 2}),                    // usable
              Probe({300, 400}, {0, -3}, "grazing"),        // drawn, orange
              Probe({500, 150}, {-2, 0}, "line_of_sight"),  // drawn, magenta
              Probe({550, 400}, {0.1, 0}, "", true),        // stable check, cyan
              Probe({100, 420}, {0, 0}, "lsc_textureless")};
  const cv::Mat photo(kPhotoHeight, kPhotoWidth, CV_8UC1, cv::Scalar(kGrey));
  FieldPictureSummary s;
  const cv::Mat out = DrawDisplacementField(photo, f, Camera(), Nadir(), FieldPictureOptions(), &s);
  ASSERT_EQ(out.size(), photo.size());
  ASSERT_EQ(out.type(), CV_8UC3);
  // 80 px for the 4 px motion; the bar stands for 2 px (1-2-5 below 4), 2 cm/px at
  // 100 m (the probes' median range is 100.04 m: 0.04 % more).
  EXPECT_DOUBLE_EQ(s.exaggeration, 20.0);
  EXPECT_DOUBLE_EQ(s.bar_motion_px, 2.0);
  EXPECT_NEAR(s.metres_per_px, 0.02, 1e-5);
  EXPECT_NEAR(s.bar_metres, 0.04, 2e-5);
  EXPECT_EQ(s.arrows, 5);
  EXPECT_EQ(s.dots, 1);

  // Along each arrow (a quarter and half of its drawn length) the colour of its kind.
  auto along = [&](const FieldPoint& p, double k) {
    return p.xa + k * s.exaggeration * (p.xb - p.xa);
  };
  for (double k : {0.25, 0.5}) {
    for (int i : {0, 1}) {  // green
      const cv::Vec3b c = At(out, along(f.points[i], k));
      EXPECT_GT(c[1], c[0] + 60) << "usable probe " << i;
      EXPECT_GT(c[1], c[2] + 60) << "usable probe " << i;
    }
    const cv::Vec3b grazing = At(out, along(f.points[2], k));  // orange: R > G > B
    EXPECT_GT(grazing[2], grazing[1] + 40);
    EXPECT_GT(grazing[1], grazing[0] + 20);
    const cv::Vec3b los = At(out, along(f.points[3], k));  // magenta: R, B > G
    EXPECT_GT(los[2], los[1] + 60);
    EXPECT_GT(los[0], los[1] + 60);
  }
  // The stable probe's 2 px arrow: its tail is cyan (B, G > R).
  const cv::Vec3b stable = At(out, f.points[4].xa);
  EXPECT_GT(stable[0], stable[2] + 60);
  EXPECT_GT(stable[1], stable[2] + 60);
  // The probe without a match: a red dot at its reference position.
  const cv::Vec3b dot = At(out, f.points[5].xa);
  EXPECT_GT(dot[2], dot[1] + 60);
  // Beyond the heads and off the legend the photo is unchanged.
  for (const Eigen::Vector2d& x : {Eigen::Vector2d(200, 330), Eigen::Vector2d(620, 470),
                                   Eigen::Vector2d(400, 390), Eigen::Vector2d(450, 300)})
    EXPECT_EQ(At(out, x), cv::Vec3b(kGrey, kGrey, kGrey)) << x.transpose();
}

TEST(FieldPicture, BadPhotoAndFileName) {
  DisplacementField f;
  const cv::Mat small(240, 320, CV_8UC1, cv::Scalar(kGrey));
  try {
    DrawDisplacementField(small, f, Camera(), Nadir(), FieldPictureOptions());
    FAIL() << "a photo of the wrong size was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("the photo is 320x240x1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("the camera 640x480"), std::string::npos) << e.what();
  }
  FieldPictureOptions o;
  o.longest_arrow_px = 0;
  EXPECT_THROW(o.Check(), InvalidArgument);
  EXPECT_EQ(FieldPictureFileName("north_cam", 2), "north_cam_field_e02.png");
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
