// LoG band-pass for the dense matcher: separable spatial filter
// (matching::LaplacianOfGaussian) against the FFT implementation
// (dense::LaplacianOfGaussianFft), on the Cones left image and on a 4x tiled
// copy, at the three levels' sigma (peak 1 rad/px: sigma = sqrt(2)) and at the
// full-resolution sigma of the coarser bands (2.83, 5.66 px).
//
//   bench_dense_log_filter [image] [repetitions]
//
// Prints time per call of both and `ratio fft/separable = ...` (speed: > 1
// means the FFT is faster) and the largest absolute difference relative to
// the response range.
#include <chrono>
#include <cstdio>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/dense/log_fft.h"
#include "slope_monitor/core/matching/filters.h"

int main(int argc, char** argv) {
  const std::string path =
      argc > 1 ? argv[1]
               : std::string(SM_SOURCE_DIR) + "/test/data/stereo_middlebury_cones/left.tif";
  const int reps = argc > 2 ? std::atoi(argv[2]) : 10;
  cv::setNumThreads(2);
  const cv::Mat small = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (small.empty()) {
    std::fprintf(stderr, "cannot read %s\n", path.c_str());
    return 1;
  }
  cv::Mat big;
  cv::repeat(small, 2, 2, big);
  for (const cv::Mat* im :
       {static_cast<const cv::Mat*>(&small), static_cast<const cv::Mat*>(&big)}) {
    const cv::Mat f = slope_monitor::matching::ToFloat(*im);
    for (double sigma : {std::sqrt(2.0), 2.0 * std::sqrt(2.0), 4.0 * std::sqrt(2.0)}) {
      cv::Mat a, b;
      auto t0 = std::chrono::steady_clock::now();
      for (int i = 0; i < reps; ++i) a = slope_monitor::matching::LaplacianOfGaussian(f, sigma);
      const double ts =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / reps;
      t0 = std::chrono::steady_clock::now();
      for (int i = 0; i < reps; ++i) b = slope_monitor::dense::LaplacianOfGaussianFft(f, sigma);
      const double tf =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / reps;
      double lo, hi, diff;
      cv::minMaxLoc(a, &lo, &hi);
      diff = cv::norm(a, b, cv::NORM_INF);
      std::printf("%dx%d sigma %.3f: separable %.5f s, fft %.5f s, max |diff| / range %.4f\n",
                  im->cols, im->rows, sigma, ts, tf, diff / (hi - lo));
      std::printf("ratio fft/separable (speed) %dx%d sigma %.2f = %.3f\n", im->cols, im->rows,
                  sigma, ts / tf);
    }
  }
  return 0;
}
