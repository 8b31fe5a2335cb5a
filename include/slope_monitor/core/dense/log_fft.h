// The scale-normalised LoG band-pass of matching/filters.h computed in the
// frequency domain, for the dense matcher's choice between the separable
// (spatial) and the FFT implementation (bench/dense_log_filter.cpp measures
// both on the same images and prints the ratio and the largest difference).
//
// Response: H(w) = s^2 w^2 exp(-s^2 w^2 / 2), w the radial angular frequency
// [rad/px] (the same band-pass as matching::LaplacianOfGaussian, without its
// spatial truncation). The image is padded by reflection (BORDER_REFLECT_101,
// as filters.h) by ceil(4 s) pixels on every side to an FFT-friendly size.
#pragma once

#include <opencv2/core.hpp>

namespace slope_monitor {
namespace dense {

// Scale-normalised, sign-flipped LoG (bright blob -> positive), CV_32F.
// Throws InvalidArgument for sigma <= 0 or an empty / multi-channel image.
cv::Mat LaplacianOfGaussianFft(const cv::Mat& image, double sigma);

}  // namespace dense
}  // namespace slope_monitor
