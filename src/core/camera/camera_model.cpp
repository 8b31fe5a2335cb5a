#include "slope_monitor/core/camera/camera_model.h"

#include <cmath>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace camera {
namespace {

bool Finite(double v) { return std::isfinite(v); }

// Lens distortion only (no affinity) and its Jacobian d(xl, yl)/d(xu, yu).
void LensDistort(const std::array<double, kNumInterior>& p, double xu, double yu, double* xl,
                 double* yl, Eigen::Matrix2d* jacobian) {
  const double r2 = xu * xu + yu * yu;
  const double radial = p[kK1] * r2 + p[kK2] * r2 * r2 + p[kK3] * r2 * r2 * r2;
  const double dradial = p[kK1] + 2.0 * p[kK2] * r2 + 3.0 * p[kK3] * r2 * r2;  // d radial / d r2
  *xl = xu + xu * radial + p[kP1] * (r2 + 2.0 * xu * xu) + 2.0 * p[kP2] * xu * yu;
  *yl = yu + yu * radial + p[kP2] * (r2 + 2.0 * yu * yu) + 2.0 * p[kP1] * xu * yu;
  if (jacobian) {
    const double cross = 2.0 * xu * yu * dradial + 2.0 * p[kP1] * yu + 2.0 * p[kP2] * xu;
    (*jacobian)(0, 0) =
        1.0 + radial + 2.0 * xu * xu * dradial + 6.0 * p[kP1] * xu + 2.0 * p[kP2] * yu;
    (*jacobian)(0, 1) = cross;
    (*jacobian)(1, 0) = cross;
    (*jacobian)(1, 1) =
        1.0 + radial + 2.0 * yu * yu * dradial + 6.0 * p[kP2] * yu + 2.0 * p[kP1] * xu;
  }
}

}  // namespace

const std::array<const char*, kNumInterior>& InteriorNames() {
  static const std::array<const char*, kNumInterior> names = {"c",  "x0", "y0", "k1", "k2",
                                                              "k3", "p1", "p2", "b1", "b2"};
  return names;
}

DistortionModel DistortionModelFromName(const std::string& name) {
  if (name == "none") return DistortionModel::kNone;
  if (name == "radial") return DistortionModel::kRadial;
  if (name == "brown") return DistortionModel::kBrown;
  if (name == "brown_affinity") return DistortionModel::kBrownAffinity;
  throw InvalidArgument(Message("unknown distortion model '", name,
                                "' (expected one of: none, radial, brown, brown_affinity)"));
}

std::string DistortionModelName(DistortionModel model) {
  switch (model) {
    case DistortionModel::kNone:
      return "none";
    case DistortionModel::kRadial:
      return "radial";
    case DistortionModel::kBrown:
      return "brown";
    case DistortionModel::kBrownAffinity:
      return "brown_affinity";
  }
  return "unknown";
}

std::vector<int> InteriorIndicesOf(DistortionModel model) {
  std::vector<int> idx = {kC, kX0, kY0};
  if (model != DistortionModel::kNone) idx.insert(idx.end(), {kK1, kK2, kK3});
  if (model == DistortionModel::kBrown || model == DistortionModel::kBrownAffinity)
    idx.insert(idx.end(), {kP1, kP2});
  if (model == DistortionModel::kBrownAffinity) idx.insert(idx.end(), {kB1, kB2});
  return idx;
}

ExteriorOrientation ExteriorOrientation::FromArray(const double* e) {
  ExteriorOrientation eo;
  eo.position = Eigen::Vector3d(e[0], e[1], e[2]);
  eo.angles = AttitudeAngles{e[3], e[4], e[5]};
  return eo;
}

Rigid3 ExteriorOrientation::CamFromSite() const {
  const Eigen::Matrix3d m = RotationFromAngles(angles);
  return Rigid3(m, -(m * position));
}

Rigid3 ExteriorOrientation::OpticalFromSite() const {
  const Eigen::Matrix3d r = OpticalFromPhotogrammetric() * RotationFromAngles(angles);
  return Rigid3(r, -(r * position));
}

ExteriorOrientation ExteriorOrientation::FromOpticalFromSite(const Rigid3& optical_from_site) {
  ExteriorOrientation eo;
  const Eigen::Matrix3d r = optical_from_site.RotationMatrix();
  eo.position = -(r.transpose() * optical_from_site.translation);
  eo.angles = AnglesFromRotation(OpticalFromPhotogrammetric() * r);
  return eo;
}

CameraModel::CameraModel(const Sensor& sensor, DistortionModel model,
                         const std::array<double, kNumInterior>& interior)
    : sensor_(sensor), model_(model), interior_(interior) {}

void CameraModel::Check() const {
  if (sensor_.width <= 0 || sensor_.height <= 0) {
    throw InvalidArgument(
        Message("camera sensor size ", sensor_.width, "x", sensor_.height, " px is not positive"));
  }
  if (!Finite(sensor_.pixel_size) || sensor_.pixel_size <= 0.0) {
    throw InvalidArgument(
        Message("camera pixel_size ", sensor_.pixel_size, " mm is not a positive number"));
  }
  for (int i = 0; i < kNumInterior; ++i) {
    if (!Finite(interior_[i])) {
      throw InvalidArgument(
          Message("camera parameter '", InteriorNames()[i], "' is ", interior_[i]));
    }
  }
  if (interior_[kC] <= 0.0) {
    throw InvalidArgument(
        Message("camera principal distance 'c' = ", interior_[kC], " mm must be > 0"));
  }
  const std::vector<int> used = InteriorIndicesOf(model_);
  for (int i = 0; i < kNumInterior; ++i) {
    bool in_model = false;
    for (int u : used) in_model = in_model || u == i;
    if (!in_model && interior_[i] != 0.0) {
      throw InvalidArgument(Message("camera parameter '", InteriorNames()[i], "' = ", interior_[i],
                                    " is not part of distortion model '",
                                    DistortionModelName(model_), "'"));
    }
  }
}

bool CameraModel::ProjectMm(const ExteriorOrientation& pose, const Eigen::Vector3d& point_in_site,
                            Eigen::Vector2d* xy_mm) const {
  const std::array<double, kNumExterior> e = pose.ToArray();
  return ProjectToImageMm(e.data(), interior_.data(), point_in_site.data(), xy_mm->data());
}

bool CameraModel::Project(const ExteriorOrientation& pose, const Eigen::Vector3d& point_in_site,
                          Eigen::Vector2d* pixel) const {
  Eigen::Vector2d mm;
  const bool in_front = ProjectMm(pose, point_in_site, &mm);
  *pixel = MmToPixel(mm);
  return in_front;
}

Eigen::Vector2d CameraModel::DistortMm(const Eigen::Vector2d& ideal) const {
  double xd, yd;
  Distort(interior_.data(), ideal.x(), ideal.y(), &xd, &yd);
  return Eigen::Vector2d(interior_[kX0] + xd, interior_[kY0] + yd);
}

Eigen::Vector2d CameraModel::UndistortMm(const Eigen::Vector2d& measured) const {
  // Remove the principal point and the affinity exactly, then invert the lens
  // distortion by Newton's method starting from the distorted point.
  const double yl = measured.y() - interior_[kY0];
  const double xl = (measured.x() - interior_[kX0] - interior_[kB2] * yl) / (1.0 + interior_[kB1]);
  Eigen::Vector2d u(xl, yl);
  for (int it = 0; it < 50; ++it) {
    double fx, fy;
    Eigen::Matrix2d j;
    LensDistort(interior_, u.x(), u.y(), &fx, &fy, &j);
    const Eigen::Vector2d residual(fx - xl, fy - yl);
    const Eigen::Vector2d step = j.lu().solve(residual);
    if (!step.allFinite()) break;
    u -= step;
    if (step.norm() < 1e-13) return u;
  }
  double fx, fy;
  LensDistort(interior_, u.x(), u.y(), &fx, &fy, nullptr);
  if (u.allFinite() && std::hypot(fx - xl, fy - yl) < 1e-9) return u;
  throw InvalidArgument(Message("cannot undistort image point (", measured.x(), ", ", measured.y(),
                                ") mm: the distortion model does not invert there"));
}

Eigen::Vector2d CameraModel::MmToPixel(const Eigen::Vector2d& xy_mm) const {
  Eigen::Vector2d px;
  camera::MmToPixel(sensor_, xy_mm.x(), xy_mm.y(), &px.x(), &px.y());
  return px;
}

Eigen::Vector2d CameraModel::PixelToMm(const Eigen::Vector2d& pixel) const {
  return Eigen::Vector2d((pixel.x() - 0.5 * (sensor_.width - 1)) * sensor_.pixel_size,
                         -(pixel.y() - 0.5 * (sensor_.height - 1)) * sensor_.pixel_size);
}

Ray CameraModel::ImageToRay(const ExteriorOrientation& pose, const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d ideal = UndistortMm(PixelToMm(pixel));
  const Eigen::Vector3d in_cam(ideal.x(), ideal.y(), -interior_[kC]);
  Ray ray;
  ray.origin = pose.position;
  ray.direction = (RotationFromAngles(pose.angles).transpose() * in_cam).normalized();
  return ray;
}

Eigen::Vector3d CameraModel::PixelToOpticalDirection(const Eigen::Vector2d& pixel) const {
  const Eigen::Vector2d ideal = UndistortMm(PixelToMm(pixel));
  return (OpticalFromPhotogrammetric() * Eigen::Vector3d(ideal.x(), ideal.y(), -interior_[kC]))
      .normalized();
}

OpenCvCamera CameraModel::ToOpenCv() const {
  Check();
  if (interior_[kB2] != 0.0) {
    throw InvalidArgument(
        Message("camera shear b2 = ", interior_[kB2],
                " cannot be represented in OpenCV's camera matrix (projectPoints has no skew)"));
  }
  const double c = interior_[kC];
  const double ps = sensor_.pixel_size;
  OpenCvCamera cv;
  cv.width = sensor_.width;
  cv.height = sensor_.height;
  cv.k << (1.0 + interior_[kB1]) * c / ps, 0.0, 0.5 * (sensor_.width - 1) + interior_[kX0] / ps,
      0.0, c / ps, 0.5 * (sensor_.height - 1) - interior_[kY0] / ps, 0.0, 0.0, 1.0;
  // Normalised OpenCV coordinates are x' = xu / c, y' = -yu / c (y down).
  cv.distortion = {interior_[kK1] * c * c, interior_[kK2] * std::pow(c, 4), -interior_[kP2] * c,
                   interior_[kP1] * c, interior_[kK3] * std::pow(c, 6)};
  return cv;
}

CameraModel CameraModel::FromOpenCv(const OpenCvCamera& cv, double pixel_size) {
  static const char* kCoeffNames[] = {"k1", "k2", "p1", "p2", "k3", "k4",    "k5",
                                      "k6", "s1", "s2", "s3", "s4", "tau_x", "tau_y"};
  const size_t n = cv.distortion.size();
  if (!(n == 0 || n == 4 || n == 5 || n == 8 || n == 12 || n == 14)) {
    throw InvalidArgument(Message("OpenCV distortion vector has ", n,
                                  " coefficients (expected 0, 4, 5, 8, 12 or 14)"));
  }
  for (size_t i = 0; i < n; ++i) {
    if (!Finite(cv.distortion[i])) {
      throw InvalidArgument(
          Message("OpenCV distortion coefficient ", kCoeffNames[i], " is ", cv.distortion[i]));
    }
    if (i >= 5 && cv.distortion[i] != 0.0) {
      throw InvalidArgument(
          Message("OpenCV distortion coefficient ", kCoeffNames[i], " = ", cv.distortion[i],
                  " has no equivalent in the collinearity model (only k1 k2 p1 p2 k3)"));
    }
  }
  if (!cv.k.allFinite())
    throw InvalidArgument("OpenCV camera matrix K has a NaN or infinite element");
  if (cv.k(0, 1) != 0.0) {
    throw InvalidArgument(Message("OpenCV camera matrix has skew K[0][1] = ", cv.k(0, 1),
                                  ", which the collinearity model does not represent"));
  }
  if (cv.k(1, 0) != 0.0 || cv.k(2, 0) != 0.0 || cv.k(2, 1) != 0.0 || cv.k(2, 2) != 1.0) {
    throw InvalidArgument(
        "OpenCV camera matrix K is not of the form [[fx 0 cx] [0 fy cy] [0 0 1]]");
  }
  if (cv.k(0, 0) <= 0.0 || cv.k(1, 1) <= 0.0) {
    throw InvalidArgument(
        Message("OpenCV focal lengths fx = ", cv.k(0, 0), ", fy = ", cv.k(1, 1), " must be > 0"));
  }
  auto coeff = [&](size_t i) { return i < n ? cv.distortion[i] : 0.0; };
  Sensor sensor{cv.width, cv.height, pixel_size};
  std::array<double, kNumInterior> p{};
  const double c = cv.k(1, 1) * pixel_size;
  p[kC] = c;
  p[kB1] = cv.k(0, 0) / cv.k(1, 1) - 1.0;
  p[kX0] = (cv.k(0, 2) - 0.5 * (cv.width - 1)) * pixel_size;
  p[kY0] = -(cv.k(1, 2) - 0.5 * (cv.height - 1)) * pixel_size;
  p[kK1] = coeff(0) / (c * c);
  p[kK2] = coeff(1) / std::pow(c, 4);
  p[kK3] = coeff(4) / std::pow(c, 6);
  p[kP1] = coeff(3) / c;
  p[kP2] = -coeff(2) / c;
  DistortionModel model = DistortionModel::kNone;
  if (p[kK1] != 0.0 || p[kK2] != 0.0 || p[kK3] != 0.0) model = DistortionModel::kRadial;
  if (p[kP1] != 0.0 || p[kP2] != 0.0) model = DistortionModel::kBrown;
  if (p[kB1] != 0.0) model = DistortionModel::kBrownAffinity;
  CameraModel result(sensor, model, p);
  result.Check();
  return result;
}

CameraInfoFields CameraModel::ToCameraInfo() const {
  const OpenCvCamera cv = ToOpenCv();
  CameraInfoFields info;
  info.width = cv.width;
  info.height = cv.height;
  info.distortion_model = "plumb_bob";
  info.d = cv.distortion;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      info.k[3 * r + c] = cv.k(r, c);
      info.r[3 * r + c] = r == c ? 1.0 : 0.0;
      info.p[4 * r + c] = cv.k(r, c);
    }
    info.p[4 * r + 3] = 0.0;
  }
  return info;
}

CameraModel CameraModel::FromCameraInfo(const CameraInfoFields& info, double pixel_size) {
  if (info.width <= 0 || info.height <= 0) {
    throw InvalidArgument(
        Message("CameraInfo size ", info.width, "x", info.height, " is not positive"));
  }
  if (info.distortion_model == "plumb_bob" || (info.distortion_model.empty() && info.d.empty())) {
    if (!(info.d.empty() || info.d.size() == 5)) {
      throw InvalidArgument(Message(
          "CameraInfo distortion_model 'plumb_bob' needs 5 coefficients, got ", info.d.size()));
    }
  } else if (info.distortion_model == "rational_polynomial") {
    if (info.d.size() != 8) {
      throw InvalidArgument(
          Message("CameraInfo distortion_model 'rational_polynomial' needs 8 coefficients, got ",
                  info.d.size()));
    }
  } else {
    throw InvalidArgument(Message(
        "CameraInfo distortion_model '", info.distortion_model,
        "' cannot be represented (supported: plumb_bob, rational_polynomial with k4..k6 = 0)"));
  }
  OpenCvCamera cv;
  cv.width = info.width;
  cv.height = info.height;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) cv.k(r, c) = info.k[3 * r + c];
  }
  cv.distortion = info.d;
  return FromOpenCv(cv, pixel_size);
}

}  // namespace camera
}  // namespace slope_monitor
