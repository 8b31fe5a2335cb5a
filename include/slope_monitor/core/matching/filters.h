// Image filters on single-channel float images (cv::Mat, CV_32F), used by the
// hexagonal matcher, least-squares correlation (LSC) and the dense
// coarse-to-fine LoG correlation.
//
// Conventions (all functions):
//   * Pixels follow OpenCV: x = column (right), y = row (down), (0, 0) is the
//     centre of the top-left pixel. Sub-pixel positions use the same frame.
//   * Inputs must be non-empty, single-channel. Filters accept CV_8U, CV_16U,
//     CV_32F or CV_64F and always return CV_32F of the same size; anything
//     else throws slope_monitor::InvalidArgument naming the argument and type.
//   * Borders are handled by reflection without repeating the edge pixel
//     (cv::BORDER_REFLECT_101: ... 2 1 | 0 1 2 ... ).
//   * Kernels are truncated at radius ceil(kTruncation * sigma) and the
//     Gaussian is normalised to sum 1 after truncation.
//
// Laplacian of Gaussian (LoG) and its scale normalisation
// -------------------------------------------------------
//   G(x, y; s)  = exp(-(x^2 + y^2) / (2 s^2)) / (2 pi s^2)
//   LoG(x, y)   = Gxx + Gyy = g''(x) g(y) + g(x) g''(y)
// computed as the sum of two separable filters (2 x 2 one-dimensional passes).
// LaplacianOfGaussian() returns the *scale-normalised, sign-flipped* response
//   L = -s^2 (Gxx + Gyy) * I
// so that
//   * a bright blob on a dark background gives a positive peak;
//   * the response to a pattern does not depend on s (for a blob of matching
//     size), so levels at different s compare directly;
//   * its frequency response is  H(w) = s^2 w^2 exp(-s^2 w^2 / 2)  (w radial
//     angular frequency, rad/pixel): a band-pass peaking at w = sqrt(2) / s
//     with peak gain 2/e ~ 0.736, zero gain at DC (a constant image gives 0).
//   Use LogSigmaForPeakFrequency(w) to pick s for a band: w = 1, 1/2, 1/4
//   rad/pixel -> s = 1.414, 2.828, 5.657 px.
//   The discrete g'' is normalised so that the sampled kernel sums to zero
//   (no DC leak) and sum(x^2 g''(x)) = 2 (the continuous moment).
// Pass scale_normalised = false to get the plain (Gxx + Gyy) * I instead
// (no sign flip, no s^2).
//
// Sampling at sub-pixel positions
// -------------------------------
//   SampleBilinear: 2 x 2 neighbourhood, exact for linear ramps.
//   SampleBicubic:  4 x 4 neighbourhood, Keys' cubic convolution (a = -0.5),
//                   exact for quadratic ramps, C1-continuous.
// Positions outside the image are clamped (edge pixel replicated); use
// CanSample() to know whether the full neighbourhood is inside. Functions
// that also return the derivative of the interpolant (SampleBilinearGrad,
// SampleBicubicGrad) give d/dx and d/dy of the same interpolating surface
// (used by LSC). Sampling reads CV_32F only (throws otherwise) and does not
// check its arguments beyond that: it is meant for inner loops.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace slope_monitor {
namespace matching {

// Kernel radius in units of sigma.
constexpr double kTruncation = 4.0;

enum class Interpolation {
  kBilinear,  // "bilinear"
  kBicubic,   // "bicubic"
};
// Parses "bilinear" / "bicubic"; throws InvalidArgument naming the value.
Interpolation InterpolationFromName(const std::string& name);
const char* InterpolationName(Interpolation interpolation);

// Converts a single-channel image of depth 8U/16U/32F/64F to CV_32F (values
// unchanged, no scaling). A CV_32F input is returned as a shared header (no
// copy). Throws InvalidArgument (naming `what`) on empty or multi-channel
// input or another depth.
cv::Mat ToFloat(const cv::Mat& image, const char* what = "image");

// One-dimensional kernels, length 2 r + 1 with r = ceil(kTruncation * sigma),
// index r is x = 0. sigma must be > 0 (InvalidArgument otherwise).
std::vector<float> GaussianKernel(double sigma);                  // g, sums to 1
std::vector<float> GaussianSecondDerivativeKernel(double sigma);  // g'', see above

// Gaussian smoothing (separable). sigma [px] > 0.
cv::Mat GaussianBlur(const cv::Mat& image, double sigma);

// Laplacian of Gaussian (separable, see the header comment). sigma [px] > 0.
cv::Mat LaplacianOfGaussian(const cv::Mat& image, double sigma, bool scale_normalised = true);

// The sigma whose scale-normalised LoG has its peak gain at angular frequency
// omega [rad/pixel] (sigma = sqrt(2) / omega). omega > 0.
double LogSigmaForPeakFrequency(double omega);

// Sobel derivatives (3 x 3, normalised by 1/8 so that a ramp of slope 1
// px^-1 gives gx = 1) and the gradient magnitude sqrt(gx^2 + gy^2).
struct Gradients {
  cv::Mat gx;         // CV_32F, d/dx (column direction)
  cv::Mat gy;         // CV_32F, d/dy (row direction)
  cv::Mat magnitude;  // CV_32F
};
Gradients SobelGradients(const cv::Mat& image);

// Zero-crossings of a LoG (or any signed) image: CV_8U mask, 255 on edge
// pixels, 0 elsewhere. A pixel is marked when its value and that of its right
// or lower neighbour have opposite signs (or one is exactly 0 and the other is
// not), the absolute difference across the pair is at least min_contrast, and
// the pixel is the one of the pair closer to zero. This gives one-pixel-thin,
// 8-connected edge curves. The outermost pixel ring is never marked.
// min_contrast >= 0 (same units as the image).
cv::Mat ZeroCrossings(const cv::Mat& signed_image, double min_contrast);

// True if the interpolation neighbourhood of (x, y) lies inside the image:
// bilinear 0 <= x <= cols-1, 0 <= y <= rows-1; bicubic 1 <= x <= cols-2,
// 1 <= y <= rows-2.
bool CanSample(const cv::Mat& image, double x, double y, Interpolation interpolation);

// Interpolated value at (x, y). image must be CV_32F, single channel.
float SampleBilinear(const cv::Mat& image, double x, double y);
float SampleBicubic(const cv::Mat& image, double x, double y);
float Sample(const cv::Mat& image, double x, double y, Interpolation interpolation);

// The (2 half + 1)^2 values at (x + u, y + v), u, v = -half..half, row by
// row into out: one set of interpolation weights for the whole window (the
// sub-pixel offset is the same everywhere). The window's neighbourhood must
// lie inside the image (CanSample at both corners); else InvalidArgument.
void SampleWindow(const cv::Mat& image, double x, double y, int half, Interpolation interpolation,
                  double* out);

// Interpolated value and its analytic derivatives d/dx, d/dy of the same
// interpolant. Returns the value; writes the derivatives to *dx, *dy.
float SampleBilinearGrad(const cv::Mat& image, double x, double y, float* dx, float* dy);
float SampleBicubicGrad(const cv::Mat& image, double x, double y, float* dx, float* dy);
float SampleGrad(const cv::Mat& image, double x, double y, Interpolation interpolation, float* dx,
                 float* dy);

}  // namespace matching
}  // namespace slope_monitor
