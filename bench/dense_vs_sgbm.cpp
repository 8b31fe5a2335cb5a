// Dense matching on Middlebury 2003 "Cones" (../shared/data/stereo_middlebury_cones):
// our coarse-to-fine LoG correlation against OpenCV's StereoSGBM on the same
// pair, in the same process (ours on cv::getNumThreads() = 2 threads; SGBM's
// MODE_SGBM runs on one).
//
//   bench_dense_vs_sgbm [data_dir] [repetitions] [config=FILE|none] [fill_gap=N] [threads=N]
//   [key=value ...]
//
// Two settings of ours: "ours" = config/dense_cones.yaml (config=FILE: another
// dense_matcher parameter file; none: the CorrelationOptions defaults) with a
// per-pixel final grid, its disparity map's holes filled from the background
// side (FillFromBackground; fill_gap=0: not filled), and "design" = the plain
// doc/design.md method (15x15 windows, +-3 px search, lr 1 px, second right->left
// search, no edge window, no fill) for comparison; key=value overrides
// CorrelationOptions fields of "ours". Prints, for each
// method, the share of non-occluded pixels (occl.png white, reference known)
// with |disparity error| > 1 px and > 2 px (missing estimates count as
// errors), the same among estimated pixels, the density, the times per pair
// (minimum and median of the interleaved repetitions) and the throughput; a
// per-cause breakdown of the errors (near depth discontinuities, textureless,
// elsewhere; missing vs wrong); the error rates on the pixels both estimated;
// then the ratio lines
//   ratio throughput ours/sgbm = ...   (minimum times)
//   ratio bad1 ours/sgbm = ...
//   ratio bad2 ours/sgbm = ...
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/dense/correlation.h"
#include "slope_monitor/core/dense/evaluation.h"
#include "slope_monitor/core/dense/options_yaml.h"

using slope_monitor::dense::CorrelationOptions;
using slope_monitor::dense::DisparityErrors;
using slope_monitor::dense::EvaluateDisparity;
using slope_monitor::dense::FillFromBackground;
using slope_monitor::dense::MatchRectified;

namespace {

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// CPU time of the process (all threads) [s]: less disturbed by other
// processes on a shared machine than the wall time.
double CpuSeconds() {
  rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

void Print(const char* name, const DisparityErrors& e, double t_min, double t_median, int pixels) {
  std::printf(
      "%-6s bad>1px %.4f  bad>2px %.4f  (estimated only: %.4f / %.4f)  density %.4f  rms %.3f px  "
      "time min %.4f s median %.4f s  throughput %.3g px/s\n",
      name, e.bad_fraction[0], e.bad_fraction[1], e.bad_fraction_valid[0], e.bad_fraction_valid[1],
      1.0 - static_cast<double>(e.missing) / e.evaluated, e.rms_valid, t_min, t_median,
      pixels / t_min);
}

// Middlebury-style regions of the evaluated (non-occluded, known) pixels:
//   disc: within 4 px (9 x 9 box) of a depth discontinuity of the reference
//         (neighbouring reference disparities differ by > 2 px, or an
//         occluded / unknown neighbour);
//   textureless: not disc, squared horizontal intensity gradient averaged
//         over 3 x 3 below 4 (grey levels^2);
//   other: the rest.
// Per region: pixels, missing, wrong (> 1 px among estimated).
struct Regions {
  cv::Mat disc, textureless, other;  // CV_8U 255 = in region (evaluated pixels only)
};

Regions MakeRegions(const cv::Mat& left, const cv::Mat& gt, const cv::Mat& occl) {
  cv::Mat edge(gt.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < gt.rows; ++y)
    for (int x = 0; x < gt.cols; ++x) {
      const float d = gt.at<float>(y, x);
      for (auto [dx, dy] : {std::pair{1, 0}, std::pair{0, 1}}) {
        const int xx = x + dx, yy = y + dy;
        if (xx >= gt.cols || yy >= gt.rows) continue;
        const float e = gt.at<float>(yy, xx);
        if (std::abs(d - e) > 2.0f) edge.at<uchar>(y, x) = edge.at<uchar>(yy, xx) = 255;
      }
    }
  cv::Mat disc;
  cv::dilate(edge, disc, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(9, 9)));
  cv::Mat f, gx, g2, tl;
  left.convertTo(f, CV_32F);
  gx = cv::Mat::zeros(f.size(), CV_32F);
  for (int y = 0; y < f.rows; ++y)
    for (int x = 0; x + 1 < f.cols; ++x)
      gx.at<float>(y, x) = f.at<float>(y, x + 1) - f.at<float>(y, x);
  cv::multiply(gx, gx, g2);
  cv::blur(g2, g2, cv::Size(3, 3));
  cv::compare(g2, 4.0, tl, cv::CMP_LT);
  cv::Mat known;
  cv::compare(gt, 0.0, known, cv::CMP_GT);
  cv::Mat eval = known & (occl > 0);
  Regions r;
  r.disc = disc & eval;
  r.textureless = tl & eval & ~disc;
  r.other = eval & ~disc & ~tl;
  return r;
}

void PrintBreakdown(const char* name, const cv::Mat& est, const cv::Mat& gt, const Regions& regions,
                    float invalid_below, int evaluated) {
  std::printf("%-6s", name);
  for (auto [rname, mask] :
       {std::pair{"disc", &regions.disc}, std::pair{"textureless", &regions.textureless},
        std::pair{"other", &regions.other}}) {
    const DisparityErrors e = EvaluateDisparity(est, gt, *mask, {1.0}, invalid_below);
    const int wrong = static_cast<int>(e.bad_fraction[0] * e.evaluated + 0.5) - e.missing;
    std::printf("  %s %d px: missing %.4f wrong %.4f (of all: %.4f + %.4f)", rname, e.evaluated,
                static_cast<double>(e.missing) / e.evaluated,
                static_cast<double>(wrong) / e.evaluated,
                static_cast<double>(e.missing) / evaluated, static_cast<double>(wrong) / evaluated);
  }
  std::printf("\n");
}

bool Apply(CorrelationOptions* o, const std::string& k, double v) {
  if (k == "window")
    o->window = static_cast<int>(v);
  else if (k == "final_window")
    o->final_window = static_cast<int>(v);
  else if (k == "edge_window")
    o->edge_window = static_cast<int>(v);
  else if (k == "edge_parallax_step")
    o->edge_parallax_step = v;
  else if (k == "min_correlation")
    o->min_correlation = v;
  else if (k == "lr_tolerance")
    o->lr_tolerance = v;
  else if (k == "order_tolerance")
    o->order_tolerance = v;
  else if (k == "search_radius")
    o->search_radius = static_cast<int>(v);
  else if (k == "final_search_radius")
    o->final_search_radius = static_cast<int>(v);
  else if (k == "grid_spacing")
    o->grid_spacing = static_cast<int>(v);
  else if (k == "median_filter")
    o->median_filter = v != 0;
  else if (k == "order_check")
    o->order_check = v != 0;
  else if (k == "two_way")
    o->two_way = v != 0;
  else if (k == "full_right_search")
    o->full_right_search = v != 0;
  else if (k == "peak_frequency")
    o->peak_frequency = v;
  else if (k == "levels")
    o->levels = static_cast<int>(v);
  else if (k == "lsc_iterations")
    o->lsc_iterations = static_cast<int>(v);
  else
    return false;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string dir =
      argc > 1 ? argv[1] : std::string(SM_SOURCE_DIR) + "/test/data/stereo_middlebury_cones";
  const int reps = argc > 2 ? std::max(1, std::atoi(argv[2])) : 10;
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

  // "ours": config/dense_cones.yaml (or config=FILE), per-pixel parallaxes
  // on the final level, the search range of the pair (0..64 px), the holes
  // of the disparity map filled from the background (fill_gap=N: runs up to
  // N px; 0: none).
  CorrelationOptions opt;
  opt.final_grid_spacing = 1;
  opt.min_disparity = 0;
  opt.max_disparity = 64;
  std::string config = std::string(SM_SOURCE_DIR) + "/config/dense_cones.yaml";
  int fill_gap = left.cols;
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    const size_t eq = a.find('=');
    if (eq != std::string::npos && a.substr(0, eq) == "config") config = a.substr(eq + 1);
  }
  try {
    if (config != "none") slope_monitor::dense::ReadCorrelationOptions(config, &opt);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  for (int i = 3; i < argc; ++i) {
    const std::string a = argv[i];
    const size_t eq = a.find('=');
    if (eq != std::string::npos && a.substr(0, eq) == "config") continue;
    if (eq != std::string::npos && a.substr(0, eq) == "threads") {
      cv::setNumThreads(std::max(1, std::atoi(a.c_str() + eq + 1)));
      continue;
    }
    if (eq != std::string::npos && a.substr(0, eq) == "fill_gap") {
      fill_gap = std::atoi(a.c_str() + eq + 1);
      continue;
    }
    if (eq == std::string::npos || !Apply(&opt, a.substr(0, eq), std::atof(a.c_str() + eq + 1))) {
      std::fprintf(stderr, "bad option '%s' (key=value of a CorrelationOptions field)\n",
                   a.c_str());
      return 1;
    }
  }
  // "design": the plain doc/design.md method (the edge-aware steps off).
  CorrelationOptions design;
  design.final_grid_spacing = 1;
  design.min_disparity = 0;
  design.max_disparity = 64;
  design.window = 15;
  design.final_window = 0;
  design.edge_window = 0;
  design.search_radius = 3;
  design.lr_tolerance = 1.0;
  design.full_right_search = true;
  design.peak_frequency = 1.0;
  // OpenCV StereoSGBM with the parameters of OpenCV's own stereo_match sample:
  // 64 disparities, block 5, P1 = 8*5*5, P2 = 32*5*5, disp12MaxDiff 1,
  // preFilterCap 63, uniqueness 10, speckle window 100 / range 32, MODE_SGBM
  // (OpenCV runs this mode on one thread; ours uses cv::getNumThreads() = 2).
  const int block = 5;
  cv::Ptr<cv::StereoSGBM> sgbm =
      cv::StereoSGBM::create(0, 64, block, 8 * block * block, 32 * block * block, 1, 63, 10, 100,
                             32, cv::StereoSGBM::MODE_SGBM);
  // Interleaved repetitions (ours, SGBM, design, ...) on a shared machine:
  // the minimum time of each is the least disturbed; medians too.
  cv::Mat ours, ours_raw, ours_design, raw;
  slope_monitor::dense::CorrelationSummary summary, summary_design;
  std::vector<double> times_ours, times_design, times_sgbm;
  std::vector<double> cpu_ours, cpu_design, cpu_sgbm;
  for (int i = 0; i < reps; ++i) {
    double c0 = CpuSeconds();
    auto t0 = std::chrono::steady_clock::now();
    ours_raw = MatchRectified(left, right, opt, &summary).disparity;
    ours_raw.copyTo(ours);  // into the buffer of the previous repetition
    if (fill_gap > 0) slope_monitor::dense::FillFromBackgroundInPlace(&ours, fill_gap);
    times_ours.push_back(Seconds(t0));
    cpu_ours.push_back(CpuSeconds() - c0);
    c0 = CpuSeconds();
    t0 = std::chrono::steady_clock::now();
    sgbm->compute(left, right, raw);
    times_sgbm.push_back(Seconds(t0));
    cpu_sgbm.push_back(CpuSeconds() - c0);
    c0 = CpuSeconds();
    t0 = std::chrono::steady_clock::now();
    ours_design = MatchRectified(left, right, design, &summary_design).disparity;
    times_design.push_back(Seconds(t0));
    cpu_design.push_back(CpuSeconds() - c0);
  }
  for (auto* t : {&times_ours, &times_design, &times_sgbm, &cpu_ours, &cpu_design, &cpu_sgbm})
    std::sort(t->begin(), t->end());
  const double t_ours = times_ours.front(), t_design = times_design.front(),
               t_sgbm = times_sgbm.front();
  cv::Mat sgbm_disp;
  raw.convertTo(sgbm_disp, CV_32F, 1.0 / 16.0);
  const float kSgbmInvalid = -0.5f;
  const DisparityErrors e_ours = EvaluateDisparity(ours, gt, occl, thresholds);
  const DisparityErrors e_design = EvaluateDisparity(ours_design, gt, occl, thresholds);
  const DisparityErrors e_sgbm = EvaluateDisparity(sgbm_disp, gt, occl, thresholds, kSgbmInvalid);

  std::printf("Cones %dx%d, %d non-occluded evaluated pixels, %d repetitions, OpenCV threads %d\n",
              left.cols, left.rows, e_ours.evaluated, reps, cv::getNumThreads());
  std::printf("ours:   %s\ndesign: %s\n", summary.BriefReport().c_str(),
              summary_design.BriefReport().c_str());
  std::printf("all non-occluded pixels (missing = error):\n");
  Print("ours", e_ours, t_ours, times_ours[reps / 2], pixels);
  if (fill_gap > 0) {
    const DisparityErrors e_raw = EvaluateDisparity(ours_raw, gt, occl, thresholds);
    std::printf(
        "ours before the background fill (gap <= %d px): bad>1px %.4f  bad>2px %.4f  (estimated "
        "only: %.4f / "
        "%.4f)  density %.4f\n",
        fill_gap, e_raw.bad_fraction[0], e_raw.bad_fraction[1], e_raw.bad_fraction_valid[0],
        e_raw.bad_fraction_valid[1], 1.0 - static_cast<double>(e_raw.missing) / e_raw.evaluated);
  }
  Print("design", e_design, t_design, times_design[reps / 2], pixels);
  Print("sgbm", e_sgbm, t_sgbm, times_sgbm[reps / 2], pixels);
  {
    // For reference only (not the baseline): SGBM's holes filled the same way.
    cv::Mat s = sgbm_disp.clone();
    s.setTo(std::numeric_limits<float>::quiet_NaN(), sgbm_disp < kSgbmInvalid);
    const DisparityErrors e =
        EvaluateDisparity(FillFromBackground(s, left.cols), gt, occl, thresholds);
    std::printf(
        "sgbm with its holes filled from the background like ours (reference, not timed): bad>1px "
        "%.4f  "
        "bad>2px %.4f  density %.4f\n",
        e.bad_fraction[0], e.bad_fraction[1], 1.0 - static_cast<double>(e.missing) / e.evaluated);
  }
  const Regions regions = MakeRegions(left, gt, occl);
  std::printf(
      "errors > 1 px by cause (share of the region's pixels; in brackets share of all evaluated "
      "pixels):\n");
  PrintBreakdown("ours", ours, gt, regions, -1e30f, e_ours.evaluated);
  PrintBreakdown("design", ours_design, gt, regions, -1e30f, e_ours.evaluated);
  PrintBreakdown("sgbm", sgbm_disp, gt, regions, kSgbmInvalid, e_ours.evaluated);
  // The same pixel set: non-occluded pixels both methods estimated (ours before the fill).
  for (const auto& [name, mine] :
       {std::make_pair("ours", &ours_raw), std::make_pair("design", &ours_design)}) {
    cv::Mat both = occl.clone();
    for (int y = 0; y < both.rows; ++y)
      for (int x = 0; x < both.cols; ++x) {
        const float a = mine->at<float>(y, x), b = sgbm_disp.at<float>(y, x);
        if (!(a == a) || !(b >= kSgbmInvalid)) both.at<uchar>(y, x) = 0;
      }
    const DisparityErrors a = EvaluateDisparity(*mine, gt, both, thresholds);
    const DisparityErrors b = EvaluateDisparity(sgbm_disp, gt, both, thresholds, kSgbmInvalid);
    std::printf(
        "same pixels (%s and sgbm both estimated, %d px = %.3f of non-occluded): %s bad>1 %.4f "
        "bad>2 %.4f, "
        "sgbm bad>1 %.4f bad>2 %.4f\n",
        name, a.evaluated, static_cast<double>(a.evaluated) / e_ours.evaluated, name,
        a.bad_fraction[0], a.bad_fraction[1], b.bad_fraction[0], b.bad_fraction[1]);
  }
  std::printf("cpu time per pair (median, all threads): ours %.4f s, design %.4f s, sgbm %.4f s\n",
              cpu_ours[reps / 2], cpu_design[reps / 2], cpu_sgbm[reps / 2]);
  std::printf("ratio throughput ours/sgbm = %.3f   (median times: %.3f)\n", t_sgbm / t_ours,
              times_sgbm[reps / 2] / times_ours[reps / 2]);
  std::printf("ratio bad1 ours/sgbm = %.3f\n", e_ours.bad_fraction[0] / e_sgbm.bad_fraction[0]);
  std::printf("ratio bad2 ours/sgbm = %.3f\n", e_ours.bad_fraction[1] / e_sgbm.bad_fraction[1]);
  std::printf("ratio throughput design/sgbm = %.3f\n", t_sgbm / t_design);
  std::printf("ratio bad1 design/sgbm = %.3f\n", e_design.bad_fraction[0] / e_sgbm.bad_fraction[0]);
  return 0;
}
