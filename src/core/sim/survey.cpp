#include "slope_monitor/core/sim/survey.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <random>
#include <sstream>

#include <Eigen/Geometry>

#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {
namespace {

// Independent, reproducible generator streams.
std::mt19937 Stream(unsigned int seed, unsigned int a, unsigned int b = 0, unsigned int c = 0) {
  std::seed_seq seq{seed, a, b, c, 0x5157u};
  return std::mt19937(seq);
}

double Gauss(std::mt19937* rng, double sigma) {
  std::normal_distribution<double> n(0.0, 1.0);
  return sigma * n(*rng);
}

// The mast turns between consecutive epochs by an angle uniform in
// [mast_rotation_min, max] about a uniformly random axis (the installation's
// sway, warming and settling); epoch 0 keeps its pose.
void TurnMast(const CameraSpec& s, std::mt19937 rng, std::vector<ImageTruth>* images) {
  if (!(s.mast_rotation_max > 0.0)) return;
  std::uniform_real_distribution<double> angle(s.mast_rotation_min, s.mast_rotation_max);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (size_t k = 1; k < images->size(); ++k) {
    Eigen::Vector3d axis(normal(rng), normal(rng), normal(rng));
    axis.normalize();
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(angle(rng), axis).toRotationMatrix();
    (*images)[k].exterior.angles = camera::AnglesFromRotation(
        turn * camera::RotationFromAngles((*images)[k - 1].exterior.angles));
  }
}

// Stable ground points a crew would survey and pick in the reference photo:
// the rays of a regular pixel grid (inset 8 %) that reach the ground outside
// the landslide (weight 0) unoccluded, `surveyed_points` of them spread over
// the grid; positions with the targets' survey noise, pixels with the
// picking noise.
std::vector<SurveyedPointTruth> PickSurveyedPoints(const CameraSpec& s, const Scene::State& ref,
                                                   const SurveyConfig& c, std::mt19937 rng,
                                                   const camera::ExteriorOrientation& pose) {
  std::vector<SurveyedPointTruth> out;
  if (s.surveyed_points <= 0) return out;
  const int w = s.model.sensor().width, h = s.model.sensor().height;
  std::vector<Eigen::Vector3d> candidates;
  const int n = 16;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d px(w * (0.08 + 0.84 * (i + 0.5) / n),
                               h * (0.08 + 0.84 * (j + 0.5) / n));
      const camera::Ray ray = s.model.ImageToRay(pose, px);
      const double d = ref.grid.IntersectRay(ray.origin, ray.direction, 20000.0);
      if (!std::isfinite(d)) continue;
      const Eigen::Vector3d p = ray.origin + d * ray.direction;
      if (c.scene.landslide.Weight(p.head<2>()) > 0.0) continue;
      bool occluded = false;
      Eigen::Vector3d normal;
      for (const Obstacle& o : ref.obstacles) {
        const double t = IntersectObstacle(o, ray.origin, ray.direction, &normal);
        if (t >= 0.0 && t < d) occluded = true;
      }
      if (!occluded) candidates.push_back(p);
    }
  }
  if (static_cast<int>(candidates.size()) < s.surveyed_points) {
    throw ConfigError(Message(s.key, ": surveyed_points ", s.surveyed_points, " but only ",
                              candidates.size(), " stable ground points are in view of camera '",
                              s.name, "'"));
  }
  // Spread: every k-th candidate of the grid order.
  const double step = static_cast<double>(candidates.size()) / s.surveyed_points;
  for (int k = 0; k < s.surveyed_points; ++k) {
    SurveyedPointTruth sp;
    sp.id = "s" + std::to_string(k + 1);
    sp.position = candidates[static_cast<size_t>(k * step)];
    sp.surveyed = sp.position + Eigen::Vector3d(Gauss(&rng, c.survey_sigma.x()),
                                                Gauss(&rng, c.survey_sigma.x()),
                                                Gauss(&rng, c.survey_sigma.y()));
    Eigen::Vector2d px;
    s.model.Project(pose, sp.position, &px);
    sp.picked =
        px + Eigen::Vector2d(Gauss(&rng, s.picked_pixel_sigma), Gauss(&rng, s.picked_pixel_sigma));
    out.push_back(sp);
  }
  return out;
}

std::string EpochSuffix(int k) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "_e%02d", k);
  return buf;
}

}  // namespace

camera::ExteriorOrientation LookAt(const Eigen::Vector3d& position, const Eigen::Vector3d& look_at,
                                   const Eigen::Vector3d& up_hint, double roll) {
  const Eigen::Vector3d f = (look_at - position).normalized();
  Eigen::Vector3d right = f.cross(up_hint);
  if (right.norm() < 1e-6) right = f.cross(Eigen::Vector3d::UnitY());
  if (right.norm() < 1e-6) right = f.cross(Eigen::Vector3d::UnitX());
  right.normalize();
  const Eigen::Vector3d down = f.cross(right);
  Eigen::Matrix3d site_from_optical;
  site_from_optical.col(0) = right;
  site_from_optical.col(1) = down;
  site_from_optical.col(2) = f;
  const Eigen::Matrix3d roll_m =
      Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  site_from_optical = site_from_optical * roll_m;
  const Eigen::Matrix3d optical_from_site = site_from_optical.transpose();
  return camera::ExteriorOrientation::FromOpticalFromSite(
      Rigid3(optical_from_site, -(optical_from_site * position)));
}

Eigen::Quaterniond FlightLogAttitude(const camera::ExteriorOrientation& pose, double sigma,
                                     unsigned int seed, int camera, int image) {
  std::seed_seq sequence{seed, 0x1e5a7u, static_cast<unsigned int>(camera),
                         static_cast<unsigned int>(image)};
  std::mt19937 rng(sequence);
  const Eigen::Vector3d w(Gauss(&rng, sigma), Gauss(&rng, sigma), Gauss(&rng, sigma));
  const Eigen::Quaterniond turn =
      w.norm() > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w.normalized()))
                     : Eigen::Quaterniond::Identity();
  return (turn * Eigen::Quaterniond(pose.SiteFromOptical().rotation)).normalized();
}

bool ImagedAt(const camera::CameraModel& model, const camera::ExteriorOrientation& pose,
              const Eigen::Vector3d& x, double margin_px, Eigen::Vector2d* pixel) {
  const int w = model.sensor().width, h = model.sensor().height;
  Eigen::Vector2d px;
  if (!model.Project(pose, x, &px) || !px.allFinite() || px.x() < margin_px || px.y() < margin_px ||
      px.x() > w - 1 - margin_px || px.y() > h - 1 - margin_px)
    return false;
  // The projection of a far-off-axis point can fold back under strong
  // distortion (the radial polynomial turns over): require the ideal
  // coordinates to be near the image too.
  const Eigen::Vector3d u = camera::RotationFromAngles(pose.angles) * (x - pose.position);
  const double xu = -model.principal_distance() * u.x() / u.z(),
               yu = -model.principal_distance() * u.y() / u.z();
  if (std::abs(xu) > 0.8 * w * model.sensor().pixel_size ||
      std::abs(yu) > 0.8 * h * model.sensor().pixel_size)
    return false;
  *pixel = px;
  return true;
}

std::vector<int> VisiblePlates(const Scene::State& state, const camera::CameraModel& model,
                               const camera::ExteriorOrientation& pose, double margin_px,
                               double tolerance) {
  std::vector<int> out;
  const Eigen::Vector3d cam = pose.position;
  for (size_t k = 0; k < state.plates.size(); ++k) {
    const Plate& p = state.plates[k];
    if (p.normal.dot(cam - p.centre) <= 0.0) continue;  // back side
    std::vector<Eigen::Vector3d> pts = p.Outline(16);
    pts.push_back(p.centre);
    bool ok = true;
    for (const Eigen::Vector3d& x : pts) {
      Eigen::Vector2d px;
      if (!ImagedAt(model, pose, x, margin_px, &px)) {
        ok = false;
        break;
      }
      const Eigen::Vector3d d = (x - cam).normalized();
      const double dist = (x - cam).norm();
      if (std::isfinite(state.grid.IntersectRay(cam, d, dist - tolerance))) {
        ok = false;
        break;
      }
      for (const Obstacle& o : state.obstacles) {
        const double t = IntersectObstacle(o, cam, d, nullptr);
        if (t > 0.0 && t < dist) {
          ok = false;
          break;
        }
      }
      if (!ok) break;
    }
    if (ok) out.push_back(static_cast<int>(k));
  }
  return out;
}

namespace {

// Every target and obstacle inside the site; control and check points on
// stable ground.
void CheckSurveyPlacements(const SurveyConfig& c) {
  const Eigen::Vector4d& ext = c.scene.terrain.extent;
  auto inside = [&](const Eigen::Vector2d& xy) {
    return xy.x() >= ext[0] && xy.x() <= ext[1] && xy.y() >= ext[2] && xy.y() <= ext[3];
  };
  const LandslideModel& l = c.scene.landslide;
  for (size_t i = 0; i < c.scene.targets.size(); ++i) {
    const TargetPlacement& t = c.scene.targets[i];
    const std::string key = i < c.target_keys_for_error.size() ? c.target_keys_for_error[i]
                                                               : Message("targets.list[", i, "]");
    if (!inside(t.xy))
      throw ConfigError(
          Message(key, ": 'position' (", t.xy.x(), ", ", t.xy.y(), ") is outside site.extent"));
    if (t.role != io::TargetRole::kMonitoring && l.Weight(t.xy) > 0.0) {
      throw ConfigError(Message(key, ": 'role' = ", io::TargetRoleName(t.role),
                                " but 'position' is on the moving landslide body (control and "
                                "check points must be on stable ground)"));
    }
  }
  for (size_t i = 0; i < c.scene.obstacles.size(); ++i) {
    if (!inside(c.scene.obstacles[i].base.head<2>())) {
      throw ConfigError(Message(c.path, ": obstacles[", i, "]: 'position' is outside site.extent"));
    }
  }
}

// A fixed camera's images: its surveyed pose with per-epoch jitter, the
// mast's turn, and the stable-ground points surveyed in its reference photo.
void PlanFixedCameraImages(const SurveyConfig& c, size_t ci, const Scene::State& ref,
                           const std::vector<EpochTruth>& epochs, std::mt19937* rng_in,
                           CameraTruth* ct_out) {
  const CameraSpec& s = c.cameras[ci];
  std::mt19937& rng = *rng_in;
  CameraTruth& ct = *ct_out;
  const int w = s.model.sensor().width, h = s.model.sensor().height;
  const Eigen::Vector2d centre_px(0.5 * (w - 1), 0.5 * (h - 1));
  ct.nominal_pose = s.pose;
  const camera::Ray ray = s.model.ImageToRay(s.pose, centre_px);
  if (!std::isfinite(ref.grid.IntersectRay(ray.origin, ray.direction, 20000.0))) {
    throw ConfigError(Message(s.key,
                              ": 'look_at' makes the camera look away from the slope "
                              "(its central ray does not hit the ground)"));
  }
  for (int k = 0; k < c.num_epochs; ++k) {
    ImageTruth im;
    im.epoch = k;
    im.stamp = epochs[k].stamp + 10.0 + 2.0 * ci;
    im.exterior = s.pose;
    im.exterior.position +=
        Eigen::Vector3d(Gauss(&rng, s.jitter_position), Gauss(&rng, s.jitter_position),
                        Gauss(&rng, s.jitter_position));
    im.exterior.angles.theta += Gauss(&rng, s.jitter_angle);
    im.exterior.angles.phi += Gauss(&rng, s.jitter_angle);
    im.exterior.angles.kappa += Gauss(&rng, s.jitter_angle);
    ct.images.push_back(im);
  }
  TurnMast(s, Stream(c.seed, 5, static_cast<unsigned>(ci)), &ct.images);
  ct.surveyed_points = PickSurveyedPoints(s, ref, c, Stream(c.seed, 6, static_cast<unsigned>(ci)),
                                          ct.images.front().exterior);
}

// A UAV camera's images, flight after flight: each strip's photos at the
// configured overlap (crab into the wind, altitude wander, track and
// attitude noise, GNSS), the turn to the next strip, 30 s per turn.
void PlanUavCameraImages(const SurveyConfig& c, size_t ci, const Scene& scene,
                         const Scene::State& ref, const std::vector<EpochTruth>& epochs,
                         std::mt19937* rng_in, CameraTruth* ct_out) {
  const CameraSpec& s = c.cameras[ci];
  std::mt19937& rng = *rng_in;
  CameraTruth& ct = *ct_out;
  const int w = s.model.sensor().width, h = s.model.sensor().height;
  const Eigen::Vector2d centre_px(0.5 * (w - 1), 0.5 * (h - 1));
  const double c_mm = s.model.principal_distance();
  const double along_mm = h * s.model.sensor().pixel_size;
  for (int k = 0; k < c.num_epochs; ++k) {
    double t = epochs[k].stamp + s.start_offset;
    for (size_t si = 0; si < s.strips.size(); ++si) {
      const StripSpec& st = s.strips[si];
      const Eigen::Vector2d g = (st.end - st.start).normalized();
      const double length = (st.end - st.start).norm();
      const Eigen::Vector2d mid = 0.5 * (st.start + st.end);
      const double ground = scene.AnalyticHeight(mid.x(), mid.y());
      const double z = ground + st.altitude;
      const double footprint = st.altitude * along_mm / c_mm / std::max(0.2, std::cos(st.tilt));
      const double base = std::max(0.5, (1.0 - st.overlap) * footprint);
      const int n = static_cast<int>(std::floor(length / base + 1e-9)) + 1;
      // Into a constant cross wind: the crab's sign flips with the direction.
      const Eigen::Vector2d g0 = (s.strips[0].end - s.strips[0].start).normalized();
      const double crab = g.dot(g0) >= 0.0 ? s.crab : -s.crab;
      const Eigen::Vector2d heading = Eigen::Rotation2Dd(crab) * g;
      std::uniform_real_distribution<double> u11(-1.0, 1.0);
      for (int q = 0; q < n; ++q) {
        const Eigen::Vector2d xy = st.start + (q * base) * g;
        // Within +-altitude_variation: two thirds a slow wander, one third from shot to shot.
        const double dz = s.altitude_variation > 0.0
                              ? st.altitude * s.altitude_variation *
                                    ((2.0 / 3.0) * std::sin(2.0 * M_PI * q / std::max(n, 2) + si) +
                                     (1.0 / 3.0) * u11(rng))
                              : 0.0;
        const Eigen::Vector3d planned(xy.x(), xy.y(), z + dz);
        const Eigen::Vector3d tilt_dir(std::cos(st.tilt_azimuth), std::sin(st.tilt_azimuth), 0.0);
        const Eigen::Vector3d forward =
            std::cos(st.tilt) * Eigen::Vector3d(0, 0, -1) + std::sin(st.tilt) * tilt_dir;
        const Eigen::Vector3d up_hint = st.tilt > 1e-3
                                            ? Eigen::Vector3d(tilt_dir)
                                            : Eigen::Vector3d(heading.x(), heading.y(), 0.0);
        camera::ExteriorOrientation planned_pose = LookAt(planned, planned + forward, up_hint);
        if (k == 0 && q == 0) {
          const camera::Ray ray = s.model.ImageToRay(planned_pose, centre_px);
          if (!std::isfinite(ref.grid.IntersectRay(ray.origin, ray.direction, 20000.0))) {
            throw ConfigError(
                Message(s.key, ": strips[", si,
                        "]: the camera looks away from the slope "
                        "(the central ray of the first image does not hit the ground; "
                        "check 'start', 'tilt_deg', 'tilt_azimuth_deg')"));
          }
        }
        ImageTruth im;
        im.epoch = k;
        im.stamp = t;
        t += s.image_interval;
        im.exterior = planned_pose;
        im.exterior.position +=
            Eigen::Vector3d(Gauss(&rng, s.track_sigma), Gauss(&rng, s.track_sigma),
                            Gauss(&rng, 0.5 * s.track_sigma));
        im.exterior.angles.theta += Gauss(&rng, s.attitude_sigma);
        im.exterior.angles.phi += Gauss(&rng, s.attitude_sigma);
        im.exterior.angles.kappa += Gauss(&rng, s.attitude_sigma);
        im.gnss = im.exterior.position + Eigen::Vector3d(Gauss(&rng, s.gnss_sigma.x()),
                                                         Gauss(&rng, s.gnss_sigma.x()),
                                                         Gauss(&rng, s.gnss_sigma.y()));
        ct.images.push_back(im);
      }
      // The turn to the next strip (30 s): photos on the half circle from
      // this strip's end to the next one's start, bulging ahead.
      if (s.turn_images > 0 && si + 1 < s.strips.size()) {
        const Eigen::Vector2d e = st.start + ((n - 1) * base) * g, next = s.strips[si + 1].start;
        const Eigen::Vector2d m = 0.5 * (e + next);
        const double r = 0.5 * (next - e).norm();
        const Eigen::Vector2d u =
            r > 1e-6 ? Eigen::Vector2d((e - m) / r) : Eigen::Vector2d(-g.y(), g.x());
        const double bank = CameraSpec::kTurnBankDeg * M_PI / 180.0;
        for (int q = 1; q <= s.turn_images; ++q) {
          const double a = M_PI * q / (s.turn_images + 1);
          const Eigen::Vector2d radial = std::cos(a) * u + std::sin(a) * g;
          const Eigen::Vector2d xy = m + r * radial, tangent = -std::sin(a) * u + std::cos(a) * g;
          const Eigen::Vector3d planned(xy.x(), xy.y(), z);
          const Eigen::Vector3d forward =
              std::cos(bank) * Eigen::Vector3d(0, 0, -1) -
              std::sin(bank) * Eigen::Vector3d(radial.x(), radial.y(), 0.0);
          ImageTruth im;
          im.epoch = k;
          im.stamp = t + 30.0 * q / (s.turn_images + 1);
          im.exterior =
              LookAt(planned, planned + forward, Eigen::Vector3d(tangent.x(), tangent.y(), 0.0));
          im.exterior.position +=
              Eigen::Vector3d(Gauss(&rng, s.track_sigma), Gauss(&rng, s.track_sigma),
                              Gauss(&rng, 0.5 * s.track_sigma));
          im.gnss = im.exterior.position + Eigen::Vector3d(Gauss(&rng, s.gnss_sigma.x()),
                                                           Gauss(&rng, s.gnss_sigma.x()),
                                                           Gauss(&rng, s.gnss_sigma.y()));
          ct.images.push_back(im);
        }
      }
      t += 30.0;  // turn between strips
    }
  }
}

// Exposure per image: jitter and jumps.
void ApplyImageExposures(const CameraSpec& s, std::mt19937* rng_in, CameraTruth* ct_out) {
  std::mt19937& rng = *rng_in;
  CameraTruth& ct = *ct_out;
  for (ImageTruth& im : ct.images) {
    double factor = std::exp(Gauss(&rng, s.exposure_jitter));
    for (const auto& [epoch, f] : s.exposure_jumps)
      if (im.epoch >= epoch) factor *= f;
    im.exposure = factor;
  }
}

void RequireControlInView(const CameraSpec& s, const Scene::State& ref,
                          const std::vector<TargetTruth>& targets, const CameraTruth& ct) {
  // At least one control point in view in the reference epoch (a
  // fixed_targetless camera is re-oriented on stable ground instead).
  bool control = s.kind == "fixed_targetless";
  for (const ImageTruth& im : ct.images) {
    if (im.epoch != 0 || control) continue;
    for (int p : VisiblePlates(ref, s.model, im.exterior)) {
      if (targets[p].role == io::TargetRole::kControl) control = true;
    }
  }
  if (!control) {
    throw ConfigError(
        Message(s.key, ": no control point is in view of camera '", s.name,
                "' in the reference epoch (check 'targets.list' roles/positions and the camera's "
                "pose keys)"));
  }
}

// The radio network's simulator (receivers on stable ground, transmitters
// on masts moving with the slope) and its truth.
std::shared_ptr<RadioSimulator> MakeRadioSimulator(const SurveyConfig& c, const Scene::State& ref,
                                                   const std::vector<EpochTruth>& epochs,
                                                   RadioTruth* rt_out) {
  const Eigen::Vector4d& ext = c.scene.terrain.extent;
  auto inside = [&](const Eigen::Vector2d& xy) {
    return xy.x() >= ext[0] && xy.x() <= ext[1] && xy.y() >= ext[2] && xy.y() <= ext[3];
  };
  const LandslideModel& l = c.scene.landslide;
  std::shared_ptr<RadioSimulator> radio_;
  RadioSimConfig rc = c.radio.sim;
  for (size_t j = 0; j < rc.receivers.size(); ++j) {
    const Eigen::Vector2d xy = c.radio.receiver_xy[j];
    if (!inside(xy))
      throw ConfigError(
          Message(c.path, ": radio: receivers[", j, "]: 'position' is outside site.extent"));
    if (l.Weight(xy) > 0.0) {
      throw ConfigError(Message(c.path, ": radio: receivers[", j,
                                "]: 'position' is on the moving body "
                                "(receivers stand on stable ground)"));
    }
    rc.receivers[j].position = Eigen::Vector3d(
        xy.x(), xy.y(), ref.grid.HeightAt(xy.x(), xy.y()) + c.radio.receiver_mast[j]);
  }
  for (size_t i = 0; i < rc.transmitters.size(); ++i) {
    const Eigen::Vector2d xy = c.radio.transmitter_xy[i];
    if (!inside(xy))
      throw ConfigError(
          Message(c.path, ": radio: transmitters[", i, "]: 'position' is outside site.extent"));
    const Eigen::Vector3d ground(xy.x(), xy.y(), ref.grid.HeightAt(xy.x(), xy.y()));
    const Eigen::Vector3d x0 = ground + Eigen::Vector3d(0, 0, c.radio.transmitter_mast[i]);
    const LandslideModel field = l;
    // The mast stands on the ground point and moves with it.
    rc.transmitters[i].position = [field, ground, x0](double t) -> Eigen::Vector3d {
      return x0 + field.DisplacementAt(ground, t);
    };
  }
  try {
    radio_ = std::make_shared<RadioSimulator>(rc);
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message(c.path, ": radio: ", e.what()));
  }
  RadioTruth& rt = *rt_out;
  rt.wavelength = rc.wavelength;
  rt.center_frequency = rc.center_frequency;
  for (const auto& r : rc.receivers) rt.receivers.push_back({r.id, r.position, r.xi});
  for (const auto& t : rc.transmitters) {
    RadioTransmitterTruth tt;
    tt.id = t.id;
    tt.frequency = rc.center_frequency + t.frequency_offset;
    tt.psi = t.psi;
    for (const auto& e : epochs) tt.positions.push_back(t.position(e.stamp));
    rt.transmitters.push_back(tt);
  }
  for (size_t i = 0; i < rc.transmitters.size(); ++i) {
    std::vector<int> row;
    for (size_t j = 0; j < rc.receivers.size(); ++j) {
      row.push_back(radio_->Ambiguity(static_cast<int>(i), static_cast<int>(j), c.start_time));
    }
    rt.ambiguities.push_back(row);
  }
  rt.faults = radio_->FaultDescriptions();

  return radio_;
}

}  // namespace

// ---------------------------------------------------------------------------
// SurveyGenerator
// ---------------------------------------------------------------------------

SurveyGenerator::SurveyGenerator(const SurveyConfig& config) : config_(config) {
  const SurveyConfig& c = config_;
  const Eigen::Vector4d& ext = c.scene.terrain.extent;
  const LandslideModel& l = c.scene.landslide;
  CheckSurveyPlacements(c);
  try {
    scene_ = std::make_unique<Scene>(c.scene);
  } catch (const InvalidArgument& e) {
    throw ConfigError(Message(c.path, ": ", e.what()));
  }
  const Scene& scene = *scene_;

  // ---- truth: site, epochs, landslide, obstacles, targets ----
  truth_.seed = c.seed;
  truth_.config = c.path;
  truth_.site_name = c.name;
  truth_.origin = c.origin;
  truth_.extent = ext;
  for (int k = 0; k < c.num_epochs; ++k)
    truth_.epochs.push_back({k, c.start_time + k * c.epoch_interval});
  truth_.landslide = l;
  truth_.scarp = c.scene.scarp;
  truth_.obstacles = scene.obstacles();
  std::vector<Scene::State> states;
  for (const auto& e : truth_.epochs) states.push_back(scene.AtTime(e.stamp));
  truth_.targets = scene.targets();
  {
    std::mt19937 rng = Stream(c.seed, 1);
    for (size_t i = 0; i < truth_.targets.size(); ++i) {
      TargetTruth& t = truth_.targets[i];
      t.positions.clear();
      for (const auto& st : states) t.positions.push_back(st.plates[i].centre);
      t.survey_sigma = c.survey_sigma;
      const double ex = Gauss(&rng, c.survey_sigma.x()), ey = Gauss(&rng, c.survey_sigma.x());
      const double ez = Gauss(&rng, c.survey_sigma.y());
      if (t.role != io::TargetRole::kMonitoring)
        t.surveyed = t.positions[0] + Eigen::Vector3d(ex, ey, ez);
    }
  }

  // ---- cameras: planned poses ----
  const Scene::State& ref = states[0];
  for (size_t ci = 0; ci < c.cameras.size(); ++ci) {
    const CameraSpec& s = c.cameras[ci];
    CameraTruth ct;
    ct.name = s.name;
    ct.kind = s.kind;
    ct.encoding = s.encoding;
    ct.model = s.model;
    ct.nominal = s.nominal;
    std::mt19937 rng = Stream(c.seed, 2, static_cast<unsigned>(ci));
    if (s.kind != "uav") {  // fixed, fixed_targetless
      PlanFixedCameraImages(c, ci, ref, truth_.epochs, &rng, &ct);
    } else {
      PlanUavCameraImages(c, ci, scene, ref, truth_.epochs, &rng, &ct);
    }
    ApplyImageExposures(s, &rng, &ct);
    RequireControlInView(s, ref, truth_.targets, ct);
    truth_.cameras.push_back(ct);
  }

  // ---- radio ----
  if (c.radio.enabled) radio_ = MakeRadioSimulator(c, ref, truth_.epochs, &truth_.radio);
}

Survey SurveyGenerator::Generate(const std::function<void(int, int)>& progress) const {
  const SurveyConfig& c = config_;
  Survey survey;
  survey.config = c;
  survey.truth = truth_;
  survey.radio = radio_;
  const Scene& scene = *scene_;

  std::vector<std::unique_ptr<Renderer>> renderers;
  for (const CameraSpec& s : c.cameras)
    renderers.push_back(std::make_unique<Renderer>(scene, s.model));

  int total = 0, done = 0;
  for (const auto& ct : truth_.cameras) total += static_cast<int>(ct.images.size());
  for (int k = 0; k < c.num_epochs; ++k) {
    const Scene::State state = scene.AtTime(truth_.epochs[k].stamp);
    for (size_t ci = 0; ci < c.cameras.size(); ++ci) {
      const CameraSpec& s = c.cameras[ci];
      CameraTruth& ct = survey.truth.cameras[ci];
      for (size_t ii = 0; ii < ct.images.size(); ++ii) {
        ImageTruth& im = ct.images[ii];
        if (im.epoch != k) continue;
        RenderOptions ro = c.render;
        ro.colour = s.encoding == "bgr8";
        ro.epoch_salt = k;
        const RenderResult rr = renderers[ci]->Render(state, im.exterior, ro);
        ExposureOptions eo = s.exposure;
        eo.exposure = im.exposure;
        std::mt19937 rng = Stream(c.seed, 3, static_cast<unsigned>(ci), static_cast<unsigned>(ii));
        SurveyImage out;
        out.camera = static_cast<int>(ci);
        out.image = static_cast<int>(ii);
        out.epoch = k;
        out.stamp = im.stamp;
        out.pixels = Expose(rr.radiance, eo, &rng);
        im.visible.clear();
        for (int p : VisiblePlates(state, s.model, im.exterior))
          im.visible.push_back(survey.truth.targets[p].key);
        survey.images.push_back(std::move(out));
        if (progress) progress(++done, total);
      }
    }
    // The true surface of this epoch, on the mesh vertices.
    const HeightGrid& g = state.grid;
    io::GeoRaster r(g.nx, g.ny, g.xmin - 0.5 * g.spacing, g.Y(g.ny - 1) + 0.5 * g.spacing,
                    g.spacing);
    r.AddBand("height");
    for (int row = 0; row < g.ny; ++row)
      for (int col = 0; col < g.nx; ++col)
        r.At(0, row, col) = static_cast<float>(g.Z(col, g.ny - 1 - row));
    survey.surfaces.push_back(std::move(r));
  }
  std::stable_sort(survey.images.begin(), survey.images.end(),
                   [](const SurveyImage& a, const SurveyImage& b) { return a.stamp < b.stamp; });

  // Target list as a crew would have it.
  for (const TargetTruth& t : survey.truth.targets) {
    io::TargetSpec spec;
    spec.id = t.id;
    spec.family = t.family;
    spec.size = t.size;
    spec.role = t.role;
    if (t.surveyed) spec.position = *t.surveyed;
    spec.sigma = t.survey_sigma;
    if (!t.surveyed && t.role == io::TargetRole::kMonitoring && c.monitoring_approx_sigma > 0.0) {
      std::mt19937 rng =
          Stream(c.seed, 4, static_cast<unsigned>(spec.id), spec.family == "circle" ? 1u : 0u);
      const double a = c.monitoring_approx_sigma;
      spec.position =
          t.positions[0] + Eigen::Vector3d(Gauss(&rng, a), Gauss(&rng, a), Gauss(&rng, a));
      spec.sigma = Eigen::Vector2d(a, a);
    }
    spec.normal = t.normal;
    survey.target_list.Add(spec);
  }

  if (radio_) {
    const double end = truth_.epochs.back().stamp + c.radio.tail;
    for (double t = c.start_time; t <= end + 1e-6; t += c.radio.sim.block_interval)
      survey.radio_block_starts.push_back(t);
  }
  return survey;
}

void WriteSurveyFiles(Survey* survey, const std::string& stem) {
  const size_t slash = stem.find_last_of('/');
  const std::string name = slash == std::string::npos ? stem : stem.substr(slash + 1);
  survey->truth.surfaces.clear();
  for (size_t k = 0; k < survey->surfaces.size(); ++k) {
    const std::string file = name + ".surface" + EpochSuffix(static_cast<int>(k)) + ".tif";
    io::WriteGeoTiff(stem + ".surface" + EpochSuffix(static_cast<int>(k)) + ".tif",
                     survey->surfaces[k]);
    survey->truth.surfaces.push_back({static_cast<int>(k), file});
  }
  survey->truth.Save(stem + ".truth.yaml");
  survey->target_list.Save(stem + ".targets.yaml");
  WriteSiteOverlay(survey->truth, stem + ".site.yaml");
}

std::vector<std::pair<std::string, std::string>> ColocatedPoints(const SurveyTruth& truth,
                                                                 double max_distance) {
  std::vector<std::pair<std::string, std::string>> out;
  for (const RadioTransmitterTruth& tx : truth.radio.transmitters) {
    if (tx.positions.empty()) continue;
    const TargetTruth* best = nullptr;
    double best_d = max_distance;
    for (const TargetTruth& t : truth.targets) {
      if (t.role != io::TargetRole::kMonitoring || t.positions.empty()) continue;
      const double d = (t.positions[0].head<2>() - tx.positions[0].head<2>()).norm();
      if (d <= best_d) {
        best_d = d;
        best = &t;
      }
    }
    if (best) out.emplace_back(tx.id, best->key);
  }
  return out;
}

void WriteSiteOverlay(const SurveyTruth& truth, const std::string& path) {
  std::ostringstream out;
  out << "# deformation_estimator overlay for this simulated site (written by make_survey_bag; "
         "load it with\n"
         "# replay.launch site_config:=<this file>). Radio transmitters mounted on a monitoring "
         "target's post\n"
         "# measure the same point: their ids are aliased to the target's, so the estimator fuses "
         "both\n"
         "# sources and reports when they disagree.\n";
  if (!truth.site_name.empty())
    out << "site_name: " << truth.site_name
        << "  # the site's history: ~/.ros/slope_monitor/<site_name>.db\n";
  out << std::setprecision(12) << "geodetic_origin: [" << truth.origin.x() << ", "
      << truth.origin.y() << ", " << truth.origin.z() << "]\n";
  out << "aliases: [";
  const auto pairs = ColocatedPoints(truth, 0.5);
  for (size_t k = 0; k < pairs.size(); ++k)
    out << (k ? ", " : "") << "\"" << pairs[k].first << " = " << pairs[k].second << "\"";
  out << "]\n";
  std::ofstream f(path);
  f << out.str();
  if (!f) throw IoError(Message("cannot write the site overlay '", path, "'"));
}

}  // namespace sim
}  // namespace slope_monitor
