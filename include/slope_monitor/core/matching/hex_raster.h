// Hexagonal raster, hexagonal pyramid and the six-profile cell descriptor
// (doc/design.md, "Generalized photogrammetry and hexagonal matching").
//
// Geometry. A hex raster of scale s (s = 1 for the full-resolution level)
// has regular hexagonal cells: rows spaced dy = s / 2 px, cells in a row
// spaced dx = s / sqrt(3) px, odd rows shifted by dx / 2 (the "odd columns
// from even rows" offset), so that all six neighbours of a cell are at the
// same distance s / sqrt(3) px. Cell (i, k) (row i, index k in the row) has
// its centre, in square-raster pixels (OpenCV convention), at
//   x = (k + (i mod 2) / 2) dx,      y = (i + 1/2) dy - 1/2.
// At s = 1, hex rows 2j and 2j + 1 lie at y = j - 1/4 and j + 1/4, inside
// square row j: an n-row raster gives a 2n-row hex space.
//
// Values. kNearest: the value of the square pixel whose centre holds the
// hexagon's centre (pixel (round(x), round(y))); kInterpolated: bilinear
// interpolation at the centre.
//
// Neighbour directions d = 0..5 go counter-clockwise on screen starting at
// +x: 0 = east, 1 = north-east (up-right, y decreasing), 2 = north-west,
// 3 = west, 4 = south-west, 5 = south-east.
//
// Descriptor. The six equal-length profiles of a cell: along each direction
// the values of `length` consecutive cells starting at the neighbour; the
// 6 * length values plus the centre value, less their mean, divided by their
// norm. The dot product of two descriptors is their normalised correlation.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace slope_monitor {
namespace matching {

enum class HexSampling { kNearest, kInterpolated };

class HexRaster {
 public:
  HexRaster() = default;
  // Maps a single-channel image (any depth ToFloat accepts) onto the hex
  // raster of scale `scale` (> 0). Throws InvalidArgument on bad input.
  static HexRaster FromImage(const cv::Mat& image, HexSampling sampling, double scale = 1.0);

  int rows() const { return values_.rows; }
  int cols() const { return values_.cols; }
  double scale() const { return scale_; }
  double dx() const { return dx_; }
  double dy() const { return dy_; }
  const cv::Mat& values() const { return values_; }  // CV_32F rows x cols
  float value(int i, int k) const { return values_.at<float>(i, k); }
  bool Contains(int i, int k) const { return i >= 0 && k >= 0 && i < rows() && k < cols(); }

  Eigen::Vector2d Centre(int i, int k) const;
  // The cell whose centre is nearest to (x, y) (may lie outside; check Contains).
  void NearestCell(const Eigen::Vector2d& x, int* i, int* k) const;
  // Neighbour of (i, k) in direction d (0..5).
  static void Neighbour(int i, int k, int d, int* ni, int* nk);

  // Descriptor of cell (i, k) with profiles of `length` cells; returns false
  // when a profile leaves the raster or the cell's neighbourhood is flat.
  bool Descriptor(int i, int k, int length, std::vector<float>* descriptor) const;

 private:
  cv::Mat values_;
  double scale_ = 1.0, dx_ = 0.0, dy_ = 0.0;
};

// Hexagonal pyramid: level l is the hex raster of scale 2^l of the image
// smoothed by a Gaussian of sigma 0.5 * 2^l px (l >= 1; level 0 unsmoothed).
class HexPyramid {
 public:
  HexPyramid(const cv::Mat& image, int levels, HexSampling sampling);
  int levels() const { return static_cast<int>(levels_.size()); }
  const HexRaster& level(int l) const { return levels_[l]; }

 private:
  std::vector<HexRaster> levels_;
};

}  // namespace matching
}  // namespace slope_monitor
