// SequenceMatcher on the simulator's UAV flight (uav_flight.h: three nadir
// photos, 70 % forward overlap) with the options a user gets, both pair
// methods, against the geometric truth: each tie point's a-point is
// intersected with the true terrain (ray of xa with the true camera a) and
// projected into b with the true camera b; xb minus that projection. Pairs:
// without position priors, photo 2 with 1, photo 3 with 2 and 1.
// Links slope_monitor_core_sim (CMakeLists.txt: this test only).
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/matching/sequence_matcher.h"
#include "uav_flight.h"

namespace slope_monitor {
namespace matching {
namespace {

constexpr std::int64_t kSimSecond = 1000000000;

struct PairError {
  int normal = 0, gross = 0, low = 0;
  double rms = 0.0;
};

PairError Compare(const testing::Flight& f, const SequencePair& p) {
  const int a = static_cast<int>(p.stamp_a / kSimSecond),
            b = static_cast<int>(p.stamp_b / kSimSecond);
  PairError e;
  double sum2 = 0;
  for (const SequenceTie& t : p.points) {
    if (t.quality <= kLowQuality) {
      ++e.low;
      continue;
    }
    Eigen::Vector2d truth;
    if (!f.Transfer(a, b, t.xa, &truth)) continue;
    const double d = (t.xb - truth).norm();
    if (d > 1.0) {
      ++e.gross;
      continue;
    }
    ++e.normal;
    sum2 += d * d;
  }
  e.rms = std::sqrt(sum2 / std::max(1, e.normal));
  return e;
}

void CheckMethod(SequencePairMethod method, int min_normal, double max_rms) {
  const testing::Flight& f = testing::TheFlight();
  SequenceMatcherOptions o;
  o.method = method;
  SequenceMatcher m(o);
  m.SetPriorsExpected(false);
  std::vector<SequencePair> pairs;
  for (int i = 0; i < 3; ++i)
    for (const SequencePair& p : m.AddImage(i * kSimSecond, "uav", f.images[i]).pairs)
      if (p.has_a) pairs.push_back(p);
  ASSERT_EQ(pairs.size(), 3u);
  std::map<std::uint64_t, std::set<std::int64_t>> tracks;
  for (const SequencePair& p : pairs) {
    const PairError e = Compare(f, p);
    std::printf(
        "%s: photos %d-%d: %zu tie points (%d low quality), %d within 1 px of the truth, RMS %.3f "
        "px, %d "
        "beyond 1 px; %.2f s\n",
        SequencePairMethodName(method), int(p.stamp_a / kSimSecond) + 1,
        int(p.stamp_b / kSimSecond) + 1, p.points.size(), e.low, e.normal, e.rms, e.gross,
        p.seconds);
    EXPECT_EQ(p.reason, "") << p.message;
    EXPECT_GT(e.normal, min_normal);
    EXPECT_LE(e.gross, 0.01 * (e.normal + e.gross));
    EXPECT_LT(e.rms, max_rms);
    if (p.stamp_a == 0)
      for (const SequenceTie& t : p.points) tracks[t.id].insert(p.stamp_b);
  }
  int three = 0;
  for (const auto& kv : tracks) three += kv.second.size() == 2 ? 1 : 0;
  std::printf("%s: %d tracks over 3 photos; features %.2f s for 3 photos, peak memory %.1f MB\n",
              SequencePairMethodName(method), three, m.summary().feature_seconds,
              m.summary().peak_memory_bytes / (1024.0 * 1024.0));
  EXPECT_GT(three, 50);
}

TEST(SequenceMatcherSim, PhotoMethodTiePointsAgainstTruth) {
  CheckMethod(SequencePairMethod::kPhoto, 150, 0.3);
}

TEST(SequenceMatcherSim, ShiftHexMethodTiePointsAgainstTruth) {
  CheckMethod(SequencePairMethod::kGlobalShiftHex, 150, 0.3);
}

// With position priors and the flight log's attitude (here the true pose),
// the third photo's partners are chosen by predicted footprint overlap: the
// ground pixel size measured by the pair (1, 2) equals the flight's (60 m
// above the terrain at the flight's centre, 10 um pixels behind 9.17 mm),
// photo 2 shares 70 % with photo 3 and photo 1 40 %.
TEST(SequenceMatcherSim, PartnersByFootprintOverlapFromTheMeasuredGroundPixel) {
  const testing::Flight& f = testing::TheFlight();
  const auto run = [&](double min_overlap) {
    SequenceMatcherOptions o;
    o.pairing.exhaustive_max_photos = 0;  // the rule of a flight beyond it
    o.pairing.min_overlap = min_overlap;
    SequenceMatcher m(o);
    std::vector<SequencePair> third;
    for (int i = 0; i < 3; ++i) {
      SequencePrior prior;
      prior.position = f.poses[i].position.head<2>();
      prior.site_from_optical = f.poses[i].SiteFromOptical().rotation;
      m.AddPrior(i * kSimSecond, prior);
      for (const SequencePair& p : m.AddImage(i * kSimSecond, "uav", f.images[i]).pairs)
        if (i == 2) third.push_back(p);
    }
    EXPECT_EQ(m.summary().footprint_planned, 1) << "photo 3 (photo 2 by distance)";
    const double truth = testing::kHeight * 0.01 / testing::kC;
    std::printf("ground pixel measured %.5f m, flight %.5f m\n", m.summary().ground_pixel, truth);
    EXPECT_NEAR(m.summary().ground_pixel, truth, 0.05 * truth);
    return third;
  };
  const std::vector<SequencePair> both = run(SequencePairOptions().min_overlap);
  ASSERT_EQ(both.size(), 2u);
  EXPECT_EQ(both[0].stamp_a, 1 * kSimSecond);  // 70 % first
  EXPECT_EQ(both[1].stamp_a, 0);               // 40 %
  for (const SequencePair& p : both) EXPECT_EQ(p.reason, "") << p.message;
  // A pair needing half the smaller footprint: photo 1 (40 %) is not tried.
  const std::vector<SequencePair> one = run(0.5);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].stamp_a, 1 * kSimSecond);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
