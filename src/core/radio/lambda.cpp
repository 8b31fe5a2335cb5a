#include "slope_monitor/core/radio/lambda.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/LU>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace radio {
namespace {

double Sign(double x) { return x <= 0.0 ? -1.0 : 1.0; }

// Integer Gauss transformation of column j by column i (i > j): makes
// |L(i, j)| <= 1/2 and applies the same to Z.
void GaussTransform(int i, int j, Eigen::MatrixXd* l, Eigen::MatrixXd* z) {
  const double mu = std::round((*l)(i, j));
  if (mu == 0.0) return;
  const int n = static_cast<int>(l->rows());
  for (int k = i; k < n; ++k) (*l)(k, j) -= mu * (*l)(k, i);
  z->col(j) -= mu * z->col(i);
}

// Swaps ambiguities j and j+1, updating the factors (new_d_j1 = d(j) + L(j+1,j)^2 d(j+1)).
void Permute(int j, double new_d_j1, Eigen::MatrixXd* l, Eigen::VectorXd* d, Eigen::MatrixXd* z) {
  Eigen::MatrixXd& L = *l;
  Eigen::VectorXd& D = *d;
  const int n = static_cast<int>(L.rows());
  const double eta = D(j) / new_d_j1;
  const double lambda = D(j + 1) * L(j + 1, j) / new_d_j1;
  D(j) = eta * D(j + 1);
  D(j + 1) = new_d_j1;
  for (int k = 0; k < j; ++k) {
    const double a0 = L(j, k), a1 = L(j + 1, k);
    L(j, k) = -L(j + 1, j) * a0 + a1;
    L(j + 1, k) = eta * a0 + lambda * a1;
  }
  L(j + 1, j) = lambda;
  for (int k = j + 2; k < n; ++k) std::swap(L(k, j), L(k, j + 1));
  z->col(j).swap(z->col(j + 1));
}

void Reduce(Eigen::MatrixXd* l, Eigen::VectorXd* d, Eigen::MatrixXd* z) {
  const int n = static_cast<int>(l->rows());
  int j = n - 2, k = n - 2;
  while (j >= 0) {
    if (j <= k)
      for (int i = j + 1; i < n; ++i) GaussTransform(i, j, l, z);
    const double del = (*d)(j) + (*l)(j + 1, j) * (*l)(j + 1, j) * (*d)(j + 1);
    if (del + 1e-6 < (*d)(j + 1)) {
      Permute(j, del, l, d, z);
      k = j;
      j = n - 2;
    } else {
      --j;
    }
  }
}

// m best integer vectors for float zs with Qz = L^T D L; columns of *cands,
// norms in *norms (unsorted).
void Search(const Eigen::MatrixXd& L, const Eigen::VectorXd& D, const Eigen::VectorXd& zs, int m,
            Eigen::MatrixXd* cands, Eigen::VectorXd* norms) {
  const int n = static_cast<int>(zs.size());
  Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd dist(n), zb(n), z(n), step(n);
  cands->resize(n, m);
  norms->resize(m);
  int k = n - 1, found = 0, worst = 0;
  double radius = std::numeric_limits<double>::infinity();
  dist(k) = 0.0;
  zb(k) = zs(k);
  z(k) = std::round(zb(k));
  double y = zb(k) - z(k);
  step(k) = Sign(y);
  for (long iterations = 0; iterations < 100000000L; ++iterations) {
    const double newdist = dist(k) + y * y / D(k);
    if (newdist < radius) {
      if (k != 0) {
        --k;
        dist(k) = newdist;
        for (int i = 0; i <= k; ++i) S(k, i) = S(k + 1, i) + (z(k + 1) - zb(k + 1)) * L(k + 1, i);
        zb(k) = zs(k) + S(k, k);
        z(k) = std::round(zb(k));
        y = zb(k) - z(k);
        step(k) = Sign(y);
      } else {
        if (found < m) {
          cands->col(found) = z;
          (*norms)(found) = newdist;
          if (found == 0 || newdist > (*norms)(worst)) worst = found;
          ++found;
          if (found == m) radius = (*norms)(worst);
        } else {
          cands->col(worst) = z;
          (*norms)(worst) = newdist;
          norms->maxCoeff(&worst);
          radius = (*norms)(worst);
        }
        z(0) += step(0);
        y = zb(0) - z(0);
        step(0) = -step(0) - Sign(step(0));
      }
    } else {
      if (k == n - 1) break;
      ++k;
      z(k) += step(k);
      y = zb(k) - z(k);
      step(k) = -step(k) - Sign(step(k));
    }
  }
  if (found < m) {  // fewer candidates than asked (cannot happen for m <= infinite lattice, kept
                    // for safety)
    cands->conservativeResize(n, found);
    norms->conservativeResize(found);
  }
}

}  // namespace

double LambdaResult::Ratio() const {
  if (squared_norms.size() < 2) return 0.0;
  if (squared_norms(0) <= 0.0) return std::numeric_limits<double>::infinity();
  return squared_norms(1) / squared_norms(0);
}

void LtdlFactor(const Eigen::MatrixXd& q, Eigen::MatrixXd* l, Eigen::VectorXd* d) {
  const int n = static_cast<int>(q.rows());
  Eigen::MatrixXd a = q;
  l->setZero(n, n);
  d->setZero(n);
  for (int i = n - 1; i >= 0; --i) {
    const double di = a(i, i);
    if (!(di > 0.0))
      throw InvalidArgument(
          Message("LAMBDA: covariance is not positive definite (pivot ", i, " = ", di, ")"));
    (*d)(i) = di;
    for (int j = 0; j <= i; ++j) (*l)(i, j) = a(i, j) / di;
    for (int j = 0; j < i; ++j)
      for (int k = 0; k <= j; ++k) a(j, k) -= (*l)(i, k) * a(i, j);
    // keep a symmetric in its lower part only: a(j,k) for k <= j is what we read
  }
  // The loop above updated a(j,k) -= l(i,k) * a(i,j) using a(i,j) = l(i,j) * d(i):
  // this is a(j,k) -= d(i) l(i,j) l(i,k), the Schur complement of pivot i.
}

LambdaResult LambdaSearch(const Eigen::VectorXd& a, const Eigen::MatrixXd& q, int m) {
  const int n = static_cast<int>(a.size());
  if (n < 1) throw InvalidArgument("LAMBDA: no ambiguities");
  if (q.rows() != n || q.cols() != n)
    throw InvalidArgument(
        Message("LAMBDA: covariance is ", q.rows(), "x", q.cols(), " for ", n, " ambiguities"));
  if (m < 1)
    throw InvalidArgument(Message("LAMBDA: number of candidates m = ", m, " must be >= 1"));
  if (!a.allFinite() || !q.allFinite())
    throw InvalidArgument("LAMBDA: float ambiguities or covariance not finite");
  if (!q.isApprox(q.transpose(), 1e-9))
    throw InvalidArgument("LAMBDA: covariance is not symmetric");

  // Work on the fractional part: large ambiguities (1e9) lose no precision.
  const Eigen::VectorXd a_int = a.array().round().matrix();
  const Eigen::VectorXd a_frac = a - a_int;

  Eigen::MatrixXd L;
  Eigen::VectorXd D;
  LtdlFactor(q, &L, &D);
  Eigen::MatrixXd Z = Eigen::MatrixXd::Identity(n, n);
  Reduce(&L, &D, &Z);
  const Eigen::VectorXd zs = Z.transpose() * a_frac;

  Eigen::MatrixXd zc;
  Eigen::VectorXd s;
  Search(L, D, zs, m, &zc, &s);

  // Sort by norm.
  std::vector<int> order(s.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int x, int y) { return s(x) < s(y); });

  LambdaResult r;
  r.z_transform = Z;
  r.candidates.resize(n, s.size());
  r.squared_norms.resize(s.size());
  const Eigen::FullPivLU<Eigen::MatrixXd> zt(Z.transpose());
  for (int k = 0; k < static_cast<int>(order.size()); ++k) {
    const Eigen::VectorXd back = zt.solve(zc.col(order[k]));
    r.candidates.col(k) = back.array().round().matrix() + a_int;
    r.squared_norms(k) = s(order[k]);
  }
  return r;
}

}  // namespace radio
}  // namespace slope_monitor
