// Benchmark: our hexagonal matcher + MLSC against OpenCV ORB and SIFT (each
// with the ratio test 0.8 and RANSAC), on the same image pairs in one process:
//   * Cones left image and a synthetic affine warp of it (truth: the warp);
//   * the real rectified Cones pair (truth: ground-truth disparity, y = 0;
//     only points with known disparity outside occlusions are scored).
// A match is correct when it is within 1 px of the truth. Prints per method
// the number of matches, correct matches, precision, mean error of correct
// matches and CPU time (single thread, median of 5 after a warm-up), and
// ratios ours/ORB and ours/SIFT. "ours" = defaults
// (every match, low-quality ones included), "ours_q" = its normal-quality
// matches only, "ours_0" = quality control off (its time cost).
//   bench_matching_vs_opencv [data_dir]   (default test/data/stereo_middlebury_cones)
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/matching/filters.h"
#include "slope_monitor/core/matching/hex_matcher.h"

using namespace slope_monitor::matching;

namespace {

// CPU time of the process [s]: on a shared machine, wall time measures the
// other users' load as much as ours. OpenCV runs on one thread
// (cv::setNumThreads(1) in main), like our matcher, so CPU time compares
// the work per core.
double CpuSeconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

struct Pair {
  std::string name;
  cv::Mat a, b;  // CV_8U
  // Returns false when no truth exists at xa; else the true xb.
  std::function<bool(const cv::Point2d&, cv::Point2d*)> truth;
  bool rectified = false;
  MatchPrior prior;
};

struct Score {
  int matches = 0, correct = 0, scored = 0;
  double err_sum = 0, seconds = 0;
};

Score Evaluate(const Pair& p, const std::vector<cv::Point2d>& xa,
               const std::vector<cv::Point2d>& xb, double s) {
  Score sc;
  sc.seconds = s;
  sc.matches = static_cast<int>(xa.size());
  for (size_t i = 0; i < xa.size(); ++i) {
    cv::Point2d t;
    if (!p.truth(xa[i], &t)) continue;
    ++sc.scored;
    const double e = cv::norm(xb[i] - t);
    if (e <= 1.0) {
      ++sc.correct;
      sc.err_sum += e;
    }
  }
  return sc;
}

Score RunOpenCv(const Pair& p, cv::Ptr<cv::Feature2D> f, int norm) {
  const double t0 = CpuSeconds();
  std::vector<cv::KeyPoint> ka, kb;
  cv::Mat da, db;
  f->detectAndCompute(p.a, cv::noArray(), ka, da);
  f->detectAndCompute(p.b, cv::noArray(), kb, db);
  cv::BFMatcher bf(norm);
  std::vector<std::vector<cv::DMatch>> knn;
  if (!da.empty() && !db.empty()) bf.knnMatch(da, db, knn, 2);
  std::vector<cv::Point2f> pa, pb;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
      pa.push_back(ka[m[0].queryIdx].pt);
      pb.push_back(kb[m[0].trainIdx].pt);
    }
  std::vector<uchar> inl;
  if (pa.size() >= 8) {
    if (p.rectified) {
      cv::findFundamentalMat(pa, pb, cv::FM_RANSAC, 1.0, 0.999, inl);
    } else {
      cv::estimateAffine2D(pa, pb, inl, cv::RANSAC, 1.0);
    }
  }
  std::vector<cv::Point2d> xa, xb;
  for (size_t i = 0; i < inl.size(); ++i)
    if (inl[i]) {
      xa.emplace_back(pa[i]);
      xb.emplace_back(pb[i]);
    }
  const double s = CpuSeconds() - t0;
  return Evaluate(p, xa, xb, s);
}

// Our matcher with the defaults (quality control on, low-quality matches
// kept and marked). normal_only: score only the matches of normal quality;
// !quality_control: the matcher without quality control (its time cost).
Score RunOurs(const Pair& p, bool quality_control = true, bool normal_only = false,
              bool print_flags = true) {
  const double t0 = CpuSeconds();
  HexMatcherOptions o;
  o.quality.enabled = quality_control;
  const HexMatcher m(o);
  const HexMatchResult r = m.Match(p.a, p.b, p.prior);
  if (quality_control && !normal_only && print_flags) {
    std::printf("%-22s ours   low quality %d of %d:", p.name.c_str(), r.summary.low_quality,
                r.summary.matched);
    for (const auto& kv : r.summary.flags) std::printf(" %s %d", kv.first.c_str(), kv.second);
    std::printf("\n");
  }
  std::vector<cv::Point2d> xa, xb;
  for (const HexMatch& h : r.matches) {
    if (normal_only && h.IsLowQuality()) continue;
    xa.emplace_back(h.xa.x(), h.xa.y());
    xb.emplace_back(h.xb.x(), h.xb.y());
  }
  const double s = CpuSeconds() - t0;
  return Evaluate(p, xa, xb, s);
}

void Print(const char* pair, const char* method, const Score& s) {
  std::printf(
      "%-22s %-6s matches %5d  correct %5d  precision %.3f  mean_err %.3f px  time %.3f s\n", pair,
      method, s.matches, s.correct, s.scored ? double(s.correct) / s.scored : 0.0,
      s.correct ? s.err_sum / s.correct : 0.0, s.seconds);
}

}  // namespace

int main(int argc, char** argv) {
  cv::setNumThreads(1);
  const std::string dir =
      argc > 1 ? argv[1] : std::string(SM_SOURCE_DIR) + "/test/data/stereo_middlebury_cones";
  const cv::Mat left = cv::imread(dir + "/left.tif", cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(dir + "/right.tif", cv::IMREAD_GRAYSCALE);
  const cv::Mat gt = cv::imread(dir + "/disp_left_gt.tif", cv::IMREAD_UNCHANGED);
  const cv::Mat occl = cv::imread(dir + "/occl.png", cv::IMREAD_UNCHANGED);
  if (left.empty() || right.empty() || gt.empty() || occl.empty()) {
    std::fprintf(stderr, "cannot read the Cones set from %s\n", dir.c_str());
    return 1;
  }
  std::vector<Pair> pairs;
  {
    Pair p;
    p.name = "cones_affine_warp";
    const double c = 1.03 * std::cos(0.05), s = 1.03 * std::sin(0.05);
    const cv::Matx23d m(c, -s, 6.4, s, c, -3.7);
    p.a = left;
    cv::warpAffine(left, p.b, cv::Mat(m), left.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT_101);
    p.truth = [m, w = left.cols, h = left.rows](const cv::Point2d& x, cv::Point2d* t) {
      *t = cv::Point2d(m(0, 0) * x.x + m(0, 1) * x.y + m(0, 2),
                       m(1, 0) * x.x + m(1, 1) * x.y + m(1, 2));
      return t->x > 2 && t->y > 2 && t->x < w - 3 && t->y < h - 3;
    };
    p.prior.radius = 30;
    pairs.push_back(p);
  }
  {
    Pair p;
    p.name = "cones_real_rectified";
    p.a = left;
    p.b = right;
    p.rectified = true;
    p.truth = [gt, occl](const cv::Point2d& x, cv::Point2d* t) {
      const int c = int(std::lround(x.x)), r = int(std::lround(x.y));
      if (c < 0 || r < 0 || c >= gt.cols || r >= gt.rows) return false;
      const float d = gt.at<float>(r, c);
      if (d <= 0 || occl.at<uint8_t>(r, c) == 0) return false;
      *t = cv::Point2d(x.x - d, x.y);
      return true;
    };
    p.prior.shift = Eigen::Vector2d(-35, 0);
    p.prior.radius = 36;
    p.prior.has_epipolar = true;
    p.prior.fundamental << 0, 0, 0, 0, 0, -1, 0, 1, 0;
    p.prior.epipolar_band = 1.5;
    pairs.push_back(p);
  }
  // Each method runs kRepeats times after one untimed warm-up of all of
  // them (first-call costs: library loading, page faults); the median time
  // is reported (the machine is shared: single runs vary by up to 2x).
  constexpr int kRepeats = 5;
  auto median_of = [&](const std::function<Score()>& run) {
    std::vector<Score> runs;
    for (int i = 0; i < kRepeats; ++i) runs.push_back(run());
    std::sort(runs.begin(), runs.end(),
              [](const Score& a, const Score& b) { return a.seconds < b.seconds; });
    return runs[kRepeats / 2];
  };
  for (const Pair& p : pairs) {
    RunOurs(p, false);
    RunOpenCv(p, cv::ORB::create(2000), cv::NORM_HAMMING);
    RunOpenCv(p, cv::SIFT::create(2000), cv::NORM_L2);
    RunOurs(p);  // prints the quality flags once
    const Score ours = median_of([&] { return RunOurs(p, true, false, false); });
    const Score ours_normal = median_of([&] { return RunOurs(p, true, true); });
    const Score ours_no_qc = median_of([&] { return RunOurs(p, false); });
    const Score orb =
        median_of([&] { return RunOpenCv(p, cv::ORB::create(2000), cv::NORM_HAMMING); });
    const Score sift = median_of([&] { return RunOpenCv(p, cv::SIFT::create(2000), cv::NORM_L2); });
    Print(p.name.c_str(), "ours", ours);
    Print(p.name.c_str(), "ours_q", ours_normal);  // normal quality only
    Print(p.name.c_str(), "ours_0", ours_no_qc);   // quality control off
    Print(p.name.c_str(), "orb", orb);
    Print(p.name.c_str(), "sift", sift);
    auto ratio = [](double a, double b) { return b > 0 ? a / b : 0.0; };
    std::printf("%s ratio ours/orb: correct %.2f time %.2f; ours/sift: correct %.2f time %.2f\n",
                p.name.c_str(), ratio(ours.correct, orb.correct), ratio(ours.seconds, orb.seconds),
                ratio(ours.correct, sift.correct), ratio(ours.seconds, sift.seconds));
  }
  return 0;
}
