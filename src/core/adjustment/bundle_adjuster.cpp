#include "slope_monitor/core/adjustment/bundle_adjuster.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <sstream>

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <Eigen/SVD>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/control_point_prior.h"
#include "slope_monitor/core/adjustment/cost_functions/position_prior.h"
#include "slope_monitor/core/adjustment/schur_covariance.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {

std::string PointRoleName(PointRole role) {
  switch (role) {
    case PointRole::kTie:
      return "tie";
    case PointRole::kControl:
      return "control";
    case PointRole::kMonitoring:
      return "monitoring";
    case PointRole::kCheck:
      return "check";
  }
  return "unknown";
}

int Scene::FindPoint(const std::string& id) const {
  for (size_t i = 0; i < points.size(); ++i)
    if (points[i].id == id) return static_cast<int>(i);
  return -1;
}

int Scene::FindImage(const std::string& name) const {
  for (size_t i = 0; i < images.size(); ++i)
    if (images[i].name == name) return static_cast<int>(i);
  return -1;
}

void Scene::CheckIndices() const {
  for (size_t i = 0; i < images.size(); ++i) {
    if (images[i].camera < 0 || images[i].camera >= static_cast<int>(cameras.size())) {
      throw InvalidArgument(Message("image '", images[i].name, "' refers to camera ",
                                    images[i].camera, " of ", cameras.size()));
    }
  }
  for (size_t k = 0; k < observations.size(); ++k) {
    const Observation& o = observations[k];
    if (o.image < 0 || o.image >= static_cast<int>(images.size()) || o.point < 0 ||
        o.point >= static_cast<int>(points.size())) {
      throw InvalidArgument(Message("observation ", k, " refers to image ", o.image, " / point ",
                                    o.point, " (scene has ", images.size(), " images, ",
                                    points.size(), " points)"));
    }
  }
}

void Options::Check() const {
  auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError(Message("adjustment option '", key, "' ", what));
  };
  if (loss != "none" && loss != "huber" && loss != "cauchy")
    fail("loss", "must be none|huber|cauchy, got '" + loss + "'");
  if (!(loss_scale > 0.0)) fail("loss_scale", Message("must be > 0, got ", loss_scale));
  if (!(outlier_threshold > 0.0))
    fail("outlier_threshold", Message("must be > 0, got ", outlier_threshold));
  static const std::vector<std::string> kSolvers = {"auto",         "dense_schur",
                                                    "sparse_schur", "iterative_schur",
                                                    "dense_qr",     "sparse_normal_cholesky"};
  if (std::find(kSolvers.begin(), kSolvers.end(), linear_solver) == kSolvers.end())
    fail("linear_solver", "unknown value '" + linear_solver + "'");
  if (max_iterations <= 0) fail("max_iterations", Message("must be > 0, got ", max_iterations));
  if (!(function_tolerance > 0.0)) fail("function_tolerance", "must be > 0");
  if (!(gradient_tolerance > 0.0)) fail("gradient_tolerance", "must be > 0");
  if (!(parameter_tolerance > 0.0)) fail("parameter_tolerance", "must be > 0");
  if (num_threads < 1) fail("num_threads", Message("must be >= 1, got ", num_threads));
  if (min_control_points < 0) fail("min_control_points", "must be >= 0");
  if (min_position_priors < 0) fail("min_position_priors", "must be >= 0");
  if (min_observations_per_image < 1) fail("min_observations_per_image", "must be >= 1");
  if (min_observations_with_prior < 2) fail("min_observations_with_prior", "must be >= 2");
  if (!(max_sigma0 > 0.0)) fail("max_sigma0", "must be > 0");
  if (!(min_variance_factor >= 0.0)) fail("min_variance_factor", "must be >= 0");
  if (!(max_outlier_fraction >= 0.0 && max_outlier_fraction <= 1.0))
    fail("max_outlier_fraction", "must be in [0, 1]");
}

void Config::FreeInteriorOfAll(int num_cameras, const std::vector<int>& indices) {
  for (int c = 0; c < num_cameras; ++c) free_interior[c] = indices;
}

ErrorEllipsoid ErrorEllipsoidOf(const Eigen::Matrix3d& covariance, double k) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(0.5 * (covariance + covariance.transpose()));
  ErrorEllipsoid e;
  e.semi_axes = k * eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  e.axes = eig.eigenvectors();
  return e;
}

std::string Summary::UndeterminedList() const {
  std::string list;
  const auto& u = undetermined_points;
  for (size_t i = 0; i < u.size() && i < 5; ++i) list += (i ? ", " : "") + u[i];
  if (u.size() > 5) list += ", ...";
  return list;
}

std::string Summary::BriefReport() const {
  std::ostringstream out;
  out << (usable ? "usable" : "NOT usable") << ": " << reason << "; cost " << initial_cost << " -> "
      << final_cost << " in " << iterations << " iterations, " << solve_time << " s; "
      << num_observations << " observations, " << num_outliers << " outliers, rms "
      << rms_residual_px << " px, sigma0 " << sigma0 << " (redundancy " << redundancy << ")";
  return out.str();
}

BundleAdjuster::BundleAdjuster(const Options& options, const Config& config)
    : options_(options), config_(config) {
  options_.Check();
}

namespace {

bool IsConstrainedControl(const ObjectPoint& p) {
  return p.role == PointRole::kControl && p.surveyed.has_value();
}

// Points usable in the adjustment: observed by >= 2 images, or a control point
// observed at least once.
std::vector<int> CountImagesPerPoint(const Scene& scene) {
  std::vector<std::set<int>> seen(scene.points.size());
  for (const Observation& o : scene.observations) seen[o.point].insert(o.image);
  std::vector<int> n(scene.points.size());
  for (size_t i = 0; i < n.size(); ++i) n[i] = static_cast<int>(seen[i].size());
  return n;
}

bool PointUsed(const ObjectPoint& p, int num_images, bool control_prior) {
  return num_images >= 2 || (num_images >= 1 && IsConstrainedControl(p) && control_prior);
}

// Removes from *problem the free points that FindUndeterminedPoints finds at
// the solution (with their residual blocks), marks them unused, drops their
// observations from *used_obs and names them in the Summary; the free
// parameter count shrinks by 3 each. Returns their indices.
std::vector<int> DropUndeterminedPoints(const SchurCovarianceOptions& co, const Scene& scene,
                                        std::vector<std::array<double, 3>>* point,
                                        std::vector<bool>* point_used, std::vector<int>* used_obs,
                                        ceres::Problem* problem, Summary* summary) {
  std::vector<double*> blocks;
  std::vector<int> index;
  for (size_t j = 0; j < scene.points.size(); ++j) {
    if (!(*point_used)[j] || problem->IsParameterBlockConstant((*point)[j].data())) continue;
    blocks.push_back((*point)[j].data());
    index.push_back(static_cast<int>(j));
  }
  std::vector<int> dropped;
  for (const int u : FindUndeterminedPoints(co, blocks, problem)) {
    const int j = index[u];
    dropped.push_back(j);
    problem->RemoveParameterBlock((*point)[j].data());
    (*point_used)[j] = false;
    summary->undetermined_points.push_back(scene.points[j].id);
    summary->num_parameters -= 3;
  }
  used_obs->erase(
      std::remove_if(used_obs->begin(), used_obs->end(),
                     [&](int k) { return !(*point_used)[scene.observations[k].point]; }),
      used_obs->end());
  summary->num_observations = static_cast<int>(used_obs->size());
  return dropped;
}

}  // namespace

std::string BundleAdjuster::CheckInput(const Scene& scene) const {
  scene.CheckIndices();
  if (scene.images.empty()) return "no images";
  if (scene.observations.empty()) return "no observations";
  for (size_t k = 0; k < scene.observations.size(); ++k) {
    const Observation& o = scene.observations[k];
    if (!o.pixel.allFinite() || !o.covariance.allFinite()) {
      return Message("observation ", k, " of point '", scene.points[o.point].id, "' in image '",
                     scene.images[o.image].name, "' is not finite (NaN or inf)");
    }
    Eigen::LLT<Eigen::Matrix2d> llt(o.covariance);
    if (llt.info() != Eigen::Success || o.covariance.determinant() <= 0.0) {
      return Message("observation ", k, " of point '", scene.points[o.point].id, "' in image '",
                     scene.images[o.image].name,
                     "' has a covariance that is not positive definite");
    }
  }
  for (const Camera& c : scene.cameras) {
    try {
      c.model.Check();
    } catch (const Error& e) {
      return Message("camera '", c.name, "': ", e.what());
    }
  }
  for (const auto& [cam, indices] : config_.free_interior) {
    if (cam < 0 || cam >= static_cast<int>(scene.cameras.size()))
      return Message("free_interior names camera ", cam, " of ", scene.cameras.size());
    const std::vector<int> model = camera::InteriorIndicesOf(scene.cameras[cam].model.model());
    for (int i : indices) {
      if (std::find(model.begin(), model.end(), i) == model.end())
        return Message("camera '", scene.cameras[cam].name, "': interior parameter ", i,
                       " is not part of its distortion model '",
                       camera::DistortionModelName(scene.cameras[cam].model.model()), "'");
    }
  }
  for (const Image& im : scene.images) {
    if (!im.exterior.position.allFinite() || !std::isfinite(im.exterior.angles.theta) ||
        !std::isfinite(im.exterior.angles.phi) || !std::isfinite(im.exterior.angles.kappa))
      return Message("image '", im.name, "' has a non-finite initial exterior orientation");
    if (im.position_prior &&
        (!im.position_prior->allFinite() || !im.position_prior_covariance.allFinite()))
      return Message("image '", im.name, "' has a non-finite position prior");
  }
  const std::vector<int> images_per_point = CountImagesPerPoint(scene);
  std::vector<int> obs_per_image(scene.images.size(), 0);
  for (const Observation& o : scene.observations) {
    if (PointUsed(scene.points[o.point], images_per_point[o.point], config_.use_control_priors))
      ++obs_per_image[o.image];
  }
  for (size_t i = 0; i < scene.images.size(); ++i) {
    if (obs_per_image[i] == 0)
      return Message("image '", scene.images[i].name, "' has no observations");
    const bool prior = config_.use_position_priors && scene.images[i].position_prior.has_value();
    const int min_obs =
        prior ? std::min(options_.min_observations_with_prior, options_.min_observations_per_image)
              : options_.min_observations_per_image;
    if (obs_per_image[i] < min_obs && !config_.fixed_images.count(i))
      return Message(
          "image '", scene.images[i].name, "' has only ", obs_per_image[i],
          " usable observations (",
          prior ? "min_observations_with_prior = " : "min_observations_per_image = ", min_obs, ")");
  }
  for (const ObjectPoint& p : scene.points) {
    if (!p.position.allFinite())
      return Message("point '", p.id, "' has a non-finite initial position");
    if (p.surveyed && (!p.surveyed->allFinite() || !p.surveyed_covariance.allFinite()))
      return Message("point '", p.id, "' has a non-finite survey");
  }
  if (options_.fixed_images_define_datum) {
    if (config_.fixed_images.size() >= 2) return "";
    return Message("fixed_images_define_datum needs two or more fixed images (",
                   config_.fixed_images.size(), " held)");
  }
  // Datum: control points seen (or GNSS priors), not all on one line.
  std::vector<Eigen::Vector3d> control;
  for (size_t i = 0; i < scene.points.size(); ++i) {
    if (IsConstrainedControl(scene.points[i]) && images_per_point[i] >= 1)
      control.push_back(*scene.points[i].surveyed);
  }
  int num_priors = 0;
  std::vector<Eigen::Vector3d> prior_positions;
  if (config_.use_position_priors) {
    for (const Image& im : scene.images)
      if (im.position_prior) prior_positions.push_back(*im.position_prior);
    num_priors = static_cast<int>(prior_positions.size());
  }
  auto collinear = [](const std::vector<Eigen::Vector3d>& pts) {
    if (pts.size() < 3) return true;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& p : pts) mean += p;
    mean /= static_cast<double>(pts.size());
    Eigen::MatrixXd a(pts.size(), 3);
    for (size_t i = 0; i < pts.size(); ++i) a.row(i) = (pts[i] - mean).transpose();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(a);
    const Eigen::Vector3d s = svd.singularValues();
    return !(s(0) > 0.0) || s(1) < 1e-3 * s(0);
  };
  const bool control_ok = static_cast<int>(control.size()) >= options_.min_control_points;
  const bool priors_ok = num_priors >= std::max(3, options_.min_position_priors);
  if (!control_ok && !priors_ok) {
    return Message("too few control points: ", control.size(),
                   " observed (min_control_points = ", options_.min_control_points, ") and ",
                   num_priors, " GNSS position priors (min ",
                   std::max(3, options_.min_position_priors), ")");
  }
  std::vector<Eigen::Vector3d> datum = control;
  if (priors_ok) datum.insert(datum.end(), prior_positions.begin(), prior_positions.end());
  if (collinear(datum))
    return Message("all ", datum.size(),
                   " control points / GNSS positions lie on one line: no datum");
  return "";
}

SolveReport SolveCeresProblem(const Options& options, const std::vector<double*>& point_blocks,
                              int num_cameras, ceres::Problem* problem,
                              const std::vector<double*>& last_blocks) {
  ceres::Solver::Options so;
  std::string solver = options.linear_solver;
  if (solver == "auto")
    solver = num_cameras <= options.dense_schur_max_images ? "dense_schur" : "sparse_schur";
  bool schur = true;
  if (solver == "dense_schur") {
    so.linear_solver_type = ceres::DENSE_SCHUR;
  } else if (solver == "sparse_schur") {
    so.linear_solver_type = ceres::SPARSE_SCHUR;
  } else if (solver == "iterative_schur") {
    so.linear_solver_type = ceres::ITERATIVE_SCHUR;
    so.preconditioner_type = ceres::SCHUR_JACOBI;
  } else if (solver == "dense_qr") {
    so.linear_solver_type = ceres::DENSE_QR;
    schur = false;
  } else {
    so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    schur = false;
  }
  if (schur) {
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    std::vector<double*> blocks;
    problem->GetParameterBlocks(&blocks);
    const std::set<double*> points(point_blocks.begin(), point_blocks.end());
    const std::set<double*> last(last_blocks.begin(), last_blocks.end());
    int num_in_group0 = 0;
    for (double* b : blocks) {
      const bool is_point = points.count(b) > 0;
      ordering->AddElementToGroup(b, is_point ? 0 : last.count(b) ? 2 : 1);
      if (is_point) ++num_in_group0;
    }
    if (num_in_group0 > 0 && num_in_group0 < static_cast<int>(blocks.size())) {
      so.linear_solver_ordering = ordering;
    }
  }
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  so.minimizer_progress_to_stdout = options.minimizer_progress;
  so.logging_type = options.minimizer_progress ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;

  SolveReport report;
  std::string error;
  if (!so.IsValid(&error)) {
    report.failed = true;
    report.termination = "invalid solver options: " + error;
    return report;
  }
  ceres::Solver::Summary cs;
  const auto t0 = std::chrono::steady_clock::now();
  ceres::Solve(so, problem, &cs);
  report.time = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  report.initial_cost = cs.initial_cost;
  report.final_cost = cs.final_cost;
  report.iterations = static_cast<int>(cs.iterations.size()) - 1;
  report.termination =
      ceres::TerminationTypeToString(cs.termination_type) + std::string(": ") + cs.message;
  report.converged = cs.termination_type == ceres::CONVERGENCE;
  // Out of iterations while only creeping: a block with 10^4 tie-point
  // residuals can creep with residuals in the robust loss's linear range (a
  // step-to-model ratio of 2 every step) by 1e-8..1e-5 of the cost a step,
  // never meeting the tolerances. Converged in cost when the last 10
  // successful steps together lowered it by less than 1e-4 relative.
  if (cs.termination_type == ceres::NO_CONVERGENCE && std::isfinite(cs.final_cost) &&
      cs.final_cost > 0.0) {
    std::vector<double> costs;
    for (const ceres::IterationSummary& it : cs.iterations)
      if (it.step_is_successful) costs.push_back(it.cost);
    if (costs.size() > 10 && (costs[costs.size() - 11] - costs.back()) < 1e-4 * cs.final_cost) {
      report.converged = true;
      report.termination += " (converged in cost: the last 10 steps lowered it by less than 1e-4)";
    }
  }
  report.failed = cs.termination_type == ceres::FAILURE ||
                  cs.termination_type == ceres::USER_FAILURE || !std::isfinite(cs.final_cost);
  return report;
}

namespace {

// The parameter blocks Ceres adjusts in place: each image's exterior, each
// camera's interior, each point's position (a control point held at its
// surveyed position when the priors are off), and which points take part.
struct ParameterBlocks {
  std::vector<std::array<double, camera::kNumExterior>> exterior;
  std::vector<std::array<double, camera::kNumInterior>> interior;
  std::vector<std::array<double, 3>> point;
  std::vector<bool> point_used;
};

ParameterBlocks InitialParameters(const Scene& scene, const Config& config) {
  const std::vector<int> images_per_point = CountImagesPerPoint(scene);
  ParameterBlocks b;
  auto& exterior = b.exterior;
  auto& interior = b.interior;
  auto& point = b.point;
  auto& point_used = b.point_used;
  exterior.resize(scene.images.size());
  interior.resize(scene.cameras.size());
  point.resize(scene.points.size());
  point_used.resize(scene.points.size());
  for (size_t i = 0; i < scene.images.size(); ++i) exterior[i] = scene.images[i].exterior.ToArray();
  for (size_t c = 0; c < scene.cameras.size(); ++c) interior[c] = scene.cameras[c].model.interior();
  for (size_t j = 0; j < scene.points.size(); ++j) {
    const ObjectPoint& p = scene.points[j];
    point_used[j] =
        PointUsed(p, images_per_point[j], config.use_control_priors) ||
        (IsConstrainedControl(p) && !config.use_control_priors && images_per_point[j] >= 1);
    const Eigen::Vector3d x =
        (IsConstrainedControl(p) && !config.use_control_priors) ? *p.surveyed : p.position;
    point[j] = {x.x(), x.y(), x.z()};
  }
  return b;
}

// Problem building: one collinearity residual per observation of a point in
// use (robust loss shared), control point and GNSS priors, what is held
// (fixed points and images, interior parameters not set free). Returns the
// number of prior residuals; *used_obs the observations in the problem,
// *point_blocks the points' blocks (Ceres eliminates them first).
int BuildProblem(const Scene& scene, const Config& config, ceres::LossFunction* loss,
                 ParameterBlocks* b, ceres::Problem* problem, std::vector<int>* used_obs_out,
                 std::vector<double*>* point_blocks_out) {
  auto& exterior = b->exterior;
  auto& interior = b->interior;
  auto& point = b->point;
  const auto& point_used = b->point_used;
  ceres::Problem& prob = *problem;
  std::vector<int>& used_obs = *used_obs_out;
  std::vector<double*>& point_blocks = *point_blocks_out;
  std::vector<ceres::ResidualBlockId> obs_blocks;
  for (size_t k = 0; k < scene.observations.size(); ++k) {
    const Observation& o = scene.observations[k];
    if (!point_used[o.point]) continue;
    const Image& im = scene.images[o.image];
    ceres::CostFunction* cost = new CollinearityErrorAnalytic(
        scene.cameras[im.camera].model.sensor(), o.pixel, SqrtInformation<2>(o.covariance));
    obs_blocks.push_back(prob.AddResidualBlock(cost, loss, exterior[o.image].data(),
                                               interior[im.camera].data(), point[o.point].data()));
    used_obs.push_back(static_cast<int>(k));
  }
  int num_prior_residuals = 0;
  for (size_t j = 0; j < scene.points.size(); ++j) {
    if (!point_used[j]) continue;
    point_blocks.push_back(point[j].data());
    const ObjectPoint& p = scene.points[j];
    if (IsConstrainedControl(p)) {
      if (config.use_control_priors) {
        prob.AddResidualBlock(
            ControlPointPrior::Create(*p.surveyed, SqrtInformation<3>(p.surveyed_covariance)),
            nullptr, point[j].data());
        num_prior_residuals += 3;
      } else {
        prob.SetParameterBlockConstant(point[j].data());
      }
    }
    if (config.fixed_points.count(static_cast<int>(j)))
      prob.SetParameterBlockConstant(point[j].data());
  }
  for (size_t i = 0; i < scene.images.size(); ++i) {
    const Image& im = scene.images[i];
    if (config.use_position_priors && im.position_prior) {
      prob.AddResidualBlock(
          PositionPriorError::Create(*im.position_prior,
                                     SqrtInformation<3>(im.position_prior_covariance)),
          nullptr, exterior[i].data());
      num_prior_residuals += 3;
    }
    if (config.fixed_images.count(static_cast<int>(i)))
      prob.SetParameterBlockConstant(exterior[i].data());
  }
  for (size_t c = 0; c < scene.cameras.size(); ++c) {
    if (!prob.HasParameterBlock(interior[c].data())) continue;
    auto it = config.free_interior.find(static_cast<int>(c));
    if (it == config.free_interior.end() || it->second.empty()) {
      prob.SetParameterBlockConstant(interior[c].data());
      continue;
    }
    std::vector<int> fixed;
    for (int i = 0; i < camera::kNumInterior; ++i)
      if (std::find(it->second.begin(), it->second.end(), i) == it->second.end())
        fixed.push_back(i);
    if (!fixed.empty())
      prob.SetManifold(interior[c].data(), new ceres::SubsetManifold(camera::kNumInterior, fixed));
  }
  return num_prior_residuals;
}

// What the solution's residuals say: per-image RMS, outliers (whitened
// residual over outlier_threshold), sigma0 from the inliers and the priors,
// redundancy. Returns the outliers, worst first after sorting by the caller,
// and *n_behind the observed points behind their camera.
struct WorstObservation {
  double sigmas, px;
  int observation;
};

std::vector<WorstObservation> EvaluateResiduals(const Scene& scene, const Options& options,
                                                const Config& config, const ParameterBlocks& b,
                                                const std::vector<int>& used_obs,
                                                int num_prior_residuals, int* n_behind_out,
                                                Summary* summary_out) {
  const auto& exterior = b.exterior;
  const auto& interior = b.interior;
  const auto& point = b.point;
  const auto& point_used = b.point_used;
  Summary& summary = *summary_out;
  // Residuals, outliers, sigma0.
  summary.image_rms_px.assign(scene.images.size(), 0.0);
  std::vector<int> image_n(scene.images.size(), 0);
  double sum_w2 = 0.0, sum_px2 = 0.0;
  int n_inliers = 0, n_behind = 0;
  std::vector<WorstObservation> worst;
  for (int k : used_obs) {
    const Observation& o = scene.observations[k];
    const Image& im = scene.images[o.image];
    const camera::Sensor& sensor = scene.cameras[im.camera].model.sensor();
    double xy[2];
    const bool in_front = camera::ProjectToImageMm(
        exterior[o.image].data(), interior[im.camera].data(), point[o.point].data(), xy);
    if (!in_front) ++n_behind;
    double col, row;
    camera::MmToPixel(sensor, xy[0], xy[1], &col, &row);
    const Eigen::Vector2d e(col - o.pixel.x(), row - o.pixel.y());
    const Eigen::Vector2d w = SqrtInformation<2>(o.covariance) * e;
    if (!std::isfinite(w.norm()) || w.norm() > options.outlier_threshold) {
      summary.outliers.push_back(k);
      worst.push_back({std::isfinite(w.norm()) ? w.norm() : 1e300, e.norm(), k});
      continue;
    }
    sum_w2 += w.squaredNorm();
    sum_px2 += e.squaredNorm();
    summary.image_rms_px[o.image] += e.squaredNorm();
    ++image_n[o.image];
    ++n_inliers;
  }
  for (size_t i = 0; i < scene.images.size(); ++i)
    summary.image_rms_px[i] =
        image_n[i] > 0 ? std::sqrt(summary.image_rms_px[i] / image_n[i]) : 0.0;
  // Prior residuals (not robustified).
  double sum_prior2 = 0.0;
  for (size_t j = 0; j < scene.points.size(); ++j) {
    const ObjectPoint& p = scene.points[j];
    if (point_used[j] && IsConstrainedControl(p) && config.use_control_priors) {
      const Eigen::Vector3d d =
          Eigen::Vector3d(point[j][0], point[j][1], point[j][2]) - *p.surveyed;
      sum_prior2 += (SqrtInformation<3>(p.surveyed_covariance) * d).squaredNorm();
    }
  }
  for (size_t i = 0; i < scene.images.size(); ++i) {
    const Image& im = scene.images[i];
    if (config.use_position_priors && im.position_prior) {
      const Eigen::Vector3d d =
          Eigen::Vector3d(exterior[i][0], exterior[i][1], exterior[i][2]) - *im.position_prior;
      sum_prior2 += (SqrtInformation<3>(im.position_prior_covariance) * d).squaredNorm();
    }
  }
  summary.num_outliers = static_cast<int>(summary.outliers.size());
  summary.num_residuals = 2 * n_inliers + num_prior_residuals;
  summary.redundancy = summary.num_residuals - summary.num_parameters;
  summary.rms_residual_px = n_inliers > 0 ? std::sqrt(sum_px2 / n_inliers) : 0.0;
  summary.sigma0 =
      summary.redundancy > 0 ? std::sqrt((sum_w2 + sum_prior2) / summary.redundancy) : 0.0;
  *n_behind_out = n_behind;
  return worst;
}

// The refusals after the residuals (summary->reason set): no redundancy,
// points behind a camera, too many outliers (the worst three named), sigma0
// over max_sigma0. True when the solution passes them.
bool SolutionPassesChecks(const Scene& scene, const Options& options, int n_behind,
                          std::vector<WorstObservation> worst, Summary* summary_out) {
  Summary& summary = *summary_out;
  if (summary.redundancy <= 0) {
    summary.reason = Message("no redundancy (", summary.num_residuals, " residuals for ",
                             summary.num_parameters, " unknowns)");
    return false;
  }
  if (n_behind > 0) {
    summary.reason = Message(n_behind, " observed points ended behind their camera: diverged");
    return false;
  }
  const double outlier_fraction =
      static_cast<double>(summary.num_outliers) / std::max(1, summary.num_observations);
  if (outlier_fraction > options.max_outlier_fraction) {
    std::sort(worst.begin(), worst.end(), [](const WorstObservation& a, const WorstObservation& b) {
      return a.sigmas > b.sigmas;
    });
    std::string list;
    for (size_t i = 0; i < worst.size() && i < 3; ++i) {
      const Observation& o = scene.observations[worst[i].observation];
      list += Message(i ? ", " : "", scene.points[o.point].id, " in '", scene.images[o.image].name,
                      "' ", worst[i].px, " px (", worst[i].sigmas, " sigma)");
    }
    summary.reason =
        Message("too many outliers: ", summary.num_outliers, " of ", summary.num_observations,
                " (max_outlier_fraction = ", options.max_outlier_fraction, "); worst: ", list);
    return false;
  }
  if (!(summary.sigma0 <= options.max_sigma0)) {
    summary.reason = Message("a posteriori sigma0 = ", summary.sigma0,
                             " exceeds max_sigma0 = ", options.max_sigma0,
                             " (wrong observation weights or a diverged solution)");
    return false;
  }
  return true;
}

// Covariance: the reduced camera system (schur_covariance.h), one
// factorisation for the cameras, points by back-substitution, the
// datum-free variant by adding the held control points' terms back; scaled
// by sigma0^2 (floored by min_variance_factor). False (summary->reason set)
// when it cannot be computed.
bool ComputePrecision(const Scene& scene, const Options& options, const SchurCovarianceOptions& co,
                      ParameterBlocks* b, ceres::Problem* problem, Summary* summary_out) {
  auto& exterior = b->exterior;
  auto& interior = b->interior;
  auto& point = b->point;
  const auto& point_used = b->point_used;
  ceres::Problem& prob = *problem;
  Summary& summary = *summary_out;
  // Precision.
  Precision& pr = summary.precision;
  pr.sigma0 = summary.sigma0;
  if (options.compute_covariance) {
    // Reduced camera system (schur_covariance.h): one factorisation for the
    // cameras, points by back-substitution, the datum-free variant by adding
    // the held control points' terms back.
    std::vector<double*> camera_blocks, point_blocks_free;
    std::vector<int> camera_image(scene.images.size(), -1),
        camera_interior(scene.cameras.size(), -1);
    std::vector<int> point_index(scene.points.size(), -1), held;
    for (size_t i = 0; i < scene.images.size(); ++i) {
      if (!prob.HasParameterBlock(exterior[i].data()) ||
          prob.IsParameterBlockConstant(exterior[i].data()))
        continue;
      camera_image[i] = static_cast<int>(camera_blocks.size());
      camera_blocks.push_back(exterior[i].data());
    }
    for (size_t c = 0; c < scene.cameras.size(); ++c) {
      if (!prob.HasParameterBlock(interior[c].data()) ||
          prob.IsParameterBlockConstant(interior[c].data()))
        continue;
      camera_interior[c] = static_cast<int>(camera_blocks.size());
      camera_blocks.push_back(interior[c].data());
    }
    for (size_t j = 0; j < scene.points.size(); ++j) {
      if (!point_used[j] || prob.IsParameterBlockConstant(point[j].data())) continue;
      point_index[j] = static_cast<int>(point_blocks_free.size());
      if (options.compute_datum_free_covariance && IsConstrainedControl(scene.points[j]))
        held.push_back(point_index[j]);
      point_blocks_free.push_back(point[j].data());
    }
    const auto covariance_start = std::chrono::steady_clock::now();
    const SchurCovarianceResult cov =
        ComputeSchurCovariance(co, camera_blocks, point_blocks_free, held, &prob);
    summary.covariance_time =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - covariance_start).count();
    if (!cov.ok) {
      summary.reason = "covariance could not be computed: " + cov.message;
      return false;
    }
    // With the control points held, what is left comes from the image (and
    // GNSS) weights alone, whose scale sigma0 estimates: no floor there.
    const double datum_free_scale =
        options.scale_covariance_by_sigma0 ? summary.sigma0 * summary.sigma0 : 1.0;
    const double scale =
        options.scale_covariance_by_sigma0 && !cov.relative_to_held
            ? std::max(summary.sigma0 * summary.sigma0, options.min_variance_factor)
            : datum_free_scale;
    pr.point_covariance.assign(scene.points.size(), Eigen::Matrix3d::Zero());
    pr.exterior_covariance.assign(scene.images.size(), Eigen::Matrix<double, 6, 6>::Zero());
    pr.interior_sigma.assign(scene.cameras.size(), std::array<double, camera::kNumInterior>{});
    for (size_t j = 0; j < scene.points.size(); ++j)
      if (point_index[j] >= 0)
        pr.point_covariance[j] = scale * cov.point_covariance[point_index[j]];
    for (size_t i = 0; i < scene.images.size(); ++i)
      if (camera_image[i] >= 0)
        pr.exterior_covariance[i] = scale * cov.camera_covariance[camera_image[i]];
    for (size_t k = 0; k < scene.cameras.size(); ++k) {
      if (camera_interior[k] < 0) continue;
      const Eigen::MatrixXd& c = cov.camera_covariance[camera_interior[k]];
      for (int i = 0; i < camera::kNumInterior; ++i)
        pr.interior_sigma[k][i] = std::sqrt(std::max(0.0, scale * c(i, i)));
    }
    if (!cov.point_covariance_held.empty()) {
      pr.point_covariance_datum_free.assign(scene.points.size(), Eigen::Matrix3d::Zero());
      for (size_t j = 0; j < scene.points.size(); ++j)
        if (point_index[j] >= 0)
          pr.point_covariance_datum_free[j] =
              datum_free_scale * cov.point_covariance_held[point_index[j]];
    }
    pr.valid = true;
    pr.relative_to_control = cov.relative_to_held;
    pr.message =
        options.scale_covariance_by_sigma0 ? "a posteriori (scaled by sigma0^2)" : "a priori";
    if (cov.relative_to_held)
      pr.message += Message(", relative to the control points held: ", cov.message);
  } else {
    pr.message = "not computed (compute_covariance = false)";
  }
  return true;
}

}  // namespace

Summary BundleAdjuster::Solve(Scene* scene_in) const {
  Summary summary;
  const std::string bad = CheckInput(*scene_in);
  if (!bad.empty()) {
    summary.reason = "bad input: " + bad;
    return summary;
  }
  const Scene& scene = *scene_in;
  ParameterBlocks b = InitialParameters(scene, config_);

  // One loss object shared by all image residuals; the problem must not own it.
  std::unique_ptr<ceres::LossFunction> loss_owner;
  if (options_.loss == "huber")
    loss_owner = std::make_unique<ceres::HuberLoss>(options_.loss_scale);
  if (options_.loss == "cauchy")
    loss_owner = std::make_unique<ceres::CauchyLoss>(options_.loss_scale);
  ceres::Problem::Options problem_options;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem prob(problem_options);
  std::vector<int> used_obs;
  std::vector<double*> point_blocks;
  const int num_prior_residuals =
      BuildProblem(scene, config_, loss_owner.get(), &b, &prob, &used_obs, &point_blocks);

  summary.num_observations = static_cast<int>(used_obs.size());
  // Constant blocks do not count.
  {
    std::vector<double*> blocks;
    prob.GetParameterBlocks(&blocks);
    int n = 0;
    for (double* block : blocks)
      if (!prob.IsParameterBlockConstant(block)) n += prob.ParameterBlockTangentSize(block);
    summary.num_parameters = n;
  }

  // Solver options and the solve (SolveCeresProblem).
  std::vector<double*> interior_blocks;  // after the exteriors: one array each (see there)
  for (auto& block : b.interior)
    if (prob.HasParameterBlock(block.data())) interior_blocks.push_back(block.data());
  const SolveReport report = SolveCeresProblem(
      options_, point_blocks, static_cast<int>(scene.images.size()), &prob, interior_blocks);
  summary.termination = report.termination;
  summary.initial_cost = report.initial_cost;
  summary.final_cost = report.final_cost;
  summary.iterations = report.iterations;
  summary.solve_time = report.time;
  if (report.failed) {
    summary.reason = "solver failed: " + report.termination;
    return summary;
  }
  std::vector<int> undetermined;  // points dropped after the solve (below)
  auto WriteBack = [&]() {
    for (size_t i = 0; i < scene.images.size(); ++i)
      scene_in->images[i].exterior = camera::ExteriorOrientation::FromArray(b.exterior[i].data());
    for (size_t c = 0; c < scene.cameras.size(); ++c)
      scene_in->cameras[c].model.mutable_interior() = b.interior[c];
    for (size_t j = 0; j < scene.points.size(); ++j) {
      if (!b.point_used[j]) continue;
      scene_in->points[j].position = Eigen::Vector3d(b.point[j][0], b.point[j][1], b.point[j][2]);
      scene_in->points[j].position_known = true;
    }
    for (const int j : undetermined) scene_in->points[j].position_known = false;
  };
  if (!report.converged) {
    summary.reason =
        "solver did not converge (diverging or too few iterations): " + report.termination;
    if (options_.write_back_unconverged && std::isfinite(report.final_cost)) WriteBack();
    return summary;
  }

  // Points the solution leaves undetermined (their 3x3 normal block singular,
  // schur_covariance.h): dropped with their observations and named, so that
  // one such tie point does not refuse the whole epoch's covariance.
  SchurCovarianceOptions co;
  co.num_threads = options_.num_threads;
  undetermined =
      DropUndeterminedPoints(co, scene, &b.point, &b.point_used, &used_obs, &prob, &summary);

  int n_behind = 0;
  std::vector<WorstObservation> worst = EvaluateResiduals(scene, options_, config_, b, used_obs,
                                                          num_prior_residuals, &n_behind, &summary);
  if (!SolutionPassesChecks(scene, options_, n_behind, std::move(worst), &summary)) return summary;

  // Precision.
  if (!ComputePrecision(scene, options_, co, &b, &prob, &summary)) return summary;

  WriteBack();
  summary.usable = true;
  summary.reason =
      Message("converged; sigma0 = ", summary.sigma0, ", ", summary.num_outliers, " outliers of ",
              summary.num_observations,
              summary.undetermined_points.empty()
                  ? std::string()
                  : Message("; ", summary.undetermined_points.size(),
                            " undetermined point(s) dropped (", summary.UndeterminedList(), ")"),
              summary.precision.relative_to_control
                  ? "; covariance relative to the control points (the absolute one is singular)"
                  : "");
  return summary;
}

}  // namespace adjustment
}  // namespace slope_monitor
