// Sequence matching of a UAV flight on the package's simulator, against its
// geometric truth: three consecutive nadir photos 60 m above the ground with
// 70 % forward overlap, flying north (image up = north). The camera is the
// UAV's (1280 x 960, c 8.8 mm, 4.8 um pixels) at half the resolution: 640 x
// 480 pixels of 9.6 um (c scaled to 9.1667 mm on the simulator's 0.01 mm
// pixels: the same field of view, ground pixel 6.5 cm), so that the test
// renders and matches in seconds.
//  * EstimateGlobalShift of photos 1-2 (70 % overlap) and 1-3 (40 %) against
//    the true image displacement of the ground (median over the overlap);
//  * tie points of the pairs 1-2, 1-3, 2-3 (global shift as the prior, the
//    hexagonal matcher's search radius 24 px): each normal-quality match's
//    a-point is intersected with the true terrain (ray of xa with the true
//    camera a) and projected into b with the true camera b; RMS of xb minus
//    that projection; track IDs (SequenceTrackId) shared by the pairs 1-2 and
//    1-3: tie points seen in three photos, each consistent with the truth.
// Links slope_monitor_core_sim (CMakeLists.txt: this test only).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/matching/global_shift.h"
#include "slope_monitor/core/matching/hex_matcher.h"
#include "slope_monitor/core/matching/sequence.h"
#include "uav_flight.h"

namespace slope_monitor {
namespace matching {
namespace {

using testing::Flight;
using testing::Inside;
using testing::kH;
using testing::kW;
using testing::TheFlight;

// Median true displacement xb - xa of the ground over a grid of a's pixels
// that land inside b; *spread: the largest deviation from it.
Eigen::Vector2d TrueShift(const Flight& f, int i, int j, double* spread) {
  std::vector<double> dx, dy;
  std::vector<Eigen::Vector2d> all;
  for (int r = 10; r < kH; r += 20)
    for (int c = 10; c < kW; c += 20) {
      Eigen::Vector2d xb;
      if (f.Transfer(i, j, Eigen::Vector2d(c, r), &xb) && Inside(xb, 0)) {
        dx.push_back(xb.x() - c);
        dy.push_back(xb.y() - r);
        all.push_back(xb - Eigen::Vector2d(c, r));
      }
    }
  std::nth_element(dx.begin(), dx.begin() + dx.size() / 2, dx.end());
  std::nth_element(dy.begin(), dy.begin() + dy.size() / 2, dy.end());
  const Eigen::Vector2d m(dx[dx.size() / 2], dy[dy.size() / 2]);
  *spread = 0;
  for (const auto& d : all) *spread = std::max(*spread, (d - m).norm());
  return m;
}

TEST(UavSequence, GlobalShiftOfSimulatedPhotos) {
  const Flight& f = TheFlight();
  for (const auto& ij : {std::make_pair(0, 1), std::make_pair(0, 2), std::make_pair(1, 2)}) {
    double spread = 0;
    const Eigen::Vector2d truth = TrueShift(f, ij.first, ij.second, &spread);
    const GlobalShiftResult r =
        EstimateGlobalShift(f.images[ij.first], f.images[ij.second], GlobalShiftOptions());
    std::printf(
        "photos %d-%d: true median shift (%.2f, %.2f) (parallax: up to %.1f px from it), found "
        "(%.2f, %.2f), "
        "response %.3f, overlap NCC %.3f\n",
        ij.first + 1, ij.second + 1, truth.x(), truth.y(), spread, r.shift.x(), r.shift.y(),
        r.response, r.overlap_correlation);
    ASSERT_TRUE(r.usable) << r.reason;
    // Well inside the matcher's 24 px search radius.
    EXPECT_LT((r.shift - truth).norm(), 3.0);
  }
}

// Matcher settings for the simulator's weak ground texture (as in
// sim_tracking_test.cpp, LSC on images low-passed by 1 px) with a 19 x 19
// window (measured here: RMS 0.16 px against 0.20 px with 15 x 15; the error
// is noise, its mean below 0.03 px).
HexMatcherOptions UavSimOptions() {
  HexMatcherOptions o;
  o.lsc.half_window = 9;
  o.lsc_prefilter_sigma = 1.0;
  return o;
}

TEST(UavSequence, TiePointsAgainstTruthAndTracksOverThreePhotos) {
  const Flight& f = TheFlight();
  const HexMatcher matcher(UavSimOptions());
  std::map<std::uint64_t, std::set<int>> track_images;                // id -> photos
  std::map<std::pair<std::uint64_t, int>, Eigen::Vector2d> track_xa;  // (id, b) -> xa
  double sum2_all = 0;
  int n_all = 0;
  for (const auto& ij : {std::make_pair(0, 1), std::make_pair(0, 2), std::make_pair(1, 2)}) {
    const int a = ij.first, b = ij.second;
    const GlobalShiftResult gs =
        EstimateGlobalShift(f.images[a], f.images[b], GlobalShiftOptions());
    ASSERT_TRUE(gs.usable) << gs.reason;
    MatchPrior prior;
    prior.shift = gs.shift;
    prior.within = [&gs](const Eigen::Vector2d& x) { return Inside(x + gs.shift, 12.0); };
    const auto t0 = std::chrono::steady_clock::now();
    const HexMatchResult r = matcher.Match(f.images[a], f.images[b], prior);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    int normal = 0, gross = 0, low = 0;
    double sum2 = 0;
    Eigen::Vector2d bias = Eigen::Vector2d::Zero();
    std::set<std::uint64_t> ids;
    for (const HexMatch& m : r.matches) {
      const std::uint64_t id = SequenceTrackId(a + 1, m.xa, kW);
      EXPECT_TRUE(ids.insert(id).second) << "duplicate id in pair " << a + 1 << "-" << b + 1;
      if (m.quality <= kLowQuality) {
        ++low;
        continue;
      }
      Eigen::Vector2d truth;
      if (!f.Transfer(a, b, m.xa, &truth)) continue;
      const double e = (m.xb - truth).norm();
      if (e > 1.0) {
        ++gross;
        continue;
      }
      ++normal;
      sum2 += e * e;
      bias += m.xb - truth;
      track_images[id].insert(a);
      track_images[id].insert(b);
      track_xa[{id, b}] = m.xa;
    }
    const double rms = std::sqrt(sum2 / std::max(1, normal));
    std::printf(
        "pair %d-%d: %d candidates, %zu matches (%d low quality), %d normal within 1 px of the "
        "truth, RMS %.3f "
        "px (mean error (%.3f, %.3f)), %d normal beyond 1 px; %.2f s\n",
        a + 1, b + 1, r.summary.candidates, r.matches.size(), low, normal, rms,
        bias.x() / std::max(1, normal), bias.y() / std::max(1, normal), gross, seconds);
    EXPECT_GT(normal, 150);
    EXPECT_LE(gross, 0.01 * (normal + gross));
    EXPECT_LT(rms, 0.2);
    sum2_all += sum2;
    n_all += normal;
  }
  // Tracks of photo 1's points seen in photos 2 and 3 (the same id from the
  // pairs 1-2 and 1-3, from the same interest point xa).
  int three = 0;
  for (const auto& kv : track_images) {
    if (kv.second.size() < 3) continue;
    ++three;
    EXPECT_EQ(kv.first >> 32, 1u);
    EXPECT_EQ((track_xa.at({kv.first, 1}) - track_xa.at({kv.first, 2})).norm(), 0.0);
  }
  std::printf("all pairs: %d normal matches, RMS %.3f px; %d tracks spanning 3 photos\n", n_all,
              std::sqrt(sum2_all / std::max(1, n_all)), three);
  EXPECT_GT(three, 50);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
