// Synthetic survey scenes with known truth for the adjustment tests, made
// from the camera model (fixed seeds): a slope rising to the north, control
// points on stable ground, monitoring points on a moving body, check points,
// tie points; fixed cameras 100-200 m away across the valley, or a UAV block
// at ~60 m above ground with GNSS priors.
#pragma once

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"

namespace slope_monitor {
namespace adjustment {
namespace testing {

inline camera::ExteriorOrientation LookAt(const Eigen::Vector3d& position,
                                          const Eigen::Vector3d& target, double kappa) {
  const Eigen::Vector3d z = (position - target).normalized();  // the camera looks along -z
  camera::ExteriorOrientation e;
  e.position = position;
  e.angles.phi = std::asin(z.y());
  e.angles.theta = std::atan2(z.x(), z.z());
  e.angles.kappa = kappa;
  return e;
}

inline double SlopeHeight(double x, double y, double rise) {
  return rise * y + 1.5 * std::sin(0.07 * x) * std::cos(0.05 * y);
}

// The displacement of a monitoring point between epochs (truth).
inline Eigen::Vector3d BodyMotion(const Eigen::Vector3d& x, double amount) {
  // Moves downslope (south and down), more near the body centre (100, 75).
  const double w = std::exp(-((x.x() - 100.0) * (x.x() - 100.0) + (x.y() - 75.0) * (x.y() - 75.0)) /
                            (2 * 40.0 * 40.0));
  return amount * w * Eigen::Vector3d(0.1, -0.9, -0.42).normalized();
}

struct TruthScene {
  Scene truth;     // true values everywhere
  Scene observed;  // noisy observations and perturbed initial values
};

struct SceneSpec {
  bool uav = false;
  unsigned int seed = 1;
  double pixel_sigma = 0.1;       // [px]
  double survey_sigma_h = 0.003;  // [m]
  double survey_sigma_v = 0.003;  // [m]
  double gnss_sigma = 0.03;       // [m]
  int num_tie = 60;
  double motion = 0.0;        // [m] body motion of this epoch (0 = reference)
  double camera_drift = 0.0;  // [rad] fixed cameras: attitude change of this epoch
  bool perturb_initial = true;
  bool true_interior_differs = true;  // interior truth differs from the nominal (initial) one
};

// Builds the truth and the observed scene.
inline TruthScene MakeScene(const SceneSpec& spec) {
  std::mt19937 rng(spec.seed);
  std::mt19937 point_rng(1234);  // the points themselves are the same in every epoch
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> ux(10, 190), uy(5, 145);
  TruthScene s;
  Scene& t = s.truth;
  const double rise = spec.uav ? 0.15 : 0.3;

  // Cameras.
  std::array<double, camera::kNumInterior> nominal{};
  std::array<double, camera::kNumInterior> truth_in{};
  camera::Sensor sensor;
  camera::DistortionModel model;
  if (spec.uav) {
    sensor = camera::Sensor{5472, 3648, 0.0024};
    model = camera::DistortionModel::kRadial;
    nominal[camera::kC] = 8.8;
    truth_in = nominal;
    if (spec.true_interior_differs) {
      truth_in[camera::kC] = 8.85;
      truth_in[camera::kX0] = 0.02;
      truth_in[camera::kY0] = -0.015;
      truth_in[camera::kK1] = -1.5e-4;
      truth_in[camera::kK2] = 4e-7;
    }
    t.cameras.push_back({"uav", camera::CameraModel(sensor, model, truth_in)});
  } else {
    sensor = camera::Sensor{6000, 4000, 0.0039};
    model = camera::DistortionModel::kRadial;
    nominal[camera::kC] = 35.0;  // a 35 mm lens sees the compact fixed-camera site from 100-200 m
    nominal[camera::kK1] = 2e-5;
    truth_in = nominal;
    for (int c = 0; c < 3; ++c)
      t.cameras.push_back(
          {"fixed_cam_" + std::to_string(c + 1), camera::CameraModel(sensor, model, truth_in)});
  }

  // Images.
  if (spec.uav) {
    const double z_fly = 80.0;  // 58-80 m above the ground (ground at 0-22 m)
    int k = 0;
    for (int strip = 0; strip < 4; ++strip) {
      for (int shot = 0; shot < 6; ++shot) {
        Image im;
        im.name = "uav_" + std::to_string(k++);
        im.camera = 0;
        const double x = 30.0 + 28.0 * shot;
        const double y = 20.0 + 36.0 * strip;
        im.exterior.position =
            Eigen::Vector3d(x + 0.5 * n01(rng), y + 0.5 * n01(rng), z_fly + 0.3 * n01(rng));
        im.exterior.angles.theta = 0.02 * n01(rng);
        im.exterior.angles.phi = 0.02 * n01(rng);
        im.exterior.angles.kappa = (strip % 2 ? M_PI : 0.0) + 0.02 * n01(rng);
        t.images.push_back(im);
      }
    }
    // Two oblique cross images (help the self-calibration of c).
    for (int o = 0; o < 4; ++o) {
      Image im;
      im.name = "uav_oblique_" + std::to_string(o);
      im.camera = 0;
      const Eigen::Vector3d pos(o < 2 ? 20.0 + 160.0 * o : 100.0,
                                o < 2 ? 75.0 : 5.0 + 140.0 * (o - 2), 75.0);
      im.exterior = LookAt(pos, Eigen::Vector3d(100, 75, 10), 0.5 * o);
      t.images.push_back(im);
    }
  } else {
    const Eigen::Vector3d aim(100, 75, SlopeHeight(100, 75, rise));
    const Eigen::Vector3d pos[3] = {{30, -70, 35}, {100, -85, 40}, {170, -70, 35}};
    for (int c = 0; c < 3; ++c) {
      Image im;
      im.name = t.cameras[c].name;
      im.camera = c;
      im.exterior = LookAt(pos[c], aim, 0.01 * (c - 1));
      im.exterior.angles.theta += spec.camera_drift * (c + 1) * 0.3;
      im.exterior.angles.phi -= spec.camera_drift;
      im.exterior.angles.kappa += spec.camera_drift * 0.5;
      t.images.push_back(im);
    }
  }

  // Points: control on the stable margins, monitoring on the body, check, tie.
  auto add_point = [&](const std::string& id, PointRole role, double x, double y) {
    if (!spec.uav) {  // fixed cameras watch a compact 100 m x 80 m window around the body
      x = 100.0 + 0.55 * (x - 100.0);
      y = 75.0 + 0.55 * (y - 75.0);
    }
    ObjectPoint p;
    p.id = id;
    p.role = role;
    p.position =
        Eigen::Vector3d(x, y, SlopeHeight(x, y, rise) + (role == PointRole::kTie ? 0.0 : 0.8));
    if (role == PointRole::kMonitoring) p.position += BodyMotion(p.position, spec.motion);
    t.points.push_back(p);
  };
  const double ctrl[][2] = {{15, 10},  {100, 8},   {185, 12},  {12, 75}, {188, 80},
                            {18, 140}, {100, 142}, {182, 138}, {55, 40}, {150, 115}};
  for (int i = 0; i < 10; ++i)
    add_point("tag36h11/" + std::to_string(i), PointRole::kControl, ctrl[i][0], ctrl[i][1]);
  for (int i = 0; i < 4; ++i)
    add_point("tag36h11/" + std::to_string(50 + i), PointRole::kCheck, 40.0 + 40.0 * i,
              i % 2 ? 25.0 : 125.0);
  for (int i = 0; i < 20; ++i) {
    const double a = 2 * M_PI * i / 20.0, r = 10.0 + 25.0 * ((i * 7) % 10) / 10.0;
    add_point("tag36h11/" + std::to_string(100 + i), PointRole::kMonitoring, 100 + r * std::cos(a),
              75 + 0.8 * r * std::sin(a));
  }
  for (int i = 0; i < spec.num_tie; ++i) {
    const double x = ux(point_rng), y = uy(point_rng);
    add_point("tie/" + std::to_string(i), PointRole::kTie, x, y);
  }
  // Survey of control and check points (noisy, same survey in every epoch).
  std::mt19937 survey_rng(777);
  for (ObjectPoint& p : t.points) {
    if (p.role != PointRole::kControl && p.role != PointRole::kCheck) continue;
    p.surveyed_covariance = Eigen::Vector3d(spec.survey_sigma_h * spec.survey_sigma_h,
                                            spec.survey_sigma_h * spec.survey_sigma_h,
                                            spec.survey_sigma_v * spec.survey_sigma_v)
                                .asDiagonal();
    p.surveyed = p.position + Eigen::Vector3d(spec.survey_sigma_h * n01(survey_rng),
                                              spec.survey_sigma_h * n01(survey_rng),
                                              spec.survey_sigma_v * n01(survey_rng));
  }
  // Observations (true projections inside the sensor with a margin).
  for (size_t i = 0; i < t.images.size(); ++i) {
    const camera::CameraModel& cam = t.cameras[t.images[i].camera].model;
    for (size_t j = 0; j < t.points.size(); ++j) {
      Eigen::Vector2d px;
      if (!cam.Project(t.images[i].exterior, t.points[j].position, &px)) continue;
      if (px.x() < 20 || px.y() < 20 || px.x() > sensor.width - 21 || px.y() > sensor.height - 21)
        continue;
      Observation o;
      o.image = static_cast<int>(i);
      o.point = static_cast<int>(j);
      o.pixel = px;
      o.covariance = Eigen::Matrix2d::Identity() * spec.pixel_sigma * spec.pixel_sigma;
      t.observations.push_back(o);
    }
  }
  // GNSS priors.
  if (spec.uav) {
    for (Image& im : t.images) {
      im.position_prior = im.exterior.position;  // replaced by a noisy copy below
      im.position_prior_covariance =
          Eigen::Matrix3d::Identity() * spec.gnss_sigma * spec.gnss_sigma;
    }
  }

  // Observed scene: noise on pixels and GNSS, nominal interior, perturbed
  // initial values.
  Scene o = t;
  for (Observation& ob : o.observations)
    ob.pixel += spec.pixel_sigma * Eigen::Vector2d(n01(rng), n01(rng));
  for (Image& im : o.images) {
    if (im.position_prior)
      *im.position_prior += spec.gnss_sigma * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
    if (spec.perturb_initial) {
      im.exterior.position += 0.5 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      im.exterior.angles.theta += 0.005 * n01(rng);
      im.exterior.angles.phi += 0.005 * n01(rng);
      im.exterior.angles.kappa += 0.005 * n01(rng);
    }
  }
  for (Camera& c : o.cameras) c.model = camera::CameraModel(sensor, model, nominal);
  for (ObjectPoint& p : o.points) {
    if (spec.perturb_initial) p.position += 0.5 * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
  }
  s.observed = o;
  return s;
}

}  // namespace testing
}  // namespace adjustment
}  // namespace slope_monitor
