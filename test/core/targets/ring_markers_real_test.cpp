// Ring markers on real photos nobody here made, with the defaults a user
// gets (test/data/README.md):
//   * targets_real_cctag/01.png: five CCTag markers counted by eye (three
//     dark rings each on a white sheet), the leftmost cut by the image
//     border: four measured as ring markers of three rings, the cut one
//     named "partial", nothing else;
//   * targets_real_cctag/02.png: six such markers (one on the ceiling seen
//     60-70 deg oblique, one small and far): six measured, nothing else;
//   * uav_real_caliterra/IMG_9388.jpg: a 12 MP drone photo of fields and
//     round tree crowns, no marker: no circle.
#include <cstdio>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace ring_markers_real {

cv::Mat ReadGrey(const std::string& relative) {
  const std::string path = std::string(SM_SOURCE_DIR) + "/test/data/" + relative;
  const cv::Mat m = cv::imread(path, cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(m.empty()) << "cannot read " << path;
  return m;
}

// The ring markers of a result (method ring_centre); each printed.
int RingMarkers(const Result& r, const std::string& name) {
  int n = 0;
  for (const Observation& o : r.observations) {
    std::printf("%s: %s at (%.2f, %.2f), %d rings, ring ratio %.2f, sigma %.3f px\n", name.c_str(),
                CentreMethodName(o.method).c_str(), o.centre.x(), o.centre.y(), o.rings,
                o.ring_ratio, std::sqrt(0.5 * o.covariance.trace()));
    if (o.method != CentreMethod::kRingCentre) continue;
    EXPECT_EQ(o.rings, 3) << name << " at (" << o.centre.x() << ", " << o.centre.y() << ")";
    ++n;
  }
  for (size_t i = 0; i < r.observations.size(); ++i)
    for (size_t j = i + 1; j < r.observations.size(); ++j)
      EXPECT_GT((r.observations[i].centre - r.observations[j].centre).norm(), 50.0)
          << name << ": one marker measured twice";
  return n;
}

TEST(RingMarkersReal, CctagPhotoWithAMarkerCutByTheBorder) {
  const TargetCentroider c{Options(), io::TargetList()};
  const Result r = c.Detect(ReadGrey("targets_real_cctag/01.png"), "mono8");
  EXPECT_EQ(RingMarkers(r, "01.png"), 4);
  EXPECT_EQ(r.observations.size(), 4u);
  ASSERT_EQ(r.rejections.size(), 1u);
  const Rejection& cut = r.rejections[0];
  std::printf("01.png: rejected at (%.1f, %.1f): %s: %s\n", cut.where.x(), cut.where.y(),
              RejectReasonName(cut.reason).c_str(), cut.detail.c_str());
  EXPECT_EQ(cut.reason, RejectReason::kPartial);
  EXPECT_LT(cut.where.x(), 60.0);
  EXPECT_GT(cut.radius_px, 50.0);
}

TEST(RingMarkersReal, CctagPhotoWithAnObliqueAndAFarMarker) {
  const TargetCentroider c{Options(), io::TargetList()};
  const Result r = c.Detect(ReadGrey("targets_real_cctag/02.png"), "mono8");
  EXPECT_EQ(RingMarkers(r, "02.png"), 6);
  EXPECT_EQ(r.observations.size(), 6u);
}

TEST(RingMarkersReal, DronePhotoOfTreeCrownsHasNoCircle) {
  const TargetCentroider c{Options(), io::TargetList()};
  const Result r = c.Detect(ReadGrey("uav_real_caliterra/IMG_9388.jpg"), "mono8");
  RingMarkers(r, "IMG_9388.jpg");
  EXPECT_EQ(r.summary.num_circles, 0);
}

}  // namespace ring_markers_real
}  // namespace targets
}  // namespace slope_monitor
