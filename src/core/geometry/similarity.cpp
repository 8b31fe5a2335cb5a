#include "slope_monitor/core/geometry/similarity.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/LU>
#include <Eigen/SVD>

#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/rigid3.h"

namespace slope_monitor {
namespace geometry {

Similarity3 Similarity3::Inverse() const {
  Similarity3 inv;
  inv.scale = 1.0 / scale;
  inv.rotation = rotation.transpose();
  inv.translation = -(inv.scale * (inv.rotation * translation));
  return inv;
}

void HelmertOptions::Check() const {
  if (!(inlier_threshold > 0.0))
    throw ConfigError(Message("helmert inlier_threshold must be > 0, got ", inlier_threshold));
  if (max_iterations <= 0)
    throw ConfigError(Message("helmert max_iterations must be > 0, got ", max_iterations));
}

bool AreCollinear(const std::vector<Eigen::Vector3d>& points, double relative_tolerance) {
  if (points.size() < 3) return true;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(points.size());
  Eigen::MatrixXd a(points.size(), 3);
  for (size_t i = 0; i < points.size(); ++i) a.row(i) = (points[i] - mean).transpose();
  const Eigen::Vector3d s = Eigen::JacobiSVD<Eigen::MatrixXd>(a).singularValues();
  return !(s(0) > 0.0) || s(1) < relative_tolerance * s(0);
}

camera::ExteriorOrientation TransformExterior(const Similarity3& t,
                                              const camera::ExteriorOrientation& e) {
  const Eigen::Matrix3d r = e.CamFromSite().RotationMatrix() * t.rotation.transpose();
  const Eigen::Vector3d centre = t * e.position;
  const Eigen::Matrix3d d = camera::OpticalFromPhotogrammetric();
  return camera::ExteriorOrientation::FromOpticalFromSite(
      Rigid3(Eigen::Matrix3d(d * r), Eigen::Vector3d(d * -(r * centre))));
}

Similarity3 FitSimilarity(const std::vector<Eigen::Vector3d>& source,
                          const std::vector<Eigen::Vector3d>& target, bool estimate_scale,
                          const std::vector<double>& weights) {
  if (source.size() != target.size())
    throw InvalidArgument(Message("similarity: ", source.size(), " source points but ",
                                  target.size(), " target points"));
  if (source.size() < 3)
    throw InvalidArgument(Message("similarity needs >= 3 point pairs, got ", source.size()));
  if (!weights.empty() && weights.size() != source.size())
    throw InvalidArgument(
        Message("similarity: ", weights.size(), " weights for ", source.size(), " points"));
  if (AreCollinear(source) || AreCollinear(target))
    throw InvalidArgument("similarity: the points are collinear");
  double wsum = 0.0;
  Eigen::Vector3d ms = Eigen::Vector3d::Zero(), mt = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < source.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    if (!(w >= 0.0) || !source[i].allFinite() || !target[i].allFinite())
      throw InvalidArgument(
          Message("similarity: point pair ", i, " is not finite or has a negative weight"));
    wsum += w;
    ms += w * source[i];
    mt += w * target[i];
  }
  if (!(wsum > 0.0)) throw InvalidArgument("similarity: all weights are zero");
  ms /= wsum;
  mt /= wsum;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double var_s = 0.0;
  for (size_t i = 0; i < source.size(); ++i) {
    const double w = weights.empty() ? 1.0 : weights[i];
    const Eigen::Vector3d ds = source[i] - ms, dt = target[i] - mt;
    cov += w * dt * ds.transpose();
    var_s += w * ds.squaredNorm();
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d s = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) s(2, 2) = -1.0;
  Similarity3 t;
  t.rotation = svd.matrixU() * s * svd.matrixV().transpose();
  t.scale = estimate_scale ? (svd.singularValues().asDiagonal() * s).trace() / var_s : 1.0;
  t.translation = mt - t.scale * t.rotation * ms;
  return t;
}

HelmertResult FitSimilarityRobust(const std::vector<Eigen::Vector3d>& source,
                                  const std::vector<Eigen::Vector3d>& target,
                                  const HelmertOptions& options) {
  options.Check();
  HelmertResult r;
  const size_t n = source.size();
  if (n != target.size()) {
    r.message = Message(source.size(), " source points but ", target.size(), " target points");
    return r;
  }
  if (n < 3) {
    r.message = Message("too few point pairs: ", n, " (need >= 3)");
    return r;
  }
  if (AreCollinear(source) || AreCollinear(target)) {
    r.message =
        Message("all ", n, " points are collinear: the rotation about their line is undetermined");
    return r;
  }
  auto count_inliers = [&](const Similarity3& t, std::vector<bool>* in, double* sum) {
    int k = 0;
    *sum = 0.0;
    for (size_t i = 0; i < n; ++i) {
      const double e = (t * source[i] - target[i]).norm();
      (*in)[i] = e < options.inlier_threshold;
      if ((*in)[i]) {
        ++k;
        *sum += e;
      }
    }
    return k;
  };
  std::mt19937 rng(options.seed);
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::vector<bool> best(n, true), cur(n);
  int best_n = -1;
  double best_sum = 0.0;
  if (n == 3) {
    best_n = 3;
  } else {
    for (int it = 0; it < options.max_iterations; ++it) {
      size_t a = pick(rng), b = pick(rng), c = pick(rng);
      if (a == b || b == c || a == c) continue;
      std::vector<Eigen::Vector3d> s = {source[a], source[b], source[c]},
                                   t = {target[a], target[b], target[c]};
      if (AreCollinear(s, 1e-2) || AreCollinear(t, 1e-2)) continue;
      const Similarity3 tr = FitSimilarity(s, t, options.estimate_scale);
      double sum;
      const int k = count_inliers(tr, &cur, &sum);
      if (k > best_n || (k == best_n && sum < best_sum)) {
        best_n = k;
        best_sum = sum;
        best = cur;
      }
    }
  }
  // Refit on the inliers, then recount once.
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Eigen::Vector3d> s, t;
    for (size_t i = 0; i < n; ++i)
      if (best[i]) {
        s.push_back(source[i]);
        t.push_back(target[i]);
      }
    if (s.size() < 3 || AreCollinear(s) || AreCollinear(t)) {
      r.message = Message("only ", s.size(), " inliers (or collinear inliers) within ",
                          options.inlier_threshold, " m");
      return r;
    }
    r.target_from_source = FitSimilarity(s, t, options.estimate_scale);
    if (n > 3) {
      double sum;
      count_inliers(r.target_from_source, &best, &sum);
    }
  }
  r.inliers = best;
  r.residuals.resize(n);
  double ss = 0.0;
  r.num_inliers = 0;
  for (size_t i = 0; i < n; ++i) {
    r.residuals[i] = (r.target_from_source * source[i] - target[i]).norm();
    if (best[i]) {
      ss += r.residuals[i] * r.residuals[i];
      ++r.num_inliers;
    }
  }
  r.rms = std::sqrt(ss / std::max(1, r.num_inliers));
  if (r.num_inliers < 3) {
    r.message = Message("only ", r.num_inliers, " inliers");
    return r;
  }
  r.success = true;
  r.message = Message(r.num_inliers, " of ", n, " pairs inliers, rms ", r.rms, " m");
  return r;
}

}  // namespace geometry
}  // namespace slope_monitor
