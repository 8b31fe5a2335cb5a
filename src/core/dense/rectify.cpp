#include "slope_monitor/core/dense/rectify.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {

namespace {

void CheckImage(const OrientedImage& im, const char* role) {
  const std::string name = im.name.empty() ? std::string(role) : im.name;
  if (!im.oriented)
    throw InvalidArgument(Message("dense pair: ", role, " image '", name,
                                  "' is not oriented (no exterior orientation)"));
  if (im.image.empty())
    throw InvalidArgument(Message("dense pair: ", role, " image '", name, "' is empty"));
  try {
    im.camera.Check();
  } catch (const Error& e) {
    throw InvalidArgument(Message("dense pair: ", role, " image '", name, "': ", e.what()));
  }
  if (im.image.cols != im.camera.sensor().width || im.image.rows != im.camera.sensor().height)
    throw InvalidArgument(Message("dense pair: ", role, " image '", name, "' is ", im.image.cols,
                                  "x", im.image.rows, " px but its camera sensor is ",
                                  im.camera.sensor().width, "x", im.camera.sensor().height));
  const auto e = im.pose.ToArray();
  for (double v : e)
    if (!std::isfinite(v))
      throw InvalidArgument(Message("dense pair: ", role, " image '", name,
                                    "' has a non-finite exterior orientation"));
}

// Maps of one rectified camera into its real image.
struct Projector {
  Eigen::Matrix3d m;  // cam_from_site (photogrammetric)
  Eigen::Vector3d centre;
  const camera::CameraModel* cam;
  bool Project(const Eigen::Vector3d& dir_in_site, float* col, float* row) const {
    const Eigen::Vector3d u = m * dir_in_site;
    if (!(u.z() < 0)) return false;
    const double c = cam->principal_distance();
    const Eigen::Vector2d px =
        cam->MmToPixel(cam->DistortMm({-c * u.x() / u.z(), -c * u.y() / u.z()}));
    *col = static_cast<float>(px.x());
    *row = static_cast<float>(px.y());
    return px.x() >= 0 && px.y() >= 0 && px.x() <= cam->sensor().width - 1 &&
           px.y() <= cam->sensor().height - 1;
  }
};

}  // namespace

void RectifyOptions::Check() const {
  RequireOption("rectify", scale > 0 && scale <= 4, "scale",
                Message("= ", scale, " must be in (0, 4]"));
  RequireOption("rectify", patch_size == 0 || (patch_size >= 64 && patch_size <= 8192),
                "patch_size", Message("= ", patch_size, " must be 0 or in [64, 8192]"));
  RequireOption("rectify",
                patch_overlap >= 0 && (patch_size == 0 || patch_overlap < patch_size / 2),
                "patch_overlap", Message("= ", patch_overlap, " must be in [0, patch_size / 2)"));
  RequireOption("rectify", min_baseline > 0, "min_baseline",
                Message("= ", min_baseline, " must be > 0"));
  RequireOption("rectify", min_overlap >= 0 && min_overlap <= 1, "min_overlap",
                Message("= ", min_overlap, " must be in [0, 1]"));
}

cv::Mat ToGrayFloat(const cv::Mat& image, const std::string& what) {
  if (image.empty()) throw InvalidArgument(Message(what, ": empty image"));
  cv::Mat gray = image;
  if (image.channels() == 3) {
    cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
  } else if (image.channels() == 4) {
    cv::cvtColor(image, gray, cv::COLOR_BGRA2GRAY);
  } else if (image.channels() != 1) {
    throw InvalidArgument(Message(what, ": ", image.channels(), " channels (expected 1, 3 or 4)"));
  }
  cv::Mat f;
  gray.convertTo(f, CV_32F);
  return f;
}

Eigen::Vector3d RectifiedGeometry::RayDirection(int i, double x, double y) const {
  return site_from_rect * Eigen::Vector3d((x - cx[i]) / f, (y - cy) / f, 1.0);
}

Eigen::Vector3d RectifiedGeometry::Intersect(double x_left, double y, double d, double* gap) const {
  const Eigen::Vector3d a = RayDirection(0, x_left, y), b = RayDirection(1, x_left - d, y);
  const Eigen::Vector3d w0 = centre[0] - centre[1];
  const double aa = a.dot(a), ab = a.dot(b), bb = b.dot(b), aw = a.dot(w0), bw = b.dot(w0);
  const double den = aa * bb - ab * ab;
  if (!(std::abs(den) > 1e-18)) {
    if (gap) *gap = std::numeric_limits<double>::infinity();
    return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  const double s = (ab * bw - bb * aw) / den, t = (aa * bw - ab * aw) / den;
  const Eigen::Vector3d pa = centre[0] + s * a, pb = centre[1] + t * b;
  if (gap) *gap = (pa - pb).norm();
  if (s <= 0 || t <= 0) return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  return 0.5 * (pa + pb);
}

bool RectifiedGeometry::ProjectLeft(const Eigen::Vector3d& x_in_site,
                                    Eigen::Vector2d* pixel) const {
  const Eigen::Vector3d r = site_from_rect.transpose() * (x_in_site - centre[0]);
  if (!(r.z() > 0)) return false;
  *pixel = Eigen::Vector2d(cx[0] + f * r.x() / r.z(), cy + f * r.y() / r.z());
  return true;
}

RectifiedPair Rectify(const OrientedImage& left, const OrientedImage& right, double min_depth,
                      double max_depth, const RectifyOptions& options) {
  options.Check();
  CheckImage(left, "left");
  CheckImage(right, "right");
  if (!(min_depth > 0 && max_depth > min_depth && std::isfinite(max_depth)))
    throw InvalidArgument(Message("dense pair: depth range [", min_depth, ", ", max_depth,
                                  "] m must satisfy 0 < min_depth < max_depth"));
  const Eigen::Vector3d baseline = right.pose.position - left.pose.position;
  if (!(baseline.norm() >= options.min_baseline))
    throw InvalidArgument(Message("dense pair '", left.name, "'/'", right.name, "': baseline ",
                                  baseline.norm(), " m is shorter than min_baseline ",
                                  options.min_baseline, " m (zero baseline: no parallax)"));
  const Eigen::Matrix3d m_l = camera::RotationFromAngles(left.pose.angles);
  const Eigen::Matrix3d m_r = camera::RotationFromAngles(right.pose.angles);
  // Viewing direction in site: the camera looks along -z of its photogrammetric frame.
  const Eigen::Vector3d view_l = -m_l.row(2).transpose(), view_r = -m_r.row(2).transpose();
  const Eigen::Vector3d x_axis = baseline.normalized();
  Eigen::Vector3d z_axis = (view_l + view_r).normalized();
  z_axis = z_axis - z_axis.dot(x_axis) * x_axis;
  if (!(z_axis.norm() > 1e-3))
    throw InvalidArgument(Message("dense pair '", left.name, "'/'", right.name,
                                  "': cameras look along the baseline (no stereo geometry)"));
  z_axis.normalize();
  const Eigen::Vector3d y_axis = z_axis.cross(x_axis);
  RectifiedGeometry g;
  g.site_from_rect.col(0) = x_axis;
  g.site_from_rect.col(1) = y_axis;
  g.site_from_rect.col(2) = z_axis;
  g.centre[0] = left.pose.position;
  g.centre[1] = right.pose.position;
  g.baseline = baseline.norm();
  const double f_l = left.camera.principal_distance() / left.camera.sensor().pixel_size;
  const double f_r = right.camera.principal_distance() / right.camera.sensor().pixel_size;
  g.f = options.scale * 0.5 * (f_l + f_r);
  g.width = static_cast<int>(std::lround(options.scale * left.camera.sensor().width));
  g.height = static_cast<int>(std::lround(options.scale * left.camera.sensor().height));
  const Eigen::Vector3d vl = g.site_from_rect.transpose() * view_l;
  if (!(vl.z() > 0.1))
    throw InvalidArgument(
        Message("dense pair '", left.name, "': left camera looks away from the rectified axis"));
  g.cx[0] = 0.5 * (g.width - 1) - g.f * vl.x() / vl.z();
  g.cy = 0.5 * (g.height - 1) - g.f * vl.y() / vl.z();
  // Parallax zero at the harmonic mean depth: the search range is centred.
  const double z_mid = 2.0 / (1.0 / min_depth + 1.0 / max_depth);
  g.cx[1] = g.cx[0] + g.f * g.baseline / z_mid;

  // Pixel maps through the real camera models.
  const Projector proj[2] = {{m_l, left.pose.position, &left.camera},
                             {m_r, right.pose.position, &right.camera}};
  cv::Mat map_x[2], map_y[2], valid[2];
  for (int i = 0; i < 2; ++i) {
    map_x[i].create(g.height, g.width, CV_32F);
    map_y[i].create(g.height, g.width, CV_32F);
    valid[i].create(g.height, g.width, CV_8U);
    for (int y = 0; y < g.height; ++y) {
      float* mx = map_x[i].ptr<float>(y);
      float* my = map_y[i].ptr<float>(y);
      uchar* v = valid[i].ptr<uchar>(y);
      for (int x = 0; x < g.width; ++x) {
        const bool ok = proj[i].Project(g.RayDirection(i, x, y), &mx[x], &my[x]);
        v[x] = ok ? 255 : 0;
        if (!ok) mx[x] = my[x] = -10.0f;
      }
    }
  }
  // Overlap: left pixels whose point at the mid depth (parallax 0) is inside
  // the right image too.
  cv::Mat both;
  cv::bitwise_and(valid[0], valid[1], both);
  const int left_count = cv::countNonZero(valid[0]);
  RectifiedPair pair;
  pair.overlap = left_count > 0 ? static_cast<double>(cv::countNonZero(both)) / left_count : 0.0;
  if (pair.overlap < options.min_overlap || left_count == 0)
    throw InvalidArgument(Message("dense pair '", left.name, "'/'", right.name,
                                  "': the images do not overlap (", 100.0 * pair.overlap,
                                  "% of the left image seen on the right at mid depth ", z_mid,
                                  " m, need ", 100.0 * options.min_overlap, "%)"));

  cv::Mat rect[2];
  const cv::Mat gray[2] = {ToGrayFloat(left.image, "left image '" + left.name + "'"),
                           ToGrayFloat(right.image, "right image '" + right.name + "'")};
  for (int i = 0; i < 2; ++i)
    cv::remap(gray[i], rect[i], map_x[i], map_y[i], cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar(0));
  pair.geometry = g;
  const int step = options.patch_size == 0 ? std::max(g.width, g.height)
                                           : options.patch_size - options.patch_overlap;
  const int size = options.patch_size == 0 ? std::max(g.width, g.height) : options.patch_size;
  for (int y0 = 0; y0 < g.height; y0 += step) {
    for (int x0 = 0; x0 < g.width; x0 += step) {
      RectifiedPatch p;
      p.roi = cv::Rect(x0, y0, std::min(size, g.width - x0), std::min(size, g.height - y0));
      p.left = rect[0](p.roi).clone();
      p.right = rect[1](p.roi).clone();
      p.valid_left = valid[0](p.roi).clone();
      p.valid_right = valid[1](p.roi).clone();
      if (cv::countNonZero(p.valid_left) > 0) pair.patches.push_back(p);
      if (x0 + size >= g.width) break;
    }
    if (y0 + size >= g.height) break;
  }
  return pair;
}

}  // namespace dense
}  // namespace slope_monitor
