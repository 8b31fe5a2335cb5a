// The centroider on the real photographs of libapriltag's own test suite
// (test/data/apriltag_real/, see test/data/README.md). The expected files
// hold one line per tag: "id, (x0 y0), (x1 y1), (x2 y2), (x3 y3)", corners in
// libapriltag's order and pixel convention (centre of the top-left pixel at
// (0.5, 0.5)), produced with quad_decimate = 1 and refine_edges = false; the
// library's test accepts 0.1 px per coordinate. Our corners are in OpenCV's
// convention, so we compare ours + 0.5 px.
//
// What we found (libapriltag 3.3.0 from Debian, images decoded by OpenCV):
// all 37 tags are found with the right ID (with 2 corrected bits, as the
// library's test uses); 294 of the 296 corner coordinates agree within
// 0.1 px; two do not (0.106 px and 0.137 px). The 0.106 px one is libapriltag
// 3.3 itself: decoded with the library's own JPEG decoder (pjpeg) the bare
// detector gives the same value, so the reference was recorded with a later
// library version. The 0.137 px one (a tag decoded with 2 bit errors) comes
// from the JPEG decoder (libjpeg vs pjpeg: +-1 grey level); with pjpeg it
// agrees. The test therefore checks: every tag found, no other tag, and
// every coordinate within 0.1 px except at most 2 of 296, none over 0.15 px.
#include <cstdio>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

struct Expected {
  int id;
  std::array<Eigen::Vector2d, 4> p;
};

std::vector<Expected> ReadExpected(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::vector<Expected> out;
  std::string line;
  while (std::getline(in, line)) {
    Expected e;
    double v[8];
    if (std::sscanf(line.c_str(), "%d, (%lf %lf), (%lf %lf), (%lf %lf), (%lf %lf)", &e.id, &v[0], &v[1], &v[2], &v[3],
                    &v[4], &v[5], &v[6], &v[7]) != 9)
      continue;
    for (int k = 0; k < 4; ++k) e.p[k] = Eigen::Vector2d(v[2 * k], v[2 * k + 1]);
    out.push_back(e);
  }
  return out;
}

TEST(AprilTagReal, MatchesTheLibraryReference) {
  Options opt;
  opt.quad_decimate = 1.0;
  opt.refine_edges = false;
  opt.refine_tags = false;        // compare libapriltag's corners as we publish them
  opt.min_decision_margin = 0.0;  // the reference keeps every decoded tag
  opt.max_hamming = 2;            // apriltag_detector_add_family corrects 2 bits
  opt.detect_circles = false;
  opt.max_residual = 1.0;         // real tags on textured backgrounds: do not reject here
  opt.max_dark_surround = 1.0;    // (their quiet zones are not all white either)
  opt.max_edge_blur = 20.0;
  opt.min_contrast = 1.0;
  opt.border_margin = 0.0;
  opt.max_saturated_fraction = 1.0;
  TargetCentroider centroider(opt, io::TargetList());
  int n_coords = 0, n_over = 0, n_tags = 0;
  double worst = 0;
  for (const std::string name : {"33369213973_9d9bb4cc96_c", "34085369442_304b6bafd9_c"}) {
    const std::string base = std::string(SM_TEST_DATA_DIR) + "/apriltag_real/" + name;
    const cv::Mat img = cv::imread(base + ".jpg", cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(img.empty()) << base;
    const std::vector<Expected> expected = ReadExpected(base + ".txt");
    ASSERT_GT(expected.size(), 10u);
    const Result r = centroider.Detect(img, "mono8");
    for (const auto& rj : r.rejections) std::printf("%s: rejected %s (%s)\n", name.c_str(), rj.family.c_str(), rj.detail.c_str());
    // Our corners as published, or the libapriltag corners of tags we rejected
    // (none should be: every expected tag must be an observation).
    EXPECT_EQ(r.observations.size(), expected.size()) << name;
    for (const Expected& e : expected) {
      const Observation* best = nullptr;
      double best_d = 1e9;
      for (const auto& o : r.observations) {
        const double d = (o.corners[0] + Eigen::Vector2d(0.5, 0.5) - e.p[0]).norm();
        if (d < best_d) {
          best_d = d;
          best = &o;
        }
      }
      ASSERT_NE(best, nullptr);
      EXPECT_LT(best_d, 1.0) << name << ": expected tag at (" << e.p[0].transpose() << ") not found";
      if (best_d >= 1.0) continue;
      ++n_tags;
      EXPECT_EQ(best->id, e.id);
      EXPECT_EQ(best->family, "tag36h11");
      EXPECT_FALSE(best->role.has_value());  // empty target list: every tag is unknown, none dropped
      for (int k = 0; k < 4; ++k) {
        for (int c = 0; c < 2; ++c) {
          const double d = std::abs(best->corners[k][c] + 0.5 - e.p[k][c]);
          ++n_coords;
          worst = std::max(worst, d);
          if (d > 0.1) {
            ++n_over;
            std::printf("%s: corner %d coord %d off by %.4f px (decision margin %.1f)\n", name.c_str(), k, c, d,
                        best->decision_margin);
          }
        }
      }
    }
  }
  std::printf("tags found %d, coordinates within 0.1 px: %d of %d, worst %.4f px\n", n_tags, n_coords - n_over,
              n_coords, worst);
  EXPECT_EQ(n_tags, 37);
  EXPECT_LE(n_over, 2);
  EXPECT_LE(worst, 0.15);
}

// The refined centre stays close to libapriltag's on real tags (a sanity
// check of the refinement on real, JPEG-compressed edges).
TEST(AprilTagReal, RefinedCentresStayNearTheDetector) {
  Options opt;
  opt.quad_decimate = 1.0;
  opt.detect_circles = false;
  TargetCentroider centroider(opt, io::TargetList());
  const cv::Mat img =
      cv::imread(std::string(SM_TEST_DATA_DIR) + "/apriltag_real/33369213973_9d9bb4cc96_c.jpg", cv::IMREAD_GRAYSCALE);
  const Result r = centroider.Detect(img, "mono8");
  ASSERT_GE(r.observations.size(), 8u);
  for (const auto& o : r.observations) {
    EXPECT_LT((o.centre - o.detector_centre).norm(), 0.5) << o.Key();
    EXPECT_GT(o.covariance(0, 0), 0.0);
    EXPECT_GT(o.quality, 0.0);
  }
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
