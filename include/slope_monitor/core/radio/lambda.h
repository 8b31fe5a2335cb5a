// Integer least-squares ambiguity resolution by the LAMBDA method
// (Teunissen 1995; search in the form of Chang, Yang & Zhou 2005, "MLAMBDA").
//
// Given float ambiguities a (n) with covariance Q (n x n, SPD), find the m
// integer vectors z with the smallest squared norms
//   s(z) = (a - z)^T Q^-1 (a - z),
// sorted ascending. Steps:
//   1. Q = L^T D L (L unit lower triangular, D diagonal), computed from the
//      last index upward.
//   2. Decorrelation ("reduction"): integer Gauss transformations and
//      permutations build a unimodular Z with z = Z^T a, Qz = Z^T Q Z whose
//      L^T D L factors are as diagonal as integers allow and whose D is
//      ordered so the search starts with the most precise conditional
//      ambiguity.
//   3. Depth-first search with a shrinking ellipsoid (the radius is the
//      m-th best norm found so far), enumerating each level in zig-zag order
//      around the conditional estimate.
//   4. Back-transformation: candidates a_int = Z^-T z (exact integers).
// Norms are invariant under Z, so s is the same in both spaces.
//
// The ratio test (Summary::ratio = s2 / s1) accepts the best candidate when it
// is clearly better than the runner-up.
#pragma once

#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace radio {

struct LambdaResult {
  // candidates.col(k) is the k-th best integer vector (k = 0 best), in the
  // original ambiguity space; squared_norms(k) its s(z).
  Eigen::MatrixXd candidates;
  Eigen::VectorXd squared_norms;
  Eigen::MatrixXd z_transform;  // Z (unimodular), z = Z^T a
  double Ratio() const;         // s(1) / s(0) (infinity when s(0) == 0; 0 when only one candidate)
};

// Throws InvalidArgument when sizes disagree, Q is not symmetric positive
// definite, a is not finite, or m < 1.
LambdaResult LambdaSearch(const Eigen::VectorXd& a, const Eigen::MatrixXd& q, int m = 2);

// L^T D L factorisation Q = L^T diag(d) L (exposed for tests); throws
// InvalidArgument when Q is not positive definite.
void LtdlFactor(const Eigen::MatrixXd& q, Eigen::MatrixXd* l, Eigen::VectorXd* d);

}  // namespace radio
}  // namespace slope_monitor
