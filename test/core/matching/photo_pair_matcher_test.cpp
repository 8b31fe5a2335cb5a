// Tie points between real UAV photos (photo_pair_matcher.h), on downscaled
// copies of the snowpeak survey (test/data/uav_real_snowpeak, README.md
// there: 1152 x 864 = 1/4 and 2304 x 1728 = 1/2 of the 4608 x 3456 originals).
//  * a real photo against a copy of itself rotated by 160 deg, scaled by 1.14,
//    shifted and with its brightness changed (gain 0.8, offset +15): every
//    tie point against that known map (the refinement at full resolution
//    runs: the copy is 2304 px wide, larger than the 1200 px reduced level);
//  * the real pairs that overlap: IMG_2213/IMG_2244 across a turn (headings
//    307.6 / 146.9 deg), IMG_2212/IMG_2244 on strips flown the same way,
//    IMG_2171/IMG_2186 on neighbouring strips flown in opposite directions
//    and IMG_2212/IMG_2213 either side of a turn (the last two share a narrow
//    band at the photos' edge; found since SIFT's contrast threshold is 0.01):
//    count, epipolar RMS, the rotation of the relation against the heading
//    difference of the autopilot (geoinfo.txt, independent of the images),
//    and the count against OpenCV SIFT + ratio test + RANSAC fundamental
//    matrix run here on the same images;
//  * a pair 540 m apart (no overlap): no tie points;
//  * footprint pair selection on hand-checkable rectangles.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/LU>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/photo_pair_matcher.h"
#include "slope_monitor/core/matching/sequence_matcher.h"

namespace slope_monitor {
namespace matching {
namespace {

const std::string kDir = std::string(SM_TEST_DATA_DIR) + "/uav_real_snowpeak/";

cv::Mat Load(const std::string& name) {
  const cv::Mat image = cv::imread(kDir + name, cv::IMREAD_COLOR);
  EXPECT_FALSE(image.empty()) << kDir + name;
  return image;
}

// Heading [deg] per file name of geoinfo.txt.
std::map<std::string, double> Headings() {
  std::ifstream in(kDir + "geoinfo.txt");
  std::map<std::string, double> h;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("IMG_", 0) != 0) continue;
    std::istringstream f(line);
    std::string name;
    double lat, lon, amsl, wgs, heading;
    f >> name >> lat >> lon >> amsl >> wgs >> heading;
    h[name] = heading;
  }
  return h;
}

double Wrap(double deg) { return std::remainder(deg, 360.0); }

// OpenCV SIFT (all features), FLANN, ratio 0.8, RANSAC fundamental matrix
// (1 px): its inliers.
int SiftInliers(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat ga, gb;
  cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
  cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);
  const auto sift = cv::SIFT::create();
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  sift->detectAndCompute(ga, cv::noArray(), ka, da);
  sift->detectAndCompute(gb, cv::noArray(), kb, db);
  std::vector<std::vector<cv::DMatch>> knn;
  cv::FlannBasedMatcher().knnMatch(da, db, knn, 2);
  std::vector<cv::Point2f> pa, pb;
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
      pa.push_back(ka[m[0].queryIdx].pt);
      pb.push_back(kb[m[0].trainIdx].pt);
    }
  }
  std::vector<unsigned char> inliers;
  EpipolarRms(pa, pb, 1.0, &inliers);
  int n = 0;
  for (unsigned char c : inliers) n += c;
  return n;
}

TEST(PhotoPairMatcher, RotatedScaledRelitCopyOfARealPhotoAgainstItsMap) {
  const cv::Mat a = Load("IMG_2212_2304.jpg");
  ASSERT_FALSE(a.empty());
  // b(x) = a(T^-1 x): T rotates by 160 deg about a's centre, scales by 1.14,
  // shifts by (60, -40) px.
  const double angle = 160.0, scale = 1.14;
  const cv::Point2f centre(0.5f * (a.cols - 1), 0.5f * (a.rows - 1));
  cv::Mat t = cv::getRotationMatrix2D(centre, -angle,
                                      scale);  // OpenCV: positive = counter-clockwise on screen
  t.at<double>(0, 2) += 60.0;
  t.at<double>(1, 2) -= 40.0;
  cv::Mat b;
  cv::warpAffine(a, b, t, a.size(), cv::INTER_CUBIC, cv::BORDER_CONSTANT);
  b.convertTo(b, -1, 0.8, 15.0);

  const PhotoFeatureOptions feature_options;
  const PhotoFeatures fa(a, "IMG_2212_2304", feature_options), fb(b, "warped", feature_options);
  EXPECT_LT(fa.reduce(), 1.0);  // the full-resolution refinement runs
  const PhotoPairResult r = MatchPhotoPair(fa, fb, PhotoPairOptions());
  const PhotoPairSummary& s = r.summary;
  double sum = 0.0, worst = 0.0;
  std::vector<double> errors;
  for (const PhotoTiePoint& p : r.tie_points) {
    const Eigen::Vector2d truth(
        t.at<double>(0, 0) * p.xa.x() + t.at<double>(0, 1) * p.xa.y() + t.at<double>(0, 2),
        t.at<double>(1, 0) * p.xa.x() + t.at<double>(1, 1) * p.xa.y() + t.at<double>(1, 2));
    const double e = (p.xb - truth).norm();
    sum += e * e;
    worst = std::max(worst, e);
    errors.push_back(e);
    EXPECT_GT(p.covariance.determinant(), 0.0);
  }
  ASSERT_FALSE(errors.empty());
  const double rms = std::sqrt(sum / errors.size());
  std::sort(errors.begin(), errors.end());
  const double median = errors[errors.size() / 2], p99 = errors[errors.size() * 99 / 100];
  std::printf(
      "warped copy: %d tie points, rotation %.2f deg scale %.4f, error median %.3f px, rms %.3f "
      "px, "
      "99 %% %.3f px, max %.3f px, epipolar rms %.3f px, %.2f s (+ features %.2f s, %.2f s)\n",
      s.matched, s.rotation_deg, s.scale, median, rms, p99, worst, s.epipolar_rms, s.seconds,
      fa.seconds(), fb.seconds());
  EXPECT_NEAR(s.rotation_deg, angle, 1.0);
  EXPECT_NEAR(s.scale, scale, 0.02);
  EXPECT_GE(s.matched, 1500);
  EXPECT_LT(median, 0.08);
  EXPECT_LT(rms, 0.15);
  EXPECT_LT(p99, 0.5);
}

struct RealPair {
  const char* a;
  const char* b;
  int min_tie_points;           // measured count minus a margin (see the printout)
  double max_rms;               // [px] measured epipolar RMS plus a margin
  int min_sequence_tie_points;  // the same with the UAV sequence matcher's options
  double max_heading_error;     // [deg] relation's rotation against the headings' difference
};

class RealPairs : public ::testing::TestWithParam<RealPair> {};

TEST_P(RealPairs, TiePointsAgreeWithTheAutopilotHeadingAndOutnumberSift) {
  const RealPair& p = GetParam();
  const cv::Mat a = Load(std::string(p.a) + "_1152.jpg"), b = Load(std::string(p.b) + "_1152.jpg");
  ASSERT_FALSE(a.empty() || b.empty());
  const PhotoFeatureOptions fo;
  const PhotoFeatures fa(a, p.a, fo), fb(b, p.b, fo);
  const PhotoPairResult r = MatchPhotoPair(fa, fb, PhotoPairOptions());
  const PhotoPairSummary& s = r.summary;
  const auto headings = Headings();
  const double heading_rotation =
      Wrap(headings.at(std::string(p.a) + ".JPG") - headings.at(std::string(p.b) + ".JPG"));
  const int sift = SiftInliers(a, b);
  std::printf(
      "%s %s: %d tie points (%d candidates), epipolar rms %.3f px, rotation %.1f deg (headings: "
      "%.1f), "
      "%.2f s; OpenCV SIFT: %d RANSAC inliers\n",
      p.a, p.b, s.matched, s.candidates, s.epipolar_rms, s.rotation_deg, heading_rotation,
      s.seconds, sift);
  EXPECT_GE(s.matched, p.min_tie_points);
  EXPECT_LT(s.epipolar_rms, p.max_rms);
  EXPECT_GT(s.epipolar_rms, 0.0);
  // Relation against the autopilot's headings (crab and the homography's
  // fit on an overlap at the photo's edge: a few degrees).
  EXPECT_LT(std::abs(Wrap(s.rotation_deg - heading_rotation)), p.max_heading_error);
  EXPECT_GT(s.matched, 2 * sift);
  // The same with the heading difference as the prior: the same relation.
  PhotoPairPrior prior;
  prior.has_rotation = true;
  prior.rotation_deg = heading_rotation;
  const PhotoPairResult rp = MatchPhotoPair(fa, fb, PhotoPairOptions(), prior);
  EXPECT_GE(rp.summary.matched, p.min_tie_points);
  EXPECT_LT(std::abs(Wrap(rp.summary.rotation_deg - s.rotation_deg)), 2.0);
  // The block's features (BlockPhotoFeatureOptions: the graph's sequence
  // matcher and process_flight; SIFT on a 640 px copy, 2000 interest points
  // spread over 8 x 8 cells; measured 220, 119, 56 and 20 tie points; with
  // SIFT on the 1200 px copy the turn pairs got none): the same relation.
  const SequenceMatcherOptions so;
  EXPECT_EQ(so.photo.coarse_sift_max_side, BlockPhotoFeatureOptions().coarse_sift_max_side);
  const PhotoFeatures sa(a, p.a, so.photo), sb(b, p.b, so.photo);
  const PhotoPairSummary ss = MatchPhotoPair(sa, sb, so.photo_pair).summary;
  std::printf(
      "  sequence options: %d tie points, epipolar rms %.3f px, rotation %.1f deg, %.2f s\n",
      ss.matched, ss.epipolar_rms, ss.rotation_deg, ss.seconds);
  EXPECT_GE(ss.matched, p.min_sequence_tie_points);
  EXPECT_LT(ss.epipolar_rms, p.max_rms);
  if (ss.matched > 0) {
    EXPECT_LT(std::abs(Wrap(ss.rotation_deg - heading_rotation)), p.max_heading_error);
  }
}

INSTANTIATE_TEST_SUITE_P(Snowpeak, RealPairs,
                         ::testing::Values(RealPair{"IMG_2213", "IMG_2244", 330, 0.42, 80, 6.0},
                                           RealPair{"IMG_2212", "IMG_2244", 320, 0.42, 35, 6.0},
                                           // Strips flown in opposite directions (headings
                                           // 142.8 / 307.6 deg), the common scene at the
                                           // photos' edge (a path and a pole's shadow, checked
                                           // by eye): 239 tie points, -172.3 deg (sequence
                                           // options -175.3) against the headings' -164.7:
                                           // the autopilot's heading is the track's, and the
                                           // overlap at the edge holds the homography's fit.
                                           RealPair{"IMG_2171", "IMG_2186", 200, 0.42, 20, 12.0},
                                           // Either side of a turn: 115, -166.3 deg; the
                                           // sequence's 1000 interest points leave too few
                                           // in the narrow overlap (none matched).
                                           RealPair{"IMG_2212", "IMG_2213", 95, 0.42, 0, 6.0}));

TEST(PhotoPairMatcher, PhotosFarApartGiveNoTiePoints) {
  // IMG_2168 and IMG_2244: 540 m apart (geoinfo.txt), footprints ~230 m.
  const PhotoFeatureOptions fo;
  const PhotoFeatures fa(Load("IMG_2168_1152.jpg"), "IMG_2168", fo),
      fb(Load("IMG_2244_1152.jpg"), "IMG_2244", fo);
  const PhotoPairResult r = MatchPhotoPair(fa, fb, PhotoPairOptions());
  std::printf("far apart: %d tie points (%s)\n", r.summary.matched, r.summary.message.c_str());
  EXPECT_EQ(r.summary.matched, 0);
  EXPECT_FALSE(r.summary.message.empty());
}

TEST(PhotoPairMatcher, FeaturesRejectBadImagesByName) {
  const PhotoFeatureOptions fo;
  try {
    PhotoFeatures f(cv::Mat(), "empty.jpg", fo);
    FAIL() << "no exception";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty.jpg"), std::string::npos) << e.what();
  }
  EXPECT_THROW(PhotoFeatures(cv::Mat(10, 10, CV_32F, 0.f), "float.tif", fo), InvalidArgument);
  PhotoPairOptions o;
  o.coarse_ratio = 0.0;
  EXPECT_THROW(o.Check(), ConfigError);
}

// Footprints 100 m across x 80 m along the flight.
PhotoFootprint Rect(double east, double north, double heading) {
  PhotoFootprint f;
  f.has_position = true;
  f.east_north = Eigen::Vector2d(east, north);
  f.has_heading = true;
  f.heading_deg = heading;
  f.width = 100.0;
  f.length = 80.0;
  return f;
}

TEST(PairSelection, FootprintOverlapByHand) {
  // Flying north, 40 m apart: 100 x 40 common of 100 x 80.
  EXPECT_NEAR(FootprintOverlap(Rect(0, 0, 0), Rect(0, 40, 0)), 0.5, 1e-4);
  // The second flying east: x in [-40, 40], y in [-10, 90]; common 80 x 50.
  EXPECT_NEAR(FootprintOverlap(Rect(0, 0, 0), Rect(0, 40, 90)), 0.5, 1e-4);
  // Opposite directions, side by side 90 m apart: 10 x 80 common.
  EXPECT_NEAR(FootprintOverlap(Rect(0, 0, 0), Rect(90, 0, 180)), 0.1, 1e-4);
  EXPECT_EQ(FootprintOverlap(Rect(0, 0, 0), Rect(0, 200, 0)), 0.0);

  PhotoFootprint unknown;  // no GNSS: paired with every photo
  const std::vector<PhotoFootprint> photos = {Rect(0, 0, 0), Rect(0, 40, 0), Rect(0, 500, 0),
                                              unknown};
  const auto pairs = SelectOverlappingPairs(photos, PairSelectionOptions());
  const std::vector<std::pair<int, int>> expected = {{0, 1}, {0, 3}, {1, 3}, {2, 3}};
  EXPECT_EQ(pairs, expected);
}

TEST(PairSelection, NadirFootprintFromCamera) {
  PairSelectionOptions o;
  o.height_above_ground = 100.0;
  // 4608 x 3456 px of 1.34 um behind 4.3 mm: 143.6 m x 107.7 m at 100 m.
  const PhotoFootprint f =
      NadirFootprint({0, 0}, true, 30.0, cv::Size(4608, 3456), 4.3, 1.34e-3, o);
  EXPECT_NEAR(f.width, 4608 * 1.34e-3 / 4.3 * 100.0, 1e-9);
  EXPECT_NEAR(f.length, 3456 * 1.34e-3 / 4.3 * 100.0, 1e-9);
  EXPECT_THROW(NadirFootprint({0, 0}, false, 0.0, cv::Size(10, 10), 0.0, 1e-3, o), InvalidArgument);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
