// EstimateGlobalShift on real texture (Middlebury Cones, test/data) with a
// known shift: image b is a crop of the left image displaced by kShift from
// image a's crop, so xb - xa = kShift exactly (both crops with independent
// noise). Also: bad input, unusable pairs, and the sequence helpers
// (PlanSequencePairs, SequenceTrackId) on hand-checkable cases.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/global_shift.h"
#include "slope_monitor/core/matching/sequence.h"

#include "cones_images.h"

namespace slope_monitor {
namespace matching {
namespace {

// Crop of the Cones left image at (x0, y0), w x h, with noise 1.5 grey.
cv::Mat Crop(const cv::Mat& left, int x0, int y0, int w, int h, unsigned seed) {
  cv::Mat f;
  left(cv::Rect(x0, y0, w, h)).convertTo(f, CV_32F);
  cv::Mat out;
  slope_monitor::testing::AddNoise(f, 1.5, seed).convertTo(out, CV_8U);
  return out;
}

TEST(GlobalShift, KnownShiftOfConesTexture) {
  const cv::Mat left = slope_monitor::testing::LoadCones("left.tif", cv::IMREAD_GRAYSCALE);
  const int w = 320, h = 260;
  // b at xb sees the scene point at xb + (x0 - dx) = xa + x0 -> xb = xa + d.
  struct Case {
    int dx, dy;
  };
  for (const Case c : {Case{97, -38}, Case{-41, 70}, Case{12, 5}}) {
    const int x0 = c.dx < 0 ? 60 : 100, y0 = c.dy < 0 ? 60 : 100;
    const cv::Mat a = Crop(left, x0, y0, w, h, 1);
    const cv::Mat b = Crop(left, x0 - c.dx, y0 - c.dy, w, h, 2);
    for (int max_size : {80, 160, 320}) {
      GlobalShiftOptions o;
      o.max_size = max_size;
      const GlobalShiftResult r = EstimateGlobalShift(a, b, o);
      std::printf(
          "shift (%d, %d), max_size %d: found (%.3f, %.3f), response %.3f, overlap NCC %.3f, "
          "factor %d\n",
          c.dx, c.dy, max_size, r.shift.x(), r.shift.y(), r.response, r.overlap_correlation,
          r.factor);
      ASSERT_TRUE(r.usable) << r.reason;
      EXPECT_TRUE(r.refined);
      // Refinement at factor 2: well within a pixel (the matcher searches 24 px).
      EXPECT_NEAR(r.shift.x(), c.dx, 0.5);
      EXPECT_NEAR(r.shift.y(), c.dy, 0.5);
    }
    GlobalShiftOptions coarse_only;
    coarse_only.refine = false;
    coarse_only.max_size = 80;  // factor 4
    const GlobalShiftResult r = EstimateGlobalShift(a, b, coarse_only);
    ASSERT_TRUE(r.usable);
    EXPECT_EQ(r.factor, 4);
    EXPECT_NEAR(r.shift.x(), c.dx, 4.0);
    EXPECT_NEAR(r.shift.y(), c.dy, 4.0);
  }
}

// Overlap below 50 % in both axes: the phase-correlation peak wraps around;
// the candidate whose overlap correlates best must be taken.
TEST(GlobalShift, OverlapBelowHalfTheImage) {
  const cv::Mat left = slope_monitor::testing::LoadCones("left.tif", cv::IMREAD_GRAYSCALE);
  const int w = 200, h = 160, dx = 125, dy = 90, x0 = 150, y0 = 100;
  const cv::Mat a = Crop(left, x0, y0, w, h, 5);
  const cv::Mat b = Crop(left, x0 - dx, y0 - dy, w, h, 6);
  const GlobalShiftResult r = EstimateGlobalShift(a, b, GlobalShiftOptions());
  std::printf(
      "shift (%d, %d) on %dx%d: found (%.3f, %.3f), response %.3f, overlap correlation %.3f\n", dx,
      dy, w, h, r.shift.x(), r.shift.y(), r.response, r.overlap_correlation);
  ASSERT_TRUE(r.usable) << r.reason;
  // A 75 x 70 px overlap: within a pixel (measured 0.48 px; the matcher searches 24 px).
  EXPECT_NEAR(r.shift.x(), dx, 1.0);
  EXPECT_NEAR(r.shift.y(), dy, 1.0);
}

TEST(GlobalShift, UnrelatedOrTexturelessImagesAreNotUsable) {
  const cv::Mat left = slope_monitor::testing::LoadCones("left.tif", cv::IMREAD_GRAYSCALE);
  const cv::Mat a = Crop(left, 0, 0, 200, 160, 1);
  // Pure noise against texture: no common content.
  cv::Mat noise(160, 200, CV_8U);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  const GlobalShiftResult r = EstimateGlobalShift(a, noise, GlobalShiftOptions());
  std::printf("texture vs noise: response %.3f, overlap correlation %.3f (%s)\n", r.response,
              r.overlap_correlation, r.reason.c_str());
  EXPECT_FALSE(r.usable);
  EXPECT_NE(r.reason.find("below min_"), std::string::npos) << r.reason;
  const GlobalShiftResult flat =
      EstimateGlobalShift(cv::Mat(160, 200, CV_8U, cv::Scalar(100)),
                          cv::Mat(160, 200, CV_8U, cv::Scalar(101)), GlobalShiftOptions());
  EXPECT_FALSE(flat.usable);
}

TEST(GlobalShift, BadInputIsNamed) {
  const cv::Mat a(100, 120, CV_8U, cv::Scalar(1)), b(100, 110, CV_8U, cv::Scalar(1));
  try {
    EstimateGlobalShift(a, b, GlobalShiftOptions());
    FAIL() << "no exception";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("differ in size"), std::string::npos) << e.what();
  }
  EXPECT_THROW(EstimateGlobalShift(cv::Mat(), a, GlobalShiftOptions()), InvalidArgument);
  EXPECT_THROW(EstimateGlobalShift(cv::Mat(100, 120, CV_8UC3), cv::Mat(100, 120, CV_8UC3),
                                   GlobalShiftOptions()),
               InvalidArgument);
  GlobalShiftOptions bad;
  bad.max_size = 4;
  EXPECT_THROW(EstimateGlobalShift(a, a, bad), ConfigError);
}

SequenceImage Img(std::uint32_t serial, double stamp, double x, double y, bool prior = true) {
  SequenceImage s;
  s.serial = serial;
  s.stamp = stamp;
  s.has_position = prior;
  s.position = Eigen::Vector2d(x, y);
  return s;
}

// Up to exhaustive_max_photos images in the epoch (b included), b pairs with
// every earlier image, latest first, whatever the priors say (process_flight
// pairs a flight of that size alike); beyond, the rules below.
TEST(SequencePairs, EveryEarlierImageWhileTheEpochIsSmall) {
  const std::vector<SequenceImage> earlier = {Img(1, 0, 0, 0), Img(2, 2, 0, 10), Img(3, 4, 0, 20),
                                              Img(4, 6, 0, 30), Img(5, 20, 25, 30)};
  SequencePairOptions o;
  EXPECT_EQ(o.exhaustive_max_photos, 60);
  // b 200 m away from all of them: still every one.
  EXPECT_EQ(PlanSequencePairs(earlier, Img(6, 22, 200, 200), o),
            (std::vector<size_t>{4, 3, 2, 1, 0}));
  EXPECT_TRUE(PlansExhaustively(60, o));
  EXPECT_FALSE(PlansExhaustively(61, o));
  // The 61st image of the epoch (earlier partners released or not): the rules.
  EXPECT_TRUE(PlanSequencePairs(earlier, Img(6, 22, 200, 200), o, 61).empty());
  o.exhaustive_max_photos = 6;
  EXPECT_EQ(PlanSequencePairs(earlier, Img(6, 22, 200, 200), o).size(), 5u);
  o.exhaustive_max_photos = 5;
  EXPECT_TRUE(PlanSequencePairs(earlier, Img(6, 22, 200, 200), o).empty());
  o.exhaustive_max_photos = -1;
  EXPECT_THROW(PlanSequencePairs(earlier, Img(6, 22, 0, 0), o), ConfigError);
  // Footprints known (40 x 30 m: 400 x 300 px of 0.1 m; no heading: the
  // 30 m disc): at twice their size (discs of 60 m) an image 50 m away still
  // touches b, one 200 m away does not and is skipped; one without a
  // footprint is kept. At their own size the one 50 m away is skipped too.
  const auto with_footprint = [](SequenceImage s) {
    s.width = 400;
    s.height = 300;
    s.ground_pixel = 0.1;
    return s;
  };
  const std::vector<SequenceImage> footprints = {
      with_footprint(Img(1, 0, 0, 50)), with_footprint(Img(2, 2, 0, 200)), Img(3, 4, 0, 400)};
  SequencePairOptions e;
  EXPECT_EQ(e.exhaustive_footprint_scale, 2.0);
  EXPECT_EQ(PlanSequencePairs(footprints, with_footprint(Img(4, 6, 0, 0)), e),
            (std::vector<size_t>{2, 0}));
  e.exhaustive_footprint_scale = 1.0;
  EXPECT_EQ(PlanSequencePairs(footprints, with_footprint(Img(4, 6, 0, 0)), e),
            (std::vector<size_t>{2}));
  e.exhaustive_footprint_scale = 0.0;  // every one
  EXPECT_EQ(PlanSequencePairs(footprints, with_footprint(Img(4, 6, 0, 0)), e).size(), 3u);
  e.exhaustive_footprint_scale = 0.5;
  EXPECT_THROW(PlanSequencePairs(footprints, Img(4, 6, 0, 0), e), ConfigError);
}

TEST(SequencePairs, NearestPriorsFirstAtMostMaxPairs) {
  // Strip 1 northwards (y 0, 10, 20, 30), strip 2 southwards 25 m east.
  const std::vector<SequenceImage> earlier = {Img(1, 0, 0, 0), Img(2, 2, 0, 10), Img(3, 4, 0, 20),
                                              Img(4, 6, 0, 30), Img(5, 20, 25, 30)};
  SequencePairOptions o;
  o.exhaustive_max_photos = 0;  // the rules of a flight beyond it
  // b at (25, 20): distances 5: 25.0 (y 30 -> sqrt(625+100)=26.9), 4: 26.9, 3: 25, 2: 26.9,
  // 1: 32.0.
  const std::vector<size_t> p = PlanSequencePairs(earlier, Img(6, 22, 25, 20), o);
  // Nearest: image 5 (10 m), then image 3 (25 m), then 2 and 4 (26.9 m, later first: 4, 2); 1 is 32
  // m away.
  ASSERT_EQ(p.size(), 4u);
  EXPECT_EQ(p[0], 4u);
  EXPECT_EQ(p[1], 2u);
  EXPECT_EQ(p[2], 3u);
  EXPECT_EQ(p[3], 1u);
  o.max_pairs_per_image = 2;
  EXPECT_EQ(PlanSequencePairs(earlier, Img(6, 22, 25, 20), o).size(), 2u);
  // Nothing within reach: no pairs.
  EXPECT_TRUE(PlanSequencePairs(earlier, Img(6, 22, 200, 200), o).empty());
  // No prior for b: the previous sequence_depth images, latest first.
  const std::vector<size_t> d = PlanSequencePairs(earlier, Img(6, 22, 0, 0, false), o);
  ASSERT_EQ(d.size(), 2u);
  EXPECT_EQ(d[0], 4u);
  EXPECT_EQ(d[1], 3u);
  // First image of an epoch: no partner.
  EXPECT_TRUE(PlanSequencePairs({}, Img(1, 0, 0, 0), o).empty());
  o.sequence_depth = 0;
  EXPECT_THROW(PlanSequencePairs(earlier, Img(6, 22, 0, 0), o), ConfigError);
}

// Footprints 40 x 30 m (400 x 300 px of 0.1 m) by hand: b at (0, 0) with
// its top to the north; overlaps with b (of the smaller footprint):
//   (0, 9) heading 0: 40 x 21 of 40 x 30 = 0.70; (0, 18): 0.40; (0, 27): 0.10;
//   (25, 0) heading 180 (the next strip, flown back): 15 x 30 = 0.375;
//   (24, 9) heading 180: 16 x 21 = 0.28; no ground pixel: not a partner.
TEST(SequencePairs, LargestFootprintOverlapFirst) {
  const auto img = [](std::uint32_t serial, double stamp, double x, double y, double heading,
                      double ground_pixel = 0.1) {
    SequenceImage s = Img(serial, stamp, x, y);
    s.has_heading = true;
    s.heading_deg = heading;
    s.width = 400;
    s.height = 300;
    s.ground_pixel = ground_pixel;
    return s;
  };
  const std::vector<SequenceImage> earlier = {img(1, 0, 0, 27, 0),    img(2, 2, 0, 18, 0),
                                              img(3, 4, 0, 9, 0),     img(4, 30, 24, 9, 180),
                                              img(5, 32, 25, 0, 180), img(6, 34, 1, 1, 0, 0.0)};
  const SequenceImage b = img(7, 40, 0, 0, 0);
  EXPECT_NEAR(FootprintOverlap(FootprintOf(earlier[3]), FootprintOf(b)), 0.28, 1e-4);
  SequencePairOptions o;        // min_overlap 0.2, 4 pairs
  o.exhaustive_max_photos = 0;  // the rules of a flight beyond it
  const std::vector<size_t> p = PlanSequencePairs(earlier, b, o);
  // 0.70 (image 3), 0.40 (image 2), 0.375 (image 5), 0.28 (image 4); image 1 shares 0.10 < 0.2.
  const std::vector<size_t> expected = {2, 1, 4, 3};
  EXPECT_EQ(p, expected);
  o.min_overlap = 0.5;
  EXPECT_EQ(PlanSequencePairs(earlier, b, o), std::vector<size_t>{2});
  // Without b's ground pixel: by distance (image 6 at 1.4 m first).
  SequenceImage near = b;
  near.ground_pixel = 0.0;
  EXPECT_EQ(PlanSequencePairs(earlier, near, SequencePairOptions())[0], 5u);
  o.min_overlap = 0.0;
  EXPECT_THROW(PlanSequencePairs(earlier, b, o), ConfigError);
}

// Tie points of a pair whose b is a's image moved 120 px right and 50 px
// down (a's centre 130 px from b's), turned by 30 deg about the centre and
// scaled 1.1: a baseline of 6.5 m gives 0.05 m/px.
TEST(SequencePairs, GroundPixelFromTiesByHand) {
  const Eigen::Vector2d centre(200, 150);
  const Eigen::Rotation2Dd r(30.0 * M_PI / 180.0);
  std::vector<Eigen::Vector2d> xa, xb;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Vector2d x(10.0 * (i % 8) + 90, 12.0 * (i / 8) + 60);
    xa.push_back(x);
    xb.push_back(centre + Eigen::Vector2d(120, 50) + 1.1 * (r * (x - centre)));
  }
  EXPECT_NEAR(GroundPixelFromTies(xa, xb, centre, centre, 6.5), 0.05, 1e-9);
  // Not to be told: a baseline under 1 m, fewer than 8 tie points, no image motion.
  EXPECT_EQ(GroundPixelFromTies(xa, xb, centre, centre, 0.5), 0.0);
  EXPECT_EQ(GroundPixelFromTies({xa.begin(), xa.begin() + 7}, {xb.begin(), xb.begin() + 7}, centre,
                                centre, 6.5),
            0.0);
  EXPECT_EQ(GroundPixelFromTies(xa, xa, centre, centre, 6.5), 0.0);
}

TEST(SequencePairs, TrackIdsAreUniqueAndNeverZero) {
  EXPECT_EQ(SequenceTrackId(1, Eigen::Vector2d(0, 0), 1280), std::uint64_t(1) << 32);
  EXPECT_EQ(SequenceTrackId(3, Eigen::Vector2d(5.2, 2.9), 1280),
            (std::uint64_t(3) << 32) | (3 * 1280 + 5));
  EXPECT_NE(SequenceTrackId(1, Eigen::Vector2d(1279, 959), 1280),
            SequenceTrackId(2, Eigen::Vector2d(0, 0), 1280));
  EXPECT_THROW(SequenceTrackId(0, Eigen::Vector2d(1, 1), 1280), InvalidArgument);
  // Read back: the pixel the track starts at (rounded), whatever the serial.
  const std::uint64_t id = SequenceTrackId(3, Eigen::Vector2d(5.2, 2.9), 1280);
  EXPECT_TRUE(SequenceTrackStartsAt(id, Eigen::Vector2d(4.6, 3.4), 1280));
  EXPECT_FALSE(SequenceTrackStartsAt(id, Eigen::Vector2d(6.0, 3.0), 1280));
  EXPECT_FALSE(SequenceTrackStartsAt(id, Eigen::Vector2d(5.0, 3.0), 1000));
  EXPECT_FALSE(SequenceTrackStartsAt(SequenceTrackId(1, Eigen::Vector2d(1279, 0), 1280),
                                     Eigen::Vector2d(-1.0, 1.0), 1280));
  EXPECT_THROW(SequenceTrackId(1, Eigen::Vector2d(1300, 1), 1280), InvalidArgument);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
