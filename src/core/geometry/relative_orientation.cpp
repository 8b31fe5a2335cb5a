#include "slope_monitor/core/geometry/relative_orientation.h"

#include <cmath>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/geometry/intersection.h"

namespace slope_monitor {
namespace geometry {

void RelativeOrientationOptions::Check() const {
  if (!(inlier_threshold_px > 0.0))
    throw ConfigError(
        Message("relative orientation inlier_threshold_px must be > 0, got ", inlier_threshold_px));
  if (!(confidence > 0.0 && confidence < 1.0))
    throw ConfigError(
        Message("relative orientation confidence must be in (0, 1), got ", confidence));
  if (max_iterations <= 0)
    throw ConfigError(
        Message("relative orientation max_iterations must be > 0, got ", max_iterations));
}

RelativeOrientationResult RelativeOrientation(const camera::CameraModel& model_a,
                                              const std::vector<Eigen::Vector2d>& pixels_a,
                                              const camera::CameraModel& model_b,
                                              const std::vector<Eigen::Vector2d>& pixels_b,
                                              const RelativeOrientationOptions& options) {
  options.Check();
  RelativeOrientationResult r;
  if (pixels_a.size() != pixels_b.size())
    throw InvalidArgument(Message("relative orientation: ", pixels_a.size(), " points in a, ",
                                  pixels_b.size(), " in b"));
  const size_t n = pixels_a.size();
  if (n < 5) {
    r.message = Message("too few tie points: ", n, " (the five-point solution needs >= 5)");
    return r;
  }
  // Normalised coordinates in the REP 103 optical frames (x/z, y/z).
  std::vector<cv::Point2d> na(n), nb(n);
  for (size_t i = 0; i < n; ++i) {
    if (!pixels_a[i].allFinite() || !pixels_b[i].allFinite())
      throw InvalidArgument(Message("relative orientation: tie point ", i, " is not finite"));
    const Eigen::Vector3d da = model_a.PixelToOpticalDirection(pixels_a[i]);
    const Eigen::Vector3d db = model_b.PixelToOpticalDirection(pixels_b[i]);
    na[i] = cv::Point2d(da.x() / da.z(), da.y() / da.z());
    nb[i] = cv::Point2d(db.x() / db.z(), db.y() / db.z());
  }
  const double focal_px = 0.5 * (model_a.principal_distance() / model_a.sensor().pixel_size +
                                 model_b.principal_distance() / model_b.sensor().pixel_size);
  cv::theRNG().state = options.seed;
  cv::Mat mask;
  const cv::Mat k = cv::Mat::eye(3, 3, CV_64F);
  cv::Mat e =
      cv::findEssentialMat(na, nb, k, cv::RANSAC, options.confidence,
                           options.inlier_threshold_px / focal_px, options.max_iterations, mask);
  if (e.empty() || e.rows != 3) {
    r.message = "the five-point solver found no essential matrix (degenerate tie points?)";
    return r;
  }
  cv::Mat rot, t;
  const int good = cv::recoverPose(e, na, nb, k, rot, t, mask);
  if (good < 5) {
    r.message =
        Message("only ", good, " tie points in front of both images after the cheirality check");
    return r;
  }
  Eigen::Matrix3d r_opt;
  Eigen::Vector3d t_opt;
  cv::cv2eigen(rot, r_opt);
  cv::cv2eigen(t, t_opt);
  const Eigen::Matrix3d d = camera::OpticalFromPhotogrammetric();
  r.rotation = d * r_opt * d;
  r.translation = (d * t_opt).normalized();
  r.inliers.resize(n);
  r.num_inliers = 0;
  for (size_t i = 0; i < n; ++i) {
    r.inliers[i] = mask.at<unsigned char>(static_cast<int>(i)) != 0;
    r.num_inliers += r.inliers[i];
  }
  r.success = true;
  r.message = Message(r.num_inliers, " of ", n, " tie points inliers");
  return r;
}

PairInSite OrientPairInSite(const RelativeOrientationResult& relative,
                            const camera::CameraModel& model_a, const camera::CameraModel& model_b,
                            const std::vector<Eigen::Vector2d>& control_pixels_a,
                            const std::vector<Eigen::Vector2d>& control_pixels_b,
                            const std::vector<Eigen::Vector3d>& control_in_site,
                            const HelmertOptions& helmert) {
  PairInSite out;
  if (!relative.success) {
    out.message = "relative orientation failed: " + relative.message;
    return out;
  }
  const size_t n = control_in_site.size();
  if (control_pixels_a.size() != n || control_pixels_b.size() != n)
    throw InvalidArgument("orient pair: control pixel and coordinate counts differ");
  // Model frame = photogrammetric frame of image a, baseline length 1.
  camera::ExteriorOrientation ea, eb;
  eb.position = -relative.rotation.transpose() * relative.translation;
  eb.angles = camera::AnglesFromRotation(relative.rotation);
  std::vector<Eigen::Vector3d> model_points, site_points;
  for (size_t i = 0; i < n; ++i) {
    std::vector<RayObservation> rays(2);
    rays[0].model = &model_a;
    rays[0].exterior = ea;
    rays[0].pixel = control_pixels_a[i];
    rays[1].model = &model_b;
    rays[1].exterior = eb;
    rays[1].pixel = control_pixels_b[i];
    IntersectionOptions io;
    io.min_angle_deg = 0.1;
    const IntersectionResult x = Intersect(rays, io);
    if (!x.success) continue;
    model_points.push_back(x.position);
    site_points.push_back(control_in_site[i]);
  }
  HelmertOptions h = helmert;
  h.estimate_scale = true;
  // The model scale is arbitrary: judge inliers in site metres after a first fit.
  const HelmertResult fit = FitSimilarityRobust(model_points, site_points, h);
  if (!fit.success) {
    out.message = "scale from control failed: " + fit.message;
    return out;
  }
  const Similarity3& s = fit.target_from_source;
  auto to_site = [&](const camera::ExteriorOrientation& e) {
    camera::ExteriorOrientation o;
    o.position = s * e.position;
    o.angles =
        camera::AnglesFromRotation(camera::RotationFromAngles(e.angles) * s.rotation.transpose());
    return o;
  };
  out.exterior_a = to_site(ea);
  out.exterior_b = to_site(eb);
  out.site_from_model = s;
  out.control_rms = fit.rms;
  out.success = true;
  out.message = Message("scaled by ", fit.num_inliers, " control points, rms ", fit.rms, " m");
  return out;
}

}  // namespace geometry
}  // namespace slope_monitor
