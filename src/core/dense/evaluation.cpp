#include "slope_monitor/core/dense/evaluation.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {

DisparityErrors EvaluateDisparity(const cv::Mat& estimate, const cv::Mat& reference,
                                  const cv::Mat& mask, const std::vector<double>& thresholds,
                                  float invalid_below) {
  if (estimate.type() != CV_32F || reference.type() != CV_32F ||
      estimate.size() != reference.size())
    throw InvalidArgument(
        "EvaluateDisparity: estimate and reference must be CV_32F of the same size");
  if (!mask.empty() && (mask.type() != CV_8U || mask.size() != reference.size()))
    throw InvalidArgument("EvaluateDisparity: mask must be CV_8U of the reference size");
  DisparityErrors e;
  e.thresholds = thresholds;
  std::vector<long> bad(thresholds.size(), 0), bad_valid(thresholds.size(), 0);
  double sum2 = 0.0;
  long valid = 0;
  for (int y = 0; y < reference.rows; ++y)
    for (int x = 0; x < reference.cols; ++x) {
      const float r = reference.at<float>(y, x);
      if (!(r > 0.0f) || !std::isfinite(r)) continue;
      if (!mask.empty() && mask.at<uchar>(y, x) == 0) continue;
      ++e.evaluated;
      const float d = estimate.at<float>(y, x);
      if (!std::isfinite(d) || d < invalid_below) {
        ++e.missing;
        for (size_t t = 0; t < thresholds.size(); ++t) ++bad[t];
        continue;
      }
      const double err = std::abs(d - r);
      sum2 += err * err;
      ++valid;
      for (size_t t = 0; t < thresholds.size(); ++t)
        if (err > thresholds[t]) {
          ++bad[t];
          ++bad_valid[t];
        }
    }
  for (size_t t = 0; t < thresholds.size(); ++t) {
    e.bad_fraction.push_back(e.evaluated > 0 ? static_cast<double>(bad[t]) / e.evaluated : 1.0);
    e.bad_fraction_valid.push_back(valid > 0 ? static_cast<double>(bad_valid[t]) / valid : 1.0);
  }
  e.rms_valid = valid > 0 ? std::sqrt(sum2 / valid) : 0.0;
  return e;
}

}  // namespace dense
}  // namespace slope_monitor
