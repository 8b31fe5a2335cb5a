#include "slope_monitor/core/adjustment/resect_camera.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <sstream>

#include <ceres/ceres.h>
#include <Eigen/SVD>

#include "slope_monitor/core/adjustment/cost_functions/collinearity_error.h"
#include "slope_monitor/core/adjustment/cost_functions/control_point_prior.h"
#include "slope_monitor/core/adjustment/cost_functions/position_prior.h"
#include "slope_monitor/core/adjustment/small_problem.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/geometry/resection.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr const char* kExteriorNames[6] = {"X0", "Y0", "Z0", "theta", "phi", "kappa"};

int InteriorIndexOf(const std::string& name) {
  const auto& names = camera::InteriorNames();
  for (int i = 0; i < camera::kNumInterior; ++i)
    if (name == names[i]) return i;
  std::string all;
  for (const char* n : names) all += std::string(all.empty() ? "" : ",") + n;
  throw InvalidArgument(Message("resect_camera: free parameter '", name, "' is not one of ", all));
}

// The smallest distortion model that has every freed term.
camera::DistortionModel ModelFor(camera::DistortionModel nominal, const std::vector<int>& free) {
  int need = 0;  // 0 none, 1 radial, 2 brown, 3 brown_affinity
  for (int i : free) {
    if (i == camera::kK1 || i == camera::kK2 || i == camera::kK3) need = std::max(need, 1);
    if (i == camera::kP1 || i == camera::kP2) need = std::max(need, 2);
    if (i == camera::kB1 || i == camera::kB2) need = 3;
  }
  const camera::DistortionModel models[4] = {
      camera::DistortionModel::kNone, camera::DistortionModel::kRadial,
      camera::DistortionModel::kBrown, camera::DistortionModel::kBrownAffinity};
  int have = 0;
  for (int k = 0; k < 4; ++k)
    if (models[k] == nominal) have = k;
  return models[std::max(need, have)];
}

// Start without a position: three-point resection, the other points choosing.
bool StartFromResection(const camera::CameraModel& model,
                        const std::vector<Eigen::Vector2d>& pixels,
                        const std::vector<Eigen::Vector3d>& xyz, const ResectCameraOptions& o,
                        camera::ExteriorOrientation* start, std::string* how) {
  geometry::ResectionOptions ro;
  const double diagonal = std::hypot(model.sensor().width, model.sensor().height);
  ro.inlier_threshold_px = o.start_inlier_fraction * diagonal;
  ro.pixel_sigma = o.pixel_sigma;
  const geometry::ResectionResult r = geometry::Resect(model, pixels, xyz, ro);
  *how = Message("three-point resection: ", r.message);
  if (!r.success) return false;
  *start = r.exterior;
  return true;
}

// Start with a known position: the attitude from the directions.
camera::ExteriorOrientation StartFromPosition(const camera::CameraModel& model,
                                              const std::vector<Eigen::Vector2d>& pixels,
                                              const std::vector<Eigen::Vector3d>& xyz,
                                              const Eigen::Vector3d& x0) {
  std::vector<Eigen::Vector3d> d, b;
  for (size_t i = 0; i < xyz.size(); ++i) {
    d.push_back((xyz[i] - x0).normalized());
    b.push_back(geometry::BearingOfPixel(model, pixels[i]));
  }
  camera::ExteriorOrientation e;
  e.position = x0;
  e.angles = camera::AnglesFromRotation(RotationFromDirections(d, b));
  return e;
}

// Baarda's standardized residuals of the observation rows [0, rows) of the
// whitened Jacobian: q_vv = 1 - h_ii with H the projector onto J's range.
Eigen::VectorXd Standardized(const Eigen::MatrixXd& j, const Eigen::VectorXd& whitened, int rows,
                             int* rank) {
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(j, Eigen::ComputeThinU);
  const Eigen::VectorXd& s = svd.singularValues();
  const double tol = s.size() ? s(0) * 1e-10 : 0.0;
  *rank = 0;
  for (int k = 0; k < s.size(); ++k)
    if (s(k) > tol) ++*rank;
  const Eigen::MatrixXd u = svd.matrixU().leftCols(*rank);
  Eigen::VectorXd w(rows);
  for (int i = 0; i < rows; ++i) {
    const double qvv = 1.0 - u.row(i).squaredNorm();
    w(i) = qvv > 1e-9 ? whitened(i) / std::sqrt(qvv) : 0.0;
  }
  return w;
}

}  // namespace

void ResectCameraOptions::Check() const {
  for (const auto& n : free_interior) InteriorIndexOf(n);
  if (!(pixel_sigma > 0.0))
    throw InvalidArgument(Message("resect_camera: pixel_sigma must be > 0, got ", pixel_sigma));
  if (!(point_sigma >= 0.0))
    throw InvalidArgument(Message("resect_camera: point_sigma must be >= 0, got ", point_sigma));
  if (!(position_sigma >= 0.0))
    throw InvalidArgument(
        Message("resect_camera: position_sigma must be >= 0, got ", position_sigma));
  if (has_position && !position.allFinite())
    throw InvalidArgument("resect_camera: position is not finite");
  if (!(snooping_critical > 0.0))
    throw InvalidArgument(
        Message("resect_camera: snooping_critical must be > 0, got ", snooping_critical));
  if (!(correlation_warning > 0.0 && correlation_warning <= 1.0))
    throw InvalidArgument(
        Message("resect_camera: correlation_warning must be in (0, 1], got ", correlation_warning));
  if (!(start_inlier_fraction > 0.0))
    throw InvalidArgument(
        Message("resect_camera: start_inlier_fraction must be > 0, got ", start_inlier_fraction));
}

Eigen::Matrix3d RotationFromDirections(const std::vector<Eigen::Vector3d>& site_directions,
                                       const std::vector<Eigen::Vector3d>& bearings) {
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < site_directions.size(); ++i)
    h += bearings[i] * site_directions[i].transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d fix = Eigen::Matrix3d::Identity();
  fix(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * fix * svd.matrixV().transpose();
}

namespace {

// Residuals, RMS and standardized residuals (data snooping) of the
// adjusted resection.
void ResectionResiduals(ceres::Problem* problem_in,
                        const std::vector<ceres::ResidualBlockId>& blocks,
                        const std::vector<io::PickedPoint>& points,
                        const std::vector<Eigen::Vector2d>& pixels,
                        const std::vector<Eigen::Vector3d>& pts,
                        const camera::ExteriorOrientation& local,
                        const ResectCameraOptions& options, ResectCameraSummary* out_in) {
  ceres::Problem& problem = *problem_in;
  ResectCameraSummary& out = *out_in;
  const size_t n = points.size();
  // Residuals, RMS, standardized residuals.
  ceres::Problem::EvaluateOptions eo;
  eo.residual_blocks = blocks;
  std::vector<double> res;
  ceres::CRSMatrix crs;
  problem.Evaluate(eo, nullptr, &res, nullptr, &crs);
  Eigen::MatrixXd j = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r)
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) j(r, crs.cols[k]) = crs.values[k];
  const Eigen::VectorXd whitened = Eigen::Map<Eigen::VectorXd>(res.data(), res.size());
  int rank = 0;
  const Eigen::VectorXd w = Standardized(j, whitened, static_cast<int>(2 * n), &rank);
  out.redundancy = crs.num_rows - rank;
  out.sigma0 = out.redundancy > 0 ? std::sqrt(whitened.squaredNorm() / out.redundancy) : 0.0;
  double sum = 0.0;
  for (size_t i = 0; i < n; ++i) {
    ResectedPoint rp;
    rp.id = points[i].id;
    rp.observed = pixels[i];
    Eigen::Vector2d px;
    out.model.Project(local, pts[i], &px);
    rp.residual = px - pixels[i];
    sum += rp.residual.squaredNorm();
    rp.w = std::max(std::abs(w(2 * i)), std::abs(w(2 * i + 1)));
    rp.snooping_failed = out.redundancy > 0 && rp.w > options.snooping_critical;
    out.num_snooping_failed += rp.snooping_failed;
    out.points.push_back(rp);
  }
  out.rms_px = std::sqrt(sum / n);
}

// The a-priori covariance of the free parameters (exterior, and the free
// interior ones), each parameter with its value and sigma, their
// correlations and the ones above correlation_warning.
void ResectionCovariance(ceres::Problem* problem_in, const std::vector<int>& free,
                         bool position_held, const Eigen::Vector3d& centroid,
                         const ResectCameraOptions& options,
                         std::array<double, camera::kNumExterior>* e_in,
                         std::array<double, camera::kNumInterior>* in_in,
                         ResectCameraSummary* out_in) {
  ceres::Problem& problem = *problem_in;
  std::array<double, camera::kNumExterior>& e = *e_in;
  std::array<double, camera::kNumInterior>& in = *in_in;
  ResectCameraSummary& out = *out_in;
  // Covariance of the free parameters (a priori).
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance cov(co);
  std::vector<std::pair<const double*, const double*>> pairs = {{e.data(), e.data()}};
  if (!free.empty()) {
    pairs.push_back({e.data(), in.data()});
    pairs.push_back({in.data(), in.data()});
  }
  Eigen::MatrixXd full = Eigen::MatrixXd::Zero(16, 16);
  if (cov.Compute(pairs, &problem)) {
    Eigen::Matrix<double, 6, 6, Eigen::RowMajor> ee;
    cov.GetCovarianceBlock(e.data(), e.data(), ee.data());
    full.topLeftCorner<6, 6>() = ee;
    if (!free.empty()) {
      Eigen::Matrix<double, 6, 10, Eigen::RowMajor> ei;
      Eigen::Matrix<double, 10, 10, Eigen::RowMajor> ii;
      cov.GetCovarianceBlock(e.data(), in.data(), ei.data());
      cov.GetCovarianceBlock(in.data(), in.data(), ii.data());
      full.block<6, 10>(0, 6) = ei;
      full.block<10, 6>(6, 0) = ei.transpose();
      full.block<10, 10>(6, 6) = ii;
    }
  } else {
    out.message =
        "covariance not computable (rank-deficient: too many free parameters for these points)";
  }
  out.exterior_covariance = full.topLeftCorner<6, 6>();
  std::vector<int> index;  // into `full`
  for (int k = position_held ? 3 : 0; k < 6; ++k) index.push_back(k);
  for (int k : free) index.push_back(6 + k);
  const auto& inames = camera::InteriorNames();
  for (int k : index) {
    EstimatedParameter p;
    p.name = k < 6 ? kExteriorNames[k] : inames[k - 6];
    p.value = k < 6 ? e[k] + (k < 3 ? centroid(k) : 0.0) : in[k - 6];
    p.sigma = std::sqrt(std::max(0.0, full(k, k)));
    out.parameters.push_back(p);
  }
  const int m = static_cast<int>(index.size());
  out.correlation = Eigen::MatrixXd::Identity(m, m);
  for (int a = 0; a < m; ++a) {
    for (int b = a + 1; b < m; ++b) {
      const double d = std::sqrt(full(index[a], index[a]) * full(index[b], index[b]));
      const double rho = d > 0.0 ? full(index[a], index[b]) / d : 0.0;
      out.correlation(a, b) = out.correlation(b, a) = rho;
      if (std::abs(rho) > options.correlation_warning) {
        std::ostringstream s;
        s << out.parameters[a].name << "-" << out.parameters[b].name << " " << std::fixed
          << std::setprecision(3) << rho;
        out.correlation_warnings.push_back(s.str());
      }
    }
  }
}

}  // namespace

ResectCameraSummary ResectCamera(const std::vector<io::PickedPoint>& points,
                                 const camera::CameraModel& nominal,
                                 const ResectCameraOptions& options) {
  options.Check();
  nominal.Check();
  const size_t n = points.size();
  if (n < 4) {
    throw InvalidArgument(
        Message("resect_camera: ", n, " points; need at least 4 (three to solve, one to choose)"));
  }
  ResectCameraSummary out;
  // Shift to the centroid for numerical safety.
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (const auto& p : points) centroid += p.xyz / static_cast<double>(n);
  std::vector<Eigen::Vector3d> xyz(n);
  std::vector<Eigen::Vector2d> pixels(n);
  for (size_t i = 0; i < n; ++i) {
    xyz[i] = points[i].xyz - centroid;
    pixels[i] = points[i].pixel;
  }
  std::vector<int> free;
  for (const auto& name : options.free_interior) free.push_back(InteriorIndexOf(name));
  std::sort(free.begin(), free.end());
  free.erase(std::unique(free.begin(), free.end()), free.end());
  camera::CameraModel model(nominal.sensor(), ModelFor(nominal.model(), free), nominal.interior());

  camera::ExteriorOrientation start;
  if (options.has_position) {
    start = StartFromPosition(model, pixels, xyz, options.position - centroid);
    out.start = "attitude from the known position (directions to the points)";
  } else if (!StartFromResection(model, pixels, xyz, options, &start, &out.start)) {
    out.message = Message("no start: ", out.start);
    return out;
  }

  std::array<double, camera::kNumExterior> e = start.ToArray();
  std::array<double, camera::kNumInterior> in = model.interior();
  std::vector<Eigen::Vector3d> pts = xyz;
  ceres::Problem problem;
  std::vector<ceres::ResidualBlockId> blocks;
  const Eigen::Matrix2d sqrt_px = Eigen::Matrix2d::Identity() / options.pixel_sigma;
  for (size_t i = 0; i < n; ++i) {
    blocks.push_back(
        problem.AddResidualBlock(CollinearityError::Create(model.sensor(), pixels[i], sqrt_px),
                                 nullptr, e.data(), in.data(), pts[i].data()));
  }
  for (size_t i = 0; i < n; ++i) {
    if (options.point_sigma > 0.0) {
      blocks.push_back(problem.AddResidualBlock(
          ControlPointPrior::Create(xyz[i], Eigen::Matrix3d::Identity() / options.point_sigma),
          nullptr, pts[i].data()));
    } else {
      problem.SetParameterBlockConstant(pts[i].data());
    }
  }
  const bool position_held = options.has_position && options.position_sigma == 0.0;
  if (position_held) {
    problem.SetManifold(e.data(), new ceres::SubsetManifold(camera::kNumExterior, {0, 1, 2}));
  } else if (options.has_position) {
    blocks.push_back(problem.AddResidualBlock(
        PositionPriorError::Create(options.position - centroid,
                                   Eigen::Matrix3d::Identity() / options.position_sigma),
        nullptr, e.data()));
  }
  std::vector<int> held;
  for (int k = 0; k < camera::kNumInterior; ++k)
    if (!std::binary_search(free.begin(), free.end(), k)) held.push_back(k);
  if (free.empty()) {
    problem.SetParameterBlockConstant(in.data());
  } else {
    problem.SetManifold(in.data(), new ceres::SubsetManifold(camera::kNumInterior, held));
  }
  const ceres::Solver::Summary ss = SolveSmallProblem(&problem, 200, 1e-12);
  if (!ss.IsSolutionUsable()) {
    out.message = Message("adjustment failed: ", ss.message);
    return out;
  }
  camera::ExteriorOrientation local = camera::ExteriorOrientation::FromArray(e.data());
  out.model = camera::CameraModel(model.sensor(), model.model(), in);
  std::vector<std::string> behind;
  for (size_t i = 0; i < n; ++i) {
    if (camera::PointInCamera(e.data(), pts[i].data())(2) >= 0.0) behind.push_back(points[i].id);
  }
  if (!behind.empty()) {
    std::string ids;
    for (const auto& b : behind) ids += (ids.empty() ? "" : ", ") + b;
    throw InvalidArgument(Message("resect_camera: ", behind.size(),
                                  " point(s) behind the camera: ", ids,
                                  " (check their coordinates, pixels and the camera position)"));
  }
  out.exterior = local;
  out.exterior.position += centroid;

  ResectionResiduals(&problem, blocks, points, pixels, pts, local, options, &out);
  ResectionCovariance(&problem, free, position_held, centroid, options, &e, &in, &out);
  out.success = true;
  if (out.message.empty())
    out.message = Message(n, " points, rms ", out.rms_px, " px, redundancy ", out.redundancy);
  return out;
}

}  // namespace adjustment
}  // namespace slope_monitor
