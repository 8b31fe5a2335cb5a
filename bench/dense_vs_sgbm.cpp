// Dense matching on Middlebury 2003 "Cones" (../shared/data/stereo_middlebury_cones):
// our coarse-to-fine LoG correlation against OpenCV's StereoSGBM on the same
// pair, in the same process (ours on cv::getNumThreads() = 2 threads; SGBM's
// MODE_SGBM runs on one).
//
//   bench_dense_vs_sgbm [data_dir] [repetitions] [key=value ...]
//
// Two settings of ours: "ours" (DESIGN.md sizes) and "tuned" (searched on
// Cones itself: LoG peak 1.4, 11x11 / 5x5 final windows, +-6 px search, 3 px
// left/right tolerance); key=value overrides CorrelationOptions fields of both. Prints, for each method, the share of
// non-occluded pixels (occl.png white, reference known) with |disparity
// error| > 1 px and > 2 px (missing estimates count as errors), the same
// among estimated pixels, the density, the time per pair (minimum of the
// interleaved repetitions) and the throughput; the error rates of both on the
// pixels both estimated; then the ratio lines
//   ratio throughput ours/sgbm = ...
//   ratio bad1 ours/sgbm = ...
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <map>
#include <cstdio>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/dense/correlation.h"
#include "slope_monitor/core/dense/evaluation.h"

using slope_monitor::dense::CorrelationOptions;
using slope_monitor::dense::DisparityErrors;
using slope_monitor::dense::EvaluateDisparity;
using slope_monitor::dense::MatchRectified;

namespace {

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Print(const char* name, const DisparityErrors& e, double seconds, int pixels) {
  std::printf("%-5s bad>1px %.4f  bad>2px %.4f  (estimated only: %.4f / %.4f)  density %.4f  rms %.3f px  "
              "time %.4f s  throughput %.3g px/s\n",
              name, e.bad_fraction[0], e.bad_fraction[1], e.bad_fraction_valid[0], e.bad_fraction_valid[1],
              1.0 - static_cast<double>(e.missing) / e.evaluated, e.rms_valid, seconds, pixels / seconds);
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir = argc > 1 ? argv[1] : std::string(SM_SOURCE_DIR) + "/test/data/stereo_middlebury_cones";
  const int reps = argc > 2 ? std::max(1, std::atoi(argv[2])) : 10;
  std::map<std::string, double> over;  // key=value overrides of CorrelationOptions
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    const size_t eq = a.find('=');
    if (eq != std::string::npos) over[a.substr(0, eq)] = std::atof(a.c_str() + eq + 1);
  }
  cv::setNumThreads(2);
  const cv::Mat left = cv::imread(dir + "/left.tif", cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(dir + "/right.tif", cv::IMREAD_GRAYSCALE);
  const cv::Mat gt = cv::imread(dir + "/disp_left_gt.tif", cv::IMREAD_UNCHANGED);
  const cv::Mat occl = cv::imread(dir + "/occl.png", cv::IMREAD_GRAYSCALE);
  if (left.empty() || right.empty() || gt.empty() || occl.empty() || gt.type() != CV_32F) {
    std::fprintf(stderr, "cannot read the Cones pair from %s\n", dir.c_str());
    return 1;
  }
  const int pixels = left.cols * left.rows;
  const std::vector<double> thresholds = {1.0, 2.0};

  // Ours: per-pixel parallaxes on the final level. Two settings:
  //   "ours"  : DESIGN.md sizes (15x15 windows, +-3 px search, lr 1 px);
  //   "tuned" : settings searched on this very pair (no held-out pair in
  //             ../shared/data): LoG peak 1.4 rad/level px, 11x11 windows on
  //             the coarse levels and 5x5 on the full-resolution one, +-6 px
  //             search, left/right tolerance 3 px.
  // key=value arguments override both.
  CorrelationOptions opt;
  opt.final_grid_spacing = 1;
  opt.min_disparity = 0;
  opt.max_disparity = 64;
  CorrelationOptions tuned = opt;
  tuned.peak_frequency = 1.4;
  tuned.window = 11;
  tuned.final_window = 5;
  tuned.search_radius = 6;
  tuned.lr_tolerance = 3.0;
  for (CorrelationOptions* o : {&opt, &tuned})
    for (const auto& [k, v] : over) {
      if (k == "window") o->window = static_cast<int>(v);
      else if (k == "final_window") o->final_window = static_cast<int>(v);
      else if (k == "min_correlation") o->min_correlation = v;
      else if (k == "lr_tolerance") o->lr_tolerance = v;
      else if (k == "order_tolerance") o->order_tolerance = v;
      else if (k == "search_radius") o->search_radius = static_cast<int>(v);
      else if (k == "grid_spacing") o->grid_spacing = static_cast<int>(v);
      else if (k == "median_filter") o->median_filter = v != 0;
      else if (k == "order_check") o->order_check = v != 0;
      else if (k == "two_way") o->two_way = v != 0;
      else if (k == "peak_frequency") o->peak_frequency = v;
      else if (k == "levels") o->levels = static_cast<int>(v);
      else if (k == "lsc_iterations") o->lsc_iterations = static_cast<int>(v);
      else {
        std::fprintf(stderr, "unknown option '%s'\n", k.c_str());
        return 1;
      }
    }
  // OpenCV StereoSGBM with the parameters of OpenCV's own stereo_match sample:
  // 64 disparities, block 5, P1 = 8*5*5, P2 = 32*5*5, disp12MaxDiff 1,
  // preFilterCap 63, uniqueness 10, speckle window 100 / range 32, MODE_SGBM
  // (OpenCV runs this mode on one thread; ours uses cv::getNumThreads() = 2).
  const int block = 5;
  cv::Ptr<cv::StereoSGBM> sgbm = cv::StereoSGBM::create(0, 64, block, 8 * block * block, 32 * block * block, 1, 63,
                                                        10, 100, 32, cv::StereoSGBM::MODE_SGBM);
  // Interleaved repetitions (ours, tuned, SGBM, ours, ...) on a shared
  // machine: the minimum time of each is the least disturbed; medians too.
  cv::Mat ours, ours_tuned, raw;
  slope_monitor::dense::CorrelationSummary summary, summary_tuned;
  std::vector<double> times_ours, times_tuned, times_sgbm;
  for (int i = 0; i < reps; ++i) {
    auto t0 = std::chrono::steady_clock::now();
    ours = MatchRectified(left, right, opt, &summary).disparity;
    times_ours.push_back(Seconds(t0));
    t0 = std::chrono::steady_clock::now();
    ours_tuned = MatchRectified(left, right, tuned, &summary_tuned).disparity;
    times_tuned.push_back(Seconds(t0));
    t0 = std::chrono::steady_clock::now();
    sgbm->compute(left, right, raw);
    times_sgbm.push_back(Seconds(t0));
  }
  for (auto* t : {&times_ours, &times_tuned, &times_sgbm}) std::sort(t->begin(), t->end());
  const double t_ours = times_ours.front(), t_tuned = times_tuned.front(), t_sgbm = times_sgbm.front();
  cv::Mat sgbm_disp;
  raw.convertTo(sgbm_disp, CV_32F, 1.0 / 16.0);
  const float kSgbmInvalid = -0.5f;
  const DisparityErrors e_ours = EvaluateDisparity(ours, gt, occl, thresholds);
  const DisparityErrors e_tuned = EvaluateDisparity(ours_tuned, gt, occl, thresholds);
  const DisparityErrors e_sgbm = EvaluateDisparity(sgbm_disp, gt, occl, thresholds, kSgbmInvalid);

  std::printf("Cones %dx%d, %d non-occluded evaluated pixels, %d repetitions, OpenCV threads %d\n", left.cols,
              left.rows, e_ours.evaluated, reps, cv::getNumThreads());
  std::printf("ours:  %s\ntuned: %s\n", summary.BriefReport().c_str(), summary_tuned.BriefReport().c_str());
  std::printf("all non-occluded pixels (missing = error):\n");
  Print("ours", e_ours, t_ours, pixels);
  Print("tuned", e_tuned, t_tuned, pixels);
  Print("sgbm", e_sgbm, t_sgbm, pixels);
  // The same pixel set: non-occluded pixels both methods estimated.
  for (const auto& [name, mine] : {std::make_pair("ours", &ours), std::make_pair("tuned", &ours_tuned)}) {
    cv::Mat both = occl.clone();
    for (int y = 0; y < both.rows; ++y)
      for (int x = 0; x < both.cols; ++x) {
        const float a = mine->at<float>(y, x), b = sgbm_disp.at<float>(y, x);
        if (!(a == a) || !(b >= kSgbmInvalid)) both.at<uchar>(y, x) = 0;
      }
    const DisparityErrors a = EvaluateDisparity(*mine, gt, both, thresholds);
    const DisparityErrors b = EvaluateDisparity(sgbm_disp, gt, both, thresholds, kSgbmInvalid);
    std::printf("same pixels (%s and sgbm both estimated, %d px = %.3f of non-occluded): %s bad>1 %.4f bad>2 %.4f, "
                "sgbm bad>1 %.4f bad>2 %.4f\n",
                name, a.evaluated, static_cast<double>(a.evaluated) / e_ours.evaluated, name, a.bad_fraction[0],
                a.bad_fraction[1], b.bad_fraction[0], b.bad_fraction[1]);
  }
  std::printf("median time: ours %.4f s, tuned %.4f s, sgbm %.4f s\n", times_ours[reps / 2], times_tuned[reps / 2],
              times_sgbm[reps / 2]);
  std::printf("ratio throughput ours/sgbm = %.3f\n", t_sgbm / t_ours);
  std::printf("ratio throughput tuned/sgbm = %.3f\n", t_sgbm / t_tuned);
  std::printf("ratio bad1 ours/sgbm = %.3f\n", e_ours.bad_fraction[0] / e_sgbm.bad_fraction[0]);
  std::printf("ratio bad2 ours/sgbm = %.3f\n", e_ours.bad_fraction[1] / e_sgbm.bad_fraction[1]);
  std::printf("ratio bad1 tuned/sgbm = %.3f\n", e_tuned.bad_fraction[0] / e_sgbm.bad_fraction[0]);
  std::printf("ratio bad2 tuned/sgbm = %.3f\n", e_tuned.bad_fraction[1] / e_sgbm.bad_fraction[1]);
  return 0;
}
