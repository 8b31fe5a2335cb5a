// LAMBDA integer search against RTKLIB's unit-test vectors
// (test/data/lambda_rtklib/lambda_vectors.txt) and against brute force.
#include "slope_monitor/core/radio/lambda.h"

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace radio {
namespace {

struct Case {
  int n = 0, m = 0;
  Eigen::VectorXd a;
  Eigen::MatrixXd q, f;
  Eigen::VectorXd s;
};

std::vector<Case> ReadCases(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  std::vector<Case> cases;
  std::string line;
  int q_row = 0, f_row = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "case") {
      Case c;
      std::string k;
      int id;
      ls >> id >> k >> c.n >> k >> c.m;
      c.a.resize(c.n);
      c.q.resize(c.n, c.n);
      c.f.resize(c.n, c.m);
      c.s.resize(c.m);
      cases.push_back(c);
      q_row = f_row = 0;
    } else if (tag == "a") {
      for (int i = 0; i < cases.back().n; ++i) ls >> cases.back().a(i);
    } else if (tag == "Q") {
      for (int i = 0; i < cases.back().n; ++i) ls >> cases.back().q(q_row, i);
      ++q_row;
    } else if (tag == "F") {
      for (int i = 0; i < cases.back().m; ++i) ls >> cases.back().f(f_row, i);
      ++f_row;
    } else if (tag == "s") {
      for (int i = 0; i < cases.back().m; ++i) ls >> cases.back().s(i);
    }
  }
  return cases;
}

TEST(Lambda, ReproducesRtklibVectors) {
  const auto cases = ReadCases(std::string(SM_TEST_DATA_DIR) + "/lambda_rtklib/lambda_vectors.txt");
  ASSERT_EQ(cases.size(), 2u);
  for (const Case& c : cases) {
    const LambdaResult r = LambdaSearch(c.a, c.q, c.m);
    ASSERT_EQ(r.candidates.cols(), c.m);
    for (int k = 0; k < c.m; ++k) {
      for (int i = 0; i < c.n; ++i)
        EXPECT_NEAR(r.candidates(i, k), c.f(i, k), 1e-4) << "n=" << c.n << " cand " << k;
      EXPECT_NEAR(r.squared_norms(k), c.s(k), 1e-4) << "n=" << c.n << " cand " << k;
    }
    // The norms are those of the returned candidates in the original space.
    const Eigen::MatrixXd qi = c.q.inverse();
    for (int k = 0; k < c.m; ++k) {
      const Eigen::VectorXd e = c.a - r.candidates.col(k);
      EXPECT_NEAR(e.dot(qi * e), r.squared_norms(k), 1e-4 * (1.0 + r.squared_norms(k)));
    }
    EXPECT_NEAR(r.Ratio(), c.s(1) / c.s(0), 1e-6);
  }
}

TEST(Lambda, LtdlReconstructs) {
  Eigen::MatrixXd q(3, 3);
  q << 4, 2, 1, 2, 5, 3, 1, 3, 6;
  Eigen::MatrixXd l;
  Eigen::VectorXd d;
  LtdlFactor(q, &l, &d);
  EXPECT_NEAR((l.transpose() * d.asDiagonal() * l - q).norm(), 0.0, 1e-12);
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(l(i, i), 1.0);
  EXPECT_DOUBLE_EQ(l(0, 1), 0.0);
  EXPECT_DOUBLE_EQ(d(2), 6.0);
}

// Brute force over a box around the rounded float vector on random, strongly
// correlated 4-D problems: same best and second-best.
TEST(Lambda, MatchesBruteForce) {
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::MatrixXd b(4, 4);
    for (int i = 0; i < 16; ++i) b(i / 4, i % 4) = g(rng);
    const Eigen::MatrixXd q = 0.3 * (b * b.transpose() + 0.05 * Eigen::MatrixXd::Identity(4, 4));
    Eigen::VectorXd a(4);
    for (int i = 0; i < 4; ++i) a(i) = 10.0 * g(rng);
    const Eigen::MatrixXd qi = q.inverse();
    double best = 1e300, second = 1e300;
    Eigen::VectorXd zb, z2;
    const int r = 6;
    Eigen::VectorXd c0 = a.array().round().matrix();
    for (int i0 = -r; i0 <= r; ++i0)
      for (int i1 = -r; i1 <= r; ++i1)
        for (int i2 = -r; i2 <= r; ++i2)
          for (int i3 = -r; i3 <= r; ++i3) {
            Eigen::VectorXd z = c0 + Eigen::Vector4d(i0, i1, i2, i3);
            const Eigen::VectorXd e = a - z;
            const double s = e.dot(qi * e);
            if (s < best) {
              second = best;
              z2 = zb;
              best = s;
              zb = z;
            } else if (s < second) {
              second = s;
              z2 = z;
            }
          }
    const LambdaResult res = LambdaSearch(a, q, 2);
    EXPECT_NEAR(res.squared_norms(0), best, 1e-8 * (1 + best)) << trial;
    EXPECT_NEAR(res.squared_norms(1), second, 1e-8 * (1 + second)) << trial;
    EXPECT_EQ((res.candidates.col(0) - zb).norm(), 0.0) << trial;
  }
}

TEST(Lambda, BadInputIsRejected) {
  Eigen::MatrixXd q = Eigen::MatrixXd::Identity(2, 2);
  q(1, 1) = -1.0;
  EXPECT_THROW(LambdaSearch(Eigen::Vector2d(0.2, 0.3), q, 2), InvalidArgument);
  EXPECT_THROW(LambdaSearch(Eigen::Vector2d(0.2, NAN), Eigen::MatrixXd::Identity(2, 2), 2),
               InvalidArgument);
  EXPECT_THROW(LambdaSearch(Eigen::Vector3d(0.2, 0.1, 0.0), Eigen::MatrixXd::Identity(2, 2), 2),
               InvalidArgument);
}

}  // namespace
}  // namespace radio
}  // namespace slope_monitor
