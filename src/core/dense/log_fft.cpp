#include "slope_monitor/core/dense/log_fft.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace dense {

cv::Mat LaplacianOfGaussianFft(const cv::Mat& image, double sigma) {
  if (!(sigma > 0))
    throw InvalidArgument(Message("LaplacianOfGaussianFft: sigma ", sigma, " must be > 0"));
  const cv::Mat f = matching::ToFloat(image, "image");
  const int pad = static_cast<int>(std::ceil(4.0 * sigma));
  const int w = cv::getOptimalDFTSize(f.cols + 2 * pad),
            h = cv::getOptimalDFTSize(f.rows + 2 * pad);
  cv::Mat padded;
  cv::copyMakeBorder(f, padded, pad, h - f.rows - pad, pad, w - f.cols - pad,
                     cv::BORDER_REFLECT_101);
  cv::Mat spectrum;
  cv::dft(padded, spectrum, cv::DFT_COMPLEX_OUTPUT);
  const double s2 = sigma * sigma;
  std::vector<double> wx2(w), wy2(h);
  for (int k = 0; k < w; ++k) {
    const double wk = 2.0 * M_PI * (k <= w / 2 ? k : k - w) / w;
    wx2[k] = wk * wk;
  }
  for (int k = 0; k < h; ++k) {
    const double wk = 2.0 * M_PI * (k <= h / 2 ? k : k - h) / h;
    wy2[k] = wk * wk;
  }
  for (int y = 0; y < h; ++y) {
    cv::Vec2f* row = spectrum.ptr<cv::Vec2f>(y);
    for (int x = 0; x < w; ++x) {
      const double q = s2 * (wx2[x] + wy2[y]);
      const float g = static_cast<float>(q * std::exp(-0.5 * q));
      row[x] *= g;
    }
  }
  cv::Mat back;
  cv::dft(spectrum, back, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
  return back(cv::Rect(pad, pad, f.cols, f.rows)).clone();
}

}  // namespace dense
}  // namespace slope_monitor
