// Benchmark: how the bundle block scales with the number of UAV photos.
//
// Simulated blocks of 20 / 60 / 150 / 300 nadir photos (5472 x 3648 px,
// 2.4 um pixels, c 8.8 mm, 80 m above a slope rising 15 %: ~80 % forward,
// ~70 % side overlap), tie points every 6 m seen from the truth with 0.5 px
// noise, surveyed control targets (3 mm) every ~50 m on a grid, monitoring
// targets on a moving body in the middle, RTK GNSS (3 cm) on every photo,
// the interior (c, k1) differing from the nominal and self-calibrated. Two
// epochs (the body moves 0.10 m between them); per block and epoch:
//   orientation  InitializeScene (photos start at their GNSS position and the
//                flight log's IMU attitude, 0.3 deg; points intersected)
//   solve        BundleAdjuster's Ceres solve (Options defaults)
//   covariance   the reduced-camera-system covariance incl. the datum-free one
// then the monitoring displacement RMS vs the truth [m], the photos kept,
// and the process's peak memory (getrusage ru_maxrss, cumulative).
//
//   bench_uav_block_scaling [--solver auto|dense_schur|sparse_schur|iterative_schur]
//       [--threads N] [--start imu|plan|resect] [--real-flight] [--4000x3000] [sizes...]
//   (default: auto, the hardware threads, imu, grid flight, 5472 x 3648; 20 60 150 300)
// --start plan: photos start at the flight plan's attitude (0, 0, strip
//   heading: no crab, no roll); resect: no attitude, InitializeScene orients
//   the photos from their GNSS centre and the control points seen, then the
//   tie points (incremental orientation).
// --real-flight: strips flown both ways with a crab of 8..20 deg (its sign
//   flipping with the direction), the altitude wandering within +-15 %, and
//   three banked photos in every turn between strips.
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <random>
#include <string>
#include <vector>

#include "slope_monitor/core/adjustment/bundle_adjuster.h"
#include "slope_monitor/core/adjustment/initialization.h"
#include "slope_monitor/core/sim/survey.h"

namespace {

using namespace slope_monitor;
using namespace slope_monitor::adjustment;

constexpr double kFly = 80.0;             // [m] above the datum
constexpr double kForward = 16.0;         // [m] between shots
constexpr double kSide = 36.0;            // [m] between strips
constexpr double kTieSpacing = 6.0;       // [m]
constexpr double kControlSpacing = 50.0;  // [m]
constexpr double kPixelSigma = 0.5;       // [px]
constexpr double kMotion = 0.10;          // [m] body displacement per epoch

double Ground(double x, double y) {
  return 0.15 * y + 1.5 * std::sin(0.05 * x) * std::cos(0.04 * y);
}

// How the bench runs (command line).
struct Setup {
  std::string solver = "auto";  // Options::linear_solver
  int threads = 0;              // 0: the hardware threads
  std::string start =
      "imu";  // imu | plan (attitude 0, 0, strip heading) | resect (InitializeScene orients)
  bool real_flight = false;   // crab, altitude, turns (see MakeBlock)
  bool small_sensor = false;  // 4000 x 3000 px (3.3 um) instead of 5472 x 3648 (2.4 um)
};
Setup g_setup;

struct Block {
  Scene scene;
  std::vector<Eigen::Vector3d> truth;  // per point, this epoch
};

// Strips x shots (+ 3 turn photos between strips in a real flight) close to
// n photos (strips ~ sqrt(n / 2)).
void Layout(int n, int* strips, int* shots) {
  *strips = std::max(2, static_cast<int>(std::lround(std::sqrt(n / 2.0))));
  const int turns = g_setup.real_flight ? 3 * (*strips - 1) : 0;
  *shots = (n - turns + *strips - 1) / *strips;
}

Block MakeBlock(int n, int epoch) {
  int strips, shots;
  Layout(n, &strips, &shots);
  const double length = kForward * (shots - 1), width = kSide * (strips - 1);
  std::mt19937 rng(1000 * n + epoch), survey_rng(7), tie_rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  Block b;
  std::array<double, camera::kNumInterior> nominal{}, truth_in{};
  nominal[camera::kC] = 8.8;
  truth_in = nominal;
  truth_in[camera::kC] = 8.83;
  truth_in[camera::kK1] = -1.5e-4;
  const camera::Sensor sensor = g_setup.small_sensor ? camera::Sensor{4000, 3000, 0.0033}
                                                     : camera::Sensor{5472, 3648, 0.0024};
  const camera::CameraModel truth_model(sensor, camera::DistortionModel::kRadial, truth_in);
  b.scene.cameras.push_back(
      {"uav", camera::CameraModel(sensor, camera::DistortionModel::kRadial, nominal)});

  const Eigen::Vector2d centre(0.5 * length, 0.5 * width);
  auto add_point = [&](const std::string& id, PointRole role, double x, double y, double h) {
    ObjectPoint p;
    p.id = id;
    p.role = role;
    p.position_known = false;
    Eigen::Vector3d t(x, y, Ground(x, y) + h);
    if (role == PointRole::kControl) {
      p.surveyed = t + 0.003 * Eigen::Vector3d(n01(survey_rng), n01(survey_rng), n01(survey_rng));
      p.surveyed_covariance = Eigen::Matrix3d::Identity() * 0.003 * 0.003;
    }
    if (role == PointRole::kMonitoring)
      t += epoch * kMotion * Eigen::Vector3d(0.1, -0.9, -0.42).normalized();
    b.scene.points.push_back(p);
    b.truth.push_back(t);
  };
  int id = 0;
  for (double x = -20.0; x <= length + 20.0; x += kControlSpacing)
    for (double y = -20.0; y <= width + 20.0; y += kControlSpacing) {
      // The body (middle third) carries no control.
      if (std::abs(x - centre.x()) < length / 6 + 10 && std::abs(y - centre.y()) < width / 6 + 10)
        continue;
      add_point("tag36h11/" + std::to_string(id++), PointRole::kControl, x, y, 0.5);
    }
  for (int i = 0; i < 20; ++i) {
    const double a = 2 * M_PI * i / 20.0, r = 6.0 + 2.0 * (i % 5);
    add_point("circle/" + std::to_string(100 + i), PointRole::kMonitoring,
              centre.x() + r * std::cos(a), centre.y() + r * std::sin(a), 0.5);
  }
  std::uniform_real_distribution<double> jitter(-0.4 * kTieSpacing, 0.4 * kTieSpacing);
  int tie = 0;
  for (double x = -70.0; x <= length + 70.0; x += kTieSpacing)
    for (double y = -30.0; y <= width + 30.0; y += kTieSpacing)
      add_point("tie/" + std::to_string(tie++), PointRole::kTie, x + jitter(tie_rng),
                y + jitter(tie_rng), 0.0);

  // The flight: poses (truth) and what the flight log says (start).
  std::vector<camera::ExteriorOrientation> poses, logged;
  std::vector<Eigen::Vector3d> gnss;
  std::uniform_real_distribution<double> u11(-1.0, 1.0);
  const double deg = M_PI / 180.0, z_fly = Ground(centre.x(), centre.y()) + kFly;
  auto shoot = [&](const Eigen::Vector3d& position, double heading, double roll) {
    camera::ExteriorOrientation pose;
    pose.position = position;
    const double a = 1.0 * deg;
    pose.angles = {a * n01(rng) + roll, a * n01(rng), heading + a * n01(rng)};
    // The flight log's IMU attitude (0.3 deg noise) or the plan's (no crab, no roll).
    camera::ExteriorOrientation log = pose;
    const double imu = 0.3 * deg;
    log.angles = {pose.angles.theta + imu * n01(rng), pose.angles.phi + imu * n01(rng),
                  pose.angles.kappa + imu * n01(rng)};
    poses.push_back(pose);
    logged.push_back(log);
    gnss.push_back(pose.position +
                   Eigen::Vector3d(0.03 * n01(rng), 0.03 * n01(rng), 0.03 * n01(rng)));
  };
  std::vector<double> plan_heading;
  for (int s = 0; s < strips && static_cast<int>(poses.size()) < n; ++s) {
    const bool back = s % 2 == 1;  // strips flown both ways
    const double heading = back ? M_PI : 0.0;
    // Wind across the strips: a crab of up to 20 deg, its sign flips with the direction.
    const double crab =
        g_setup.real_flight ? (back ? -1.0 : 1.0) * (14.0 + 6.0 * u11(rng)) * deg : 0.0;
    for (int q = 0; q < shots && static_cast<int>(poses.size()) < n; ++q) {
      const int k = back ? shots - 1 - q : q;
      const double x = kForward * k, y = kSide * s;
      // Altitude: the barometer/terrain follow wanders within +-15 %.
      const double dz = g_setup.real_flight
                            ? kFly * (0.10 * std::sin(2.0 * M_PI * x / 180.0 + s) + 0.05 * u11(rng))
                            : 0.0;
      shoot(Eigen::Vector3d(x + 0.5 * n01(rng), y + 0.5 * n01(rng), z_fly + dz), heading + crab,
            0.0);
      plan_heading.push_back(heading);
    }
    // The turn to the next strip: three photos on a half circle beyond the
    // strip's end, banked 12 deg, heading turning through 90 deg.
    if (g_setup.real_flight && s + 1 < strips) {
      const double end_x = back ? -0.5 * kForward : kForward * (shots - 0.5);
      for (int t = 1; t <= 3 && static_cast<int>(poses.size()) < n; ++t) {
        const double a = M_PI * t / 4.0;  // 45, 90, 135 deg around the turn
        const double r = 0.5 * kSide, sx = back ? -1.0 : 1.0;
        shoot(Eigen::Vector3d(end_x + sx * r * std::sin(a), kSide * s + r * (1.0 - std::cos(a)),
                              z_fly),
              heading + sx * a, sx * 12.0 * deg);
        plan_heading.push_back(heading + sx * a);
      }
    }
  }
  for (size_t f = 0; f < poses.size(); ++f) {
    const camera::ExteriorOrientation& pose = poses[f];
    Image im;
    im.name = "uav@" + std::to_string(b.scene.images.size());
    im.camera = 0;
    im.exterior.position = gnss[f];
    im.exterior.angles = logged[f].angles;
    if (g_setup.start == "plan") im.exterior.angles = {0.0, 0.0, plan_heading[f]};
    im.exterior_known = g_setup.start != "resect";
    im.position_prior = gnss[f];
    im.position_prior_covariance = Eigen::Matrix3d::Identity() * 0.03 * 0.03;
    const int i = static_cast<int>(b.scene.images.size());
    b.scene.images.push_back(im);
    for (size_t j = 0; j < b.truth.size(); ++j) {
      Eigen::Vector2d px;
      if (!sim::ImagedAt(truth_model, pose, b.truth[j], 20.0, &px)) continue;
      Observation o;
      o.image = i;
      o.point = static_cast<int>(j);
      o.pixel = px + kPixelSigma * Eigen::Vector2d(n01(rng), n01(rng));
      o.covariance = Eigen::Matrix2d::Identity() * kPixelSigma * kPixelSigma;
      b.scene.observations.push_back(o);
    }
  }
  return b;
}

double Seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Process CPU time [s] (all threads): the work, whatever else the machine runs.
double CpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return t.tv_sec + 1e-9 * t.tv_nsec;
}

double PeakMemoryMb() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0;
}

struct EpochResult {
  bool ok = false;
  std::string reason;
  double orientation = 0.0, solve = 0.0, covariance = 0.0, cpu = 0.0;
  int iterations = 0, undetermined = 0, photos_in = 0, photos_kept = 0, points = 0,
      observations = 0;
  Scene scene;
};

EpochResult RunEpoch(int n, int epoch) {
  EpochResult r;
  Block b = MakeBlock(n, epoch);
  r.photos_in = static_cast<int>(b.scene.images.size());
  r.observations = static_cast<int>(b.scene.observations.size());
  auto t0 = std::chrono::steady_clock::now();
  const std::string init = InitializeScene(&b.scene);
  if (!init.empty())
    std::fprintf(stderr, "n=%d epoch %d: InitializeScene: %s\n", n, epoch, init.c_str());
  PruneReport pruned;
  Scene scene = PruneScene(b.scene, Options().min_observations_per_image, &pruned);
  r.orientation = Seconds(t0);
  r.photos_kept = static_cast<int>(scene.images.size());
  r.points = static_cast<int>(scene.points.size());
  Options options;
  options.compute_datum_free_covariance = true;
  options.linear_solver = g_setup.solver;
  options.num_threads = g_setup.threads > 0 ? g_setup.threads : Options::HardwareThreads();
  Config config;
  config.FreeInteriorOfAll(1, {camera::kC, camera::kK1});
  const double cpu0 = CpuSeconds();
  const Summary s = BundleAdjuster(options, config).Solve(&scene);
  r.cpu = CpuSeconds() - cpu0;
  r.solve = s.solve_time;
  r.covariance = s.covariance_time;
  r.iterations = s.iterations;
  r.ok = s.usable;
  r.reason = s.usable ? s.termination : s.reason;
  r.undetermined = static_cast<int>(s.undetermined_points.size());
  if (std::getenv("SM_BENCH_DIAG")) {
    std::fprintf(stderr, "n=%d epoch %d: %s\n", n, epoch, s.BriefReport().c_str());
    for (const std::string& id : s.undetermined_points) {
      const int j = scene.FindPoint(id), t = b.scene.FindPoint(id);
      std::fprintf(stderr, "  %s truth (%.2f %.2f %.2f) start (%.2f %.2f %.2f):", id.c_str(),
                   b.truth[t].x(), b.truth[t].y(), b.truth[t].z(), scene.points[j].position.x(),
                   scene.points[j].position.y(), scene.points[j].position.z());
      for (const Observation& o : scene.observations)
        if (o.point == j)
          std::fprintf(stderr, " [%s (%.1f %.1f) px (%.1f %.1f)]",
                       scene.images[o.image].name.c_str(),
                       scene.images[o.image].exterior.position.x(),
                       scene.images[o.image].exterior.position.y(), o.pixel.x(), o.pixel.y());
      std::fprintf(stderr, "\n");
    }
  }
  r.scene = scene;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<int> sizes;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", arg.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--solver") {
      g_setup.solver = value();
    } else if (arg == "--threads") {
      g_setup.threads = std::atoi(value().c_str());
    } else if (arg == "--start") {
      g_setup.start = value();
      if (g_setup.start != "imu" && g_setup.start != "plan" && g_setup.start != "resect") {
        std::fprintf(stderr, "--start: imu | plan | resect, got '%s'\n", g_setup.start.c_str());
        return 2;
      }
    } else if (arg == "--real-flight") {
      g_setup.real_flight = true;
    } else if (arg == "--4000x3000") {
      g_setup.small_sensor = true;
    } else if (std::atoi(arg.c_str()) > 0) {
      sizes.push_back(std::atoi(arg.c_str()));
    } else {
      std::fprintf(stderr,
                   "unknown argument '%s' (see the header of bench/uav_block_scaling.cpp)\n",
                   arg.c_str());
      return 2;
    }
  }
  if (sizes.empty()) sizes = {20, 60, 150, 300};
  std::printf("# solver %s, threads %s, start %s, flight %s, %s photos\n", g_setup.solver.c_str(),
              g_setup.threads > 0 ? std::to_string(g_setup.threads).c_str() : "hardware",
              g_setup.start.c_str(), g_setup.real_flight ? "real (crab, altitude, turns)" : "grid",
              g_setup.small_sensor ? "4000x3000" : "5472x3648");
  std::printf(
      "| photos | kept | points | observations | orientation [s] | solve [s] | iterations | "
      "covariance [s] | solve+covariance CPU [s] | undetermined | peak memory [MB] | "
      "displacement RMS [m] |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const int n : sizes) {
    EpochResult e[2] = {RunEpoch(n, 0), RunEpoch(n, 1)};
    if (!e[0].ok || !e[1].ok) {
      std::printf("| %d | not usable: %s / %s |\n", n, e[0].reason.c_str(), e[1].reason.c_str());
      std::fflush(stdout);
      continue;
    }
    // Displacement of every monitoring point solved in both epochs vs the truth.
    const Block truth0 = MakeBlock(n, 0), truth1 = MakeBlock(n, 1);
    double sum2 = 0.0;
    int count = 0;
    for (size_t j = 0; j < truth0.scene.points.size(); ++j) {
      if (truth0.scene.points[j].role != PointRole::kMonitoring) continue;
      const int a = e[0].scene.FindPoint(truth0.scene.points[j].id),
                b = e[1].scene.FindPoint(truth0.scene.points[j].id);
      if (a < 0 || b < 0) continue;
      const Eigen::Vector3d measured =
          e[1].scene.points[b].position - e[0].scene.points[a].position;
      sum2 += (measured - (truth1.truth[j] - truth0.truth[j])).squaredNorm();
      ++count;
    }
    const double rms = count ? std::sqrt(sum2 / count) : NAN;
    std::printf(
        "| %d | %d+%d | %d | %d | %.2f | %.2f | %d+%d | %.2f | %.2f | %d+%d | %.0f | %.4f (%d "
        "points) "
        "|\n",
        n, e[0].photos_kept, e[1].photos_kept, e[0].points, e[0].observations,
        e[0].orientation + e[1].orientation, e[0].solve + e[1].solve, e[0].iterations,
        e[1].iterations, e[0].covariance + e[1].covariance, e[0].cpu + e[1].cpu, e[0].undetermined,
        e[1].undetermined, PeakMemoryMb(), rms, count);
    std::fflush(stdout);
  }
  return 0;
}
