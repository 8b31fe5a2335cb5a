#include "slope_monitor/core/dense/targetless_camera.h"

#include <cmath>
#include <utility>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/io/image_polygons.h"

namespace slope_monitor {
namespace dense {
namespace {}  // namespace

matching::HexMatcherOptions TargetlessCameraOptions::TrackingMatcherOptions() {
  matching::HexMatcherOptions o;
  o.interest.max_points = 40000;
  o.lsc_prefilter_sigma = 1.0;
  return o;
}

void TargetlessCameraOptions::Check() const {
  matcher.Check();
  reorient.Check();
  field.Check();
  if (!(match_radius > 0.0))
    throw InvalidArgument(Message("match_radius ", match_radius, " px must be > 0"));
  if (!(max_rotation_deg > 0.0))
    throw InvalidArgument(Message("max_rotation_deg ", max_rotation_deg, " deg must be > 0"));
}

ImageAreas AreasFromSitePolygons(const camera::CameraModel& model,
                                 const camera::ExteriorOrientation& reference,
                                 const io::GeoRaster& dem,
                                 const std::vector<Eigen::Vector2d>& outline,
                                 const std::vector<std::vector<Eigen::Vector2d>>& stable,
                                 double max_range) {
  if (outline.empty() && stable.empty())
    throw InvalidArgument(
        "the site gives neither stable areas nor a monitored outline: a fixed_targetless camera "
        "needs one of them (areas.stable / areas.outline) or a stable_polygons file");
  // Where the reference ray of a pixel meets the DEM (x, y), or false.
  // The model and the pose are copied; the DEM must outlive the predicates.
  const io::GeoRaster* surface = &dem;
  auto ground = [model, reference, surface, max_range](const Eigen::Vector2d& px,
                                                       Eigen::Vector2d* xy) {
    const camera::Ray ray = model.ImageToRay(reference, px);
    const Eigen::Vector3d d = ray.direction.normalized();
    double t = 0.0;
    if (!IntersectDem(*surface, ray.origin, d, max_range, &t)) return false;
    *xy = (ray.origin + t * d).head<2>();
    return true;
  };
  auto in_outline = [outline](const Eigen::Vector2d& xy) {
    return outline.empty() || io::InsidePolygon(outline, xy);
  };
  ImageAreas a;
  a.stable = [ground, stable, in_outline](const Eigen::Vector2d& px) {
    Eigen::Vector2d xy;
    if (!ground(px, &xy)) return false;
    if (stable.empty()) return !in_outline(xy);
    return io::InsideAny(stable, xy);
  };
  a.monitored = [ground, stable, in_outline](const Eigen::Vector2d& px) {
    Eigen::Vector2d xy;
    return ground(px, &xy) && in_outline(xy) && !io::InsideAny(stable, xy);
  };
  return a;
}

TargetlessCamera::TargetlessCamera(std::string name, const camera::CameraModel& model,
                                   const camera::ExteriorOrientation& reference,
                                   const io::GeoRaster* dem, ImageAreas areas,
                                   const TargetlessCameraOptions& options)
    : name_(std::move(name)),
      model_(model),
      reference_(reference),
      dem_(dem),
      areas_(std::move(areas)),
      options_(options),
      matcher_((options.Check(), options.matcher)) {
  if (areas_.stable && !areas_.monitored) {
    const ImagePredicate stable = areas_.stable;
    areas_.monitored = [stable](const Eigen::Vector2d& x) { return !stable(x); };
  }
}

void TargetlessCamera::SetReference(const cv::Mat& image, double time) {
  if (image.cols != model_.sensor().width || image.rows != model_.sensor().height ||
      image.type() != CV_8UC1)
    throw InvalidArgument(Message("camera '", name_, "': reference photo is ", image.cols, "x",
                                  image.rows, " px of type ", image.type(), ", the camera ",
                                  model_.sensor().width, "x", model_.sensor().height,
                                  " 8-bit single channel"));
  reference_image_ = image.clone();
  reference_time_ = time;
}

TargetlessEpoch TargetlessCamera::Process(const cv::Mat& image, double time,
                                          const std::string& dem_name) const {
  if (!has_reference())
    throw InvalidArgument(Message("camera '", name_, "': no reference photo yet"));
  if (image.size() != reference_image_.size() || image.type() != reference_image_.type())
    throw InvalidArgument(Message("camera '", name_, "': photo is ", image.cols, "x", image.rows,
                                  " px of type ", image.type(), ", the reference ",
                                  reference_image_.cols, "x", reference_image_.rows, " of type ",
                                  reference_image_.type()));
  TargetlessEpoch e;
  e.dt = time - reference_time_;
  const ImagePredicate& stable = areas_.stable;
  matching::MatchPrior prior;
  prior.estimate_global_shift = true;
  prior.radius = options_.match_radius;
  if (stable) {
    prior.within = stable;
    prior.moving = [&stable](const Eigen::Vector2d& x) { return !stable(x); };
  }
  const matching::HexMatchResult m = matcher_.Match(reference_image_, image, prior);
  e.matches = m.summary;
  std::vector<adjustment::StableTiePoint> ties;
  for (const auto& h : m.matches)
    if (!h.IsLowQuality() && (!stable || stable(h.xa))) ties.push_back({h.xa, h.xb});
  e.ties = static_cast<int>(ties.size());
  e.reorientation = adjustment::ReorientCamera(model_, reference_, ties, options_.reorient);
  const adjustment::ReorientSummary& r = e.reorientation;
  if (!r.success) {
    e.warnings.push_back(
        Message("camera '", name_, "': no re-orientation (", r.message, "); no field"));
    return e;
  }
  static const char* kAngle[] = {"theta", "phi", "kappa"};
  if (r.rotation_angle * kDegPerRad > options_.max_rotation_deg)
    e.warnings.push_back(Message("camera '", name_, "' turned by ", r.rotation_angle * kDegPerRad,
                                 " deg since the reference photo (limit ",
                                 options_.max_rotation_deg, " deg)"));
  for (int k = 0; k < 3; ++k)
    if (std::abs(r.delta(k)) * kDegPerRad > options_.max_rotation_deg)
      e.warnings.push_back(Message("camera '", name_, "': ", kAngle[k], " changed by ",
                                   r.delta(k) * kDegPerRad, " deg (limit ",
                                   options_.max_rotation_deg, " deg)"));
  if (!dem_) return e;
  FieldInput in;
  in.model = model_;
  in.reference = reference_;
  in.current = r.exterior;
  in.attitude_covariance = r.covariance;
  in.dt = e.dt;
  in.stable = areas_.stable;
  in.monitored = areas_.monitored;
  in.dem_name = dem_name;
  e.field = ComputeDisplacementField(reference_image_, image, *dem_, in, options_.field);
  e.has_field = true;
  return e;
}

}  // namespace dense
}  // namespace slope_monitor
