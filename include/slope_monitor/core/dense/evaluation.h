// Disparity error statistics against a reference (Middlebury-style).
//
// A pixel is evaluated when the reference is known (reference > 0, finite)
// and the mask (optional, CV_8U) is non-zero there. A pixel whose estimate is
// missing (NaN, or <= invalid_below) counts as an error at every threshold
// (the honest way: holes are not free), and is also counted in `missing`.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace slope_monitor {
namespace dense {

struct DisparityErrors {
  int evaluated = 0;                       // pixels with a known reference inside the mask
  int missing = 0;                         // of those, without an estimate
  std::vector<double> thresholds;          // [px]
  std::vector<double> bad_fraction;        // share with |error| > threshold or missing
  std::vector<double> bad_fraction_valid;  // share among estimated pixels only
  double rms_valid = 0.0;                  // [px] RMS error of estimated pixels
};

// estimate, reference: CV_32F, same size. invalid_below: estimates below it
// are missing (OpenCV's SGBM marks invalid pixels with min_disparity - 1).
DisparityErrors EvaluateDisparity(const cv::Mat& estimate, const cv::Mat& reference,
                                  const cv::Mat& mask, const std::vector<double>& thresholds,
                                  float invalid_below = -1e30f);

}  // namespace dense
}  // namespace slope_monitor
