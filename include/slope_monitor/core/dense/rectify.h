// Epipolar rectification of an oriented image pair with the package's camera
// model (camera/camera_model.h, distortion included).
//
// Both images are resampled onto two virtual, distortion-free pinhole cameras
// that share one rotation: their optical x axis is the baseline (from the
// left to the right projection centre), their z axis the mean viewing
// direction made orthogonal to it, y = z x x (REP 103 optical convention:
// x right, y down, z forward). Rows of the rectified images are then
// epipolar lines, and a site point seen at rectified (x_l, y) on the left is
// at (x_r, y) on the right with the parallax d = x_l - x_r.
//
// Every rectified pixel is mapped back through the real camera model
// (rotation, principal distance, principal point, lens and sensor
// distortion: CameraModel::ProjectMm), so no distortion is ignored. Pixels
// that fall outside the real image are marked in a validity mask.
//
// Patches: a pair is rectified as a grid of patches (patch_size px square,
// each with `patch_overlap` px of shared border) so that large images are
// processed piecewise; each patch keeps the principal-point shift of its
// position, so geometry stays exact.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"

namespace slope_monitor {
namespace dense {

// One image with its camera and orientation. `oriented` must be true: an
// image whose pose is unknown cannot be rectified.
struct OrientedImage {
  std::string name;  // for messages ("uav/0012")
  cv::Mat image;     // CV_8U or CV_32F, 1 channel (colour is converted)
  camera::CameraModel camera;
  camera::ExteriorOrientation pose;
  bool oriented = false;
};

struct RectifyOptions {
  double scale = 1.0;  // [-] rectified focal length / mean real focal length; (0, 4]
  int patch_size = 0;  // [px] square patch side; 0: one patch for the whole pair; 0 or [64, 8192]
  int patch_overlap = 32;  // [px] shared border between neighbouring patches; [0, patch_size / 2)
  double min_baseline = 1e-3;  // [m] shorter baselines are degenerate; > 0
  double min_overlap =
      0.05;            // [-] share of the left rectified image that must also be seen on the right
  void Check() const;  // throws ConfigError naming the field
};

// The virtual camera pair. Rectified pixel (x, y) of camera i looks along
//   ray_in_rect = ((x - cx[i]) / f, (y - cy) / f, 1),  direction_in_site = site_from_rect *
//   ray_in_rect.
// clang-tidy 14 reports '__i0' here: the index of the copy the compiler
// writes for the array members (centre, cx), not a name of ours.
// NOLINTNEXTLINE(bugprone-reserved-identifier)
struct RectifiedGeometry {
  Eigen::Matrix3d site_from_rect = Eigen::Matrix3d::Identity();
  Eigen::Vector3d centre[2];  // projection centres in site [m]
  double f = 0.0;             // [px]
  double cx[2] = {0.0, 0.0};  // [px]
  double cy = 0.0;            // [px]
  int width = 0, height = 0;  // [px] full rectified image size
  double baseline = 0.0;      // [m]

  Eigen::Vector3d RayDirection(int camera_index, double x, double y) const;
  // Parallax d = x_l - x_r of a point at depth z [m] along the rectified axis.
  double DisparityAtDepth(double z) const { return f * baseline / z + cx[0] - cx[1]; }
  // Depth [m] of a parallax, and the site point seen at left pixel (x, y)
  // with parallax d (intersection of the two rays: midpoint of the shortest
  // segment; `gap` receives the residual ray distance [m] when non-null).
  Eigen::Vector3d Intersect(double x_left, double y, double d, double* gap = nullptr) const;
  // Left rectified pixel of a site point (false when behind the cameras).
  bool ProjectLeft(const Eigen::Vector3d& x_in_site, Eigen::Vector2d* pixel) const;
};

struct RectifiedPatch {
  cv::Rect roi;                     // in the full rectified image
  cv::Mat left, right;              // CV_32F rectified patch images
  cv::Mat valid_left, valid_right;  // CV_8U 255 where the pixel came from inside the real image
};

struct RectifiedPair {
  RectifiedGeometry geometry;
  std::vector<RectifiedPatch> patches;
  double overlap =
      0.0;  // share of valid left pixels whose depth-range epipolar segment meets the right image
};

// Rectifies a pair. min_depth / max_depth [m] (along the viewing direction)
// bound where the surface can be: they place the right principal point so
// the parallaxes are centred, and give the parallax search range via
// DisparityAtDepth. Throws InvalidArgument naming the image when an image is
// unoriented, empty, its camera fails CameraModel::Check(), or its size
// differs from the camera's sensor; when the baseline is shorter than
// min_baseline ("zero baseline"); when the depth range is not 0 < min < max;
// and when the images do not overlap (share < min_overlap).
RectifiedPair Rectify(const OrientedImage& left, const OrientedImage& right, double min_depth,
                      double max_depth, const RectifyOptions& options = RectifyOptions());

// Converts an image to single-channel float (BGR -> gray), naming `what` in errors.
cv::Mat ToGrayFloat(const cv::Mat& image, const std::string& what);

}  // namespace dense
}  // namespace slope_monitor
