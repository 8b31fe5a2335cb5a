// Global translation between two overlapping photos of one moving camera
// (UAV strips): the prior shift of the hexagonal matcher (MatchPrior::shift)
// when the images are displaced by far more than its search radius.
//
// Method: phase correlation of copies downsampled by an integer factor so
// that their longer side is at most `max_size` px (1280 x 960 -> factor 4,
// 320 x 240): the normalised cross-power spectrum (cv::dft) of zero-mean
// copies under a Tukey window (a Hanning-shaped raised-cosine fall over the
// outer `taper` of each side; a full Hanning window suppresses the overlap
// of photos two apart, which lies at the image edges: measured on the
// uav_graph_replay bag, every such pair failed with it). The `candidates`
// highest peaks, each at d and d - size in each axis (the correlation is
// cyclic), are checked by the NCC of the overlapping parts of the coarse
// copies, and the best-correlating one is the coarse shift (sub-pixel by the
// peak's 3 x 3 centroid, times the factor). With `refine`, the overlapping
// parts of both images (cut at the rounded coarse shift) are correlated
// again by cv::phaseCorrelate with a Hanning window at factor
// `refine_factor` (finer for small overlaps) and the residual is added.
// Shifts up to the image size (overlap >= min_overlap_fraction of the area)
// are found; assumes no large rotation or scale change between the photos
// (strips flown in the same direction at one height).
//
// The shift is unusable (`usable` false, `reason` says why) when the peak
// response is below min_response, the overlapping parts correlate below
// min_overlap_correlation (unrelated images, textureless images) or they
// overlap by less than min_overlap.
#pragma once

#include <string>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace slope_monitor {
namespace matching {

struct GlobalShiftOptions {
  int max_size = 320;          // [px] longer side of the coarse copies, [32, 4096]
  double min_response = 0.01;  // [0, 1] smallest phase-correlation peak for a usable shift
  // [-1, 1] smallest NCC of the overlapping parts (coarse copies) at the
  // shift found: the real test of a shift (the peak shrinks with the
  // overlap). Measured on the uav_graph_replay bag: true shifts 0.58-0.92,
  // the best wrong candidates up to 0.49 (with 32 candidates).
  double min_overlap_correlation = 0.55;
  // [1, 100] highest correlation peaks checked by the overlap NCC. The true
  // peak of photos two apart on the uav_graph_replay bag (overlap ~35 %) was
  // beyond the 8th in 2 of 21 pairs (peak 0.017, overlap NCC 0.73).
  int candidates = 32;
  double taper = 0.1;     // (0, 0.5] coarse window: raised-cosine fall over this share of each side
  bool refine = true;     // correlate the overlap again at a finer scale
  int refine_factor = 2;  // [-] downsampling of the refinement, [1, 16]
  int min_overlap =
      48;  // [px] smallest overlap (each axis, full resolution) for the shift to be usable
  double min_overlap_fraction =
      0.1;             // [0, 1) smallest overlap area / image area of a candidate shift
  void Check() const;  // throws ConfigError naming the field
};

struct GlobalShiftResult {
  Eigen::Vector2d shift = Eigen::Vector2d::Zero();  // [px] xb - xa at full resolution
  double response = 0.0;                            // [0, 1] peak of the coarse phase correlation
  double overlap_correlation = -2.0;  // [-1, 1] NCC of the coarse overlapping parts (-2: none)
  int factor = 1;                     // coarse downsampling factor used
  bool refined = false;               // the fine correlation was applied
  bool usable = false;
  std::string reason;  // why not usable ("" when usable)
  bool IsSolutionUsable() const { return usable; }
};

// Throws InvalidArgument when an image is empty, multi-channel, of an
// unsupported depth, or the two differ in size (naming both sizes).
GlobalShiftResult EstimateGlobalShift(const cv::Mat& image_a, const cv::Mat& image_b,
                                      const GlobalShiftOptions& options);

}  // namespace matching
}  // namespace slope_monitor
