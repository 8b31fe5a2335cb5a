// The Middlebury 2003 "Cones" pair (test/data/stereo_middlebury_cones) for
// the matching and dense tests, and the noise they add to its texture.
// Header only: a test that includes it needs no CMake change.
#pragma once

#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace testing {

inline std::string ConesPath(const std::string& name) {
  return std::string(SM_TEST_DATA_DIR) + "/stereo_middlebury_cones/" + name;
}

// One file of the pair (left.tif, right.tif, disp_left_gt.tif, occl.png) as
// cv::imread reads it with `flags`; throws IoError naming the file when it
// cannot be read.
inline cv::Mat LoadCones(const std::string& name, int flags = cv::IMREAD_UNCHANGED) {
  cv::Mat m = cv::imread(ConesPath(name), flags);
  if (m.empty()) throw IoError("cannot read " + ConesPath(name));
  return m;
}

// The rectified pair with its ground truth: left and right images, the
// left image's true disparity (CV_32F, 0 = unknown) and its non-occlusion
// mask (occl.png, 255 = evaluated). The images and the mask are read with
// `image_flags`, the disparity unchanged.
struct ConesPair {
  cv::Mat left, right, gt, occl;
};
inline ConesPair LoadConesPair(int image_flags = cv::IMREAD_UNCHANGED) {
  return {LoadCones("left.tif", image_flags), LoadCones("right.tif", image_flags),
          LoadCones("disp_left_gt.tif"), LoadCones("occl.png", image_flags)};
}

// f (CV_32F) plus Gaussian noise of `sigma` grey levels from cv::RNG(seed).
inline cv::Mat AddNoise(const cv::Mat& f, double sigma, unsigned seed) {
  cv::Mat noise(f.size(), CV_32F);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  return f + noise;
}

}  // namespace testing
}  // namespace slope_monitor
