// Benchmark: tie points between real full-size UAV photos (4608 x 3456, the
// snowpeak survey in ../shared/data/uav_real_snowpeak) by the package's photo
// pair matcher (photo_pair_matcher.h, defaults) against, on the same pairs in
// the same process:
//   * OpenCV SIFT (all features, full resolution: its best configuration),
//     FLANN 2-NN, ratio 0.8, RANSAC fundamental matrix (1 px);
//   * OpenCV ORB (10000 features), brute-force Hamming 2-NN, ratio 0.8, the
//     same RANSAC.
// Per pair and method: tie points (RANSAC inliers for the baselines; ours
// after its own screening at the same 1 px), epipolar RMS (EpipolarRms: the
// same RANSAC fundamental fit for all), wall time per pair including the
// features of both photos (ours also without them: "match"), and the ratios
// ours/SIFT and ours/ORB. OpenCV runs with its default threads (its best);
// our matcher runs on one thread. Decoding the JPEGs is not timed. A line
// under each pair: ours with the UAV sequence matcher's options.
//   bench_uav_pair_matching [data_dir]   (default ../shared/data/uav_real_snowpeak)
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/matching/photo_pair_matcher.h"
#include "slope_monitor/core/matching/sequence_matcher.h"

using namespace slope_monitor::matching;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct Result {
  int n = 0;
  double rms = 0.0, seconds = 0.0;
};

Result RunOpenCv(const cv::Mat& a, const cv::Mat& b, cv::Ptr<cv::Feature2D> f,
                 cv::Ptr<cv::DescriptorMatcher> m) {
  const double t0 = Now();
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  f->detectAndCompute(a, cv::noArray(), ka, da);
  f->detectAndCompute(b, cv::noArray(), kb, db);
  std::vector<std::vector<cv::DMatch>> knn;
  m->knnMatch(da, db, knn, 2);
  std::vector<cv::Point2f> pa, pb;
  for (const auto& k : knn) {
    if (k.size() == 2 && k[0].distance < 0.8f * k[1].distance) {
      pa.push_back(ka[k[0].queryIdx].pt);
      pb.push_back(kb[k[0].trainIdx].pt);
    }
  }
  std::vector<unsigned char> inliers;
  Result r;
  r.rms = EpipolarRms(pa, pb, 1.0, &inliers);
  r.seconds = Now() - t0;
  for (unsigned char c : inliers) r.n += c;
  return r;
}

double Ratio(double x, double y) { return y > 0 ? x / y : INFINITY; }

}  // namespace

int main(int argc, char** argv) {
  const std::string dir =
      argc > 1 ? argv[1] : std::string(SM_SOURCE_DIR) + "/../shared/data/uav_real_snowpeak";
  // Overlapping pairs first (2213/2244 across a turn, 2212/2244 the same
  // direction), then the pairs the data README names (see doc/uav_real_matching.md).
  const std::vector<std::pair<std::string, std::string>> pairs = {{"IMG_2213", "IMG_2244"},
                                                                  {"IMG_2212", "IMG_2244"},
                                                                  {"IMG_2212", "IMG_2213"},
                                                                  {"IMG_2171", "IMG_2186"},
                                                                  {"IMG_2168", "IMG_2171"}};
  std::printf("%-19s | %-31s | %-24s | %-24s | ours/SIFT: time count rms | ours/ORB: time count\n",
              "pair", "ours: n rms[px] t[s] (match)", "SIFT: n rms[px] t[s]",
              "ORB: n rms[px] t[s]");
  for (const auto& [na, nb] : pairs) {
    const cv::Mat a = cv::imread(dir + "/" + na + ".JPG", cv::IMREAD_COLOR);
    const cv::Mat b = cv::imread(dir + "/" + nb + ".JPG", cv::IMREAD_COLOR);
    if (a.empty() || b.empty()) {
      std::fprintf(stderr, "bench_uav_pair_matching: cannot read %s/%s.JPG or %s.JPG\n",
                   dir.c_str(), na.c_str(), nb.c_str());
      return 1;
    }
    cv::Mat ga, gb;
    cv::cvtColor(a, ga, cv::COLOR_BGR2GRAY);
    cv::cvtColor(b, gb, cv::COLOR_BGR2GRAY);

    const double t0 = Now();
    const PhotoFeatureOptions fo;
    const PhotoFeatures fa(a, na, fo), fb(b, nb, fo);
    const PhotoPairResult r = MatchPhotoPair(fa, fb, PhotoPairOptions());
    Result ours;
    ours.seconds = Now() - t0;
    ours.n = r.summary.matched;
    ours.rms = r.summary.epipolar_rms;

    const Result sift = RunOpenCv(ga, gb, cv::SIFT::create(), cv::FlannBasedMatcher::create());
    const Result orb =
        RunOpenCv(ga, gb, cv::ORB::create(10000), cv::BFMatcher::create(cv::NORM_HAMMING, false));
    std::printf(
        "%-8s %-10s | %5d %6.3f %6.2f (%5.2f)      | %5d %6.3f %6.2f       | %5d %6.3f %6.2f       "
        "|"
        " %6.3f %6.2f %6.2f         | %6.3f %6.2f\n",
        na.c_str(), nb.c_str(), ours.n, ours.rms, ours.seconds, r.summary.seconds, sift.n, sift.rms,
        sift.seconds, orb.n, orb.rms, orb.seconds, Ratio(ours.seconds, sift.seconds),
        Ratio(ours.n, sift.n), Ratio(ours.rms, sift.rms), Ratio(ours.seconds, orb.seconds),
        Ratio(ours.n, orb.n));
    std::printf(
        "    ours: coarse %d ratio matches, %d consistent, %d inliers, rotation %.1f deg, %d "
        "candidates%s%s\n",
        r.summary.coarse_matches, r.summary.coarse_consistent, r.summary.coarse_inliers,
        r.summary.rotation_deg, r.summary.candidates, r.summary.message.empty() ? "" : "; ",
        r.summary.message.c_str());
    // The same pair with the UAV sequence matcher's options (hex_matcher,
    // mode sequence; process_bag --uav-tie-points).
    const double t1 = Now();
    const SequenceMatcherOptions so;
    const PhotoFeatures sa(a, na, so.photo), sb(b, nb, so.photo);
    const PhotoPairSummary ss = MatchPhotoPair(sa, sb, so.photo_pair).summary;
    std::printf(
        "    sequence options: %d tie points, epipolar rms %.3f px, %.2f s (match %.2f s)%s%s\n",
        ss.matched, ss.epipolar_rms, Now() - t1, ss.seconds, ss.message.empty() ? "" : "; ",
        ss.message.c_str());
    std::fflush(stdout);
  }
  return 0;
}
