#include "slope_monitor/core/targets/board_layout.h"

#include <algorithm>
#include <cmath>
#include <map>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/yaml_map.h"

namespace slope_monitor {
namespace targets {
namespace {

constexpr double kSqrt3Half = 0.8660254037844386;
// A detection takes a predicted lattice point within this share of the local
// neighbour distance; RANSAC's gate as a share of it; the marker size check.
constexpr double kLatticeGate = 0.3, kRansacShare = 0.1, kSizeTolerance = 0.25;
// Neighbour directions tried from a seed: within this angle [deg] of the
// lattice's (60 deg hex, 90 deg square).
constexpr double kBasisAngleTolDeg = 12.0;

double MedianOf(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

Eigen::Vector2d Apply(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = h * p.homogeneous();
  return q.hnormalized();
}

// Least-squares homography board -> image of the assigned points (an affine
// one while fewer than 6 are assigned).
bool FitTransform(const std::vector<Eigen::Vector2d>& board,
                  const std::vector<Eigen::Vector2d>& img, Eigen::Matrix3d* h) {
  if (board.size() < 3) return false;
  if (board.size() < 6) {
    Eigen::MatrixXd a(2 * board.size(), 6);
    Eigen::VectorXd b(2 * board.size());
    for (size_t k = 0; k < board.size(); ++k) {
      a.row(2 * k) << board[k].x(), board[k].y(), 1, 0, 0, 0;
      a.row(2 * k + 1) << 0, 0, 0, board[k].x(), board[k].y(), 1;
      b(2 * k) = img[k].x();
      b(2 * k + 1) = img[k].y();
    }
    const Eigen::VectorXd x = a.colPivHouseholderQr().solve(b);
    *h << x(0), x(1), x(2), x(3), x(4), x(5), 0, 0, 1;
    return h->allFinite();
  }
  std::vector<cv::Point2d> src, dst;
  for (size_t k = 0; k < board.size(); ++k) {
    src.emplace_back(board[k].x(), board[k].y());
    dst.emplace_back(img[k].x(), img[k].y());
  }
  const cv::Mat m = cv::findHomography(src, dst, 0);
  if (m.empty()) return false;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) (*h)(r, c) = m.at<double>(r, c);
  return h->allFinite();
}

struct Growth {
  std::map<std::pair<int, int>, int> at;   // lattice index -> centre
  std::vector<std::pair<int, int>> index;  // centre -> lattice index (assigned only)
  std::vector<bool> assigned;
  Eigen::Matrix3d h = Eigen::Matrix3d::Identity();
};

// Grows the lattice from a seed and two neighbours (axial indices (0,0),
// (1,0), (0,1)): fit, predict the neighbours (one and two steps) of every
// assigned point, take the nearest free centre within the gate, repeat.
Growth Grow(const std::vector<Eigen::Vector2d>& c, const BoardLayout& layout, int seed, int nu,
            int nv) {
  Growth g;
  g.assigned.assign(c.size(), false);
  g.index.assign(c.size(), {0, 0});
  auto assign = [&](int k, int i, int j) {
    g.at[{i, j}] = k;
    g.assigned[k] = true;
    g.index[k] = {i, j};
  };
  assign(seed, 0, 0);
  assign(nu, 1, 0);
  assign(nv, 0, 1);
  std::vector<std::pair<int, int>> steps;
  const bool hex = layout.kind == BoardLayout::Kind::kHex;
  const std::vector<std::pair<int, int>> one =
      hex ? std::vector<std::pair<int, int>>{{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, -1}, {-1, 1}}
          : std::vector<std::pair<int, int>>{{1, 0}, {-1, 0}, {0, 1}, {0, -1}};
  steps.reserve(2 * one.size());
  for (const auto& s : one) steps.push_back(s);
  for (const auto& s : one) steps.emplace_back(2 * s.first, 2 * s.second);
  for (int iter = 0; iter < 200; ++iter) {
    std::vector<Eigen::Vector2d> b, m;
    for (const auto& [ij, k] : g.at) {
      b.push_back(layout.Position(ij.first, ij.second));
      m.push_back(c[k]);
    }
    if (!FitTransform(b, m, &g.h)) break;
    bool grew = false;
    const auto snapshot = g.at;
    for (const auto& [ij, k] : snapshot) {
      for (const auto& s : steps) {
        const std::pair<int, int> n{ij.first + s.first, ij.second + s.second};
        if (g.at.count(n)) continue;
        const Eigen::Vector2d p = Apply(g.h, layout.Position(n.first, n.second));
        const double spacing = (Apply(g.h, layout.Position(n.first + 1, n.second)) - p).norm();
        int best = -1;
        double best_d = kLatticeGate * spacing;
        for (size_t q = 0; q < c.size(); ++q) {
          if (g.assigned[q]) continue;
          const double d = (c[q] - p).norm();
          if (d < best_d) {
            best_d = d;
            best = static_cast<int>(q);
          }
        }
        if (best >= 0) {
          assign(best, n.first, n.second);
          grew = true;
        }
      }
    }
    if (!grew) break;
  }
  return g;
}

// The board's image through the homography and a radial distortion about
// `centre` (r normalised by `scale`): x = c + (u - c) (1 + k1 r^2 + k2 r^4),
// u = H b. Parameters: h00..h21 (h22 = 1), k1, k2.
using DistortedParams = Eigen::Matrix<double, 10, 1>;

Eigen::Vector2d Distorted(const DistortedParams& x, const Eigen::Vector2d& b,
                          const Eigen::Vector2d& centre, double scale) {
  Eigen::Matrix3d h;
  h << x(0), x(1), x(2), x(3), x(4), x(5), x(6), x(7), 1.0;
  const Eigen::Vector2d u = Apply(h, b);
  const double r2 = (u - centre).squaredNorm() / (scale * scale);
  return centre + (u - centre) * (1.0 + x(8) * r2 + x(9) * r2 * r2);
}

// Gauss-Newton (Levenberg-damped, numeric Jacobian) of the model above.
DistortedParams FitDistorted(const std::vector<Eigen::Vector2d>& board,
                             const std::vector<Eigen::Vector2d>& img, const Eigen::Matrix3d& h0,
                             const Eigen::Vector2d& centre, double scale) {
  DistortedParams x;
  const Eigen::Matrix3d hn = h0 / h0(2, 2);
  x << hn(0, 0), hn(0, 1), hn(0, 2), hn(1, 0), hn(1, 1), hn(1, 2), hn(2, 0), hn(2, 1), 0.0, 0.0;
  auto cost = [&](const DistortedParams& p) {
    double c = 0;
    for (size_t k = 0; k < board.size(); ++k)
      c += (Distorted(p, board[k], centre, scale) - img[k]).squaredNorm();
    return c;
  };
  double c = cost(x), lambda = 1e-3;
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix<double, 10, 10> jtj = Eigen::Matrix<double, 10, 10>::Zero();
    DistortedParams jtr = DistortedParams::Zero();
    for (size_t k = 0; k < board.size(); ++k) {
      const Eigen::Vector2d r0 = Distorted(x, board[k], centre, scale) - img[k];
      Eigen::Matrix<double, 2, 10> j;
      for (int q = 0; q < 10; ++q) {
        DistortedParams xp = x;
        const double step = 1e-7 * std::max(1.0, std::abs(x(q)));
        xp(q) += step;
        j.col(q) = (Distorted(xp, board[k], centre, scale) - img[k] - r0) / step;
      }
      jtj += j.transpose() * j;
      jtr += j.transpose() * r0;
    }
    Eigen::Matrix<double, 10, 10> a = jtj;
    a.diagonal() += lambda * jtj.diagonal().cwiseMax(1e-12);
    const DistortedParams xn = x + a.ldlt().solve(-jtr);
    const double cn = cost(xn);
    if (xn.allFinite() && cn < c) {
      const bool done = c - cn < 1e-10 * c;
      x = xn;
      c = cn;
      lambda = std::max(lambda * 0.3, 1e-9);
      if (done) break;
    } else {
      lambda *= 10;
      if (lambda > 1e8) break;
    }
  }
  return x;
}

// The largest lattice grown from one of the 10 centres nearest the
// detections' middle and a pair of its neighbours at the lattice's angle (the
// first to the right); `spacing` [px] the median nearest-neighbour distance.
Growth GrowFromSeeds(const std::vector<Eigen::Vector2d>& centres, const BoardLayout& layout,
                     double* spacing_out) {
  const int n = static_cast<int>(centres.size());
  // Neighbour distance: median of every centre's nearest neighbour.
  std::vector<double> nn(n, 1e18);
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      if (a != b) nn[a] = std::min(nn[a], (centres[a] - centres[b]).norm());
  const double spacing = MedianOf(nn);
  *spacing_out = spacing;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& c : centres) mean += c;
  mean /= n;
  std::vector<int> seeds(n);
  for (int k = 0; k < n; ++k) seeds[k] = k;
  std::sort(seeds.begin(), seeds.end(),
            [&](int a, int b) { return (centres[a] - mean).norm() < (centres[b] - mean).norm(); });
  const double want = layout.kind == BoardLayout::Kind::kHex ? 60.0 : 90.0;
  Growth best;
  size_t best_count = 0;
  for (int t = 0; t < std::min(n, 10); ++t) {
    const int s = seeds[t];
    std::vector<int> near;
    for (int k = 0; k < n; ++k)
      if (k != s && (centres[k] - centres[s]).norm() < 1.3 * spacing) near.push_back(k);
    for (int u : near) {
      const Eigen::Vector2d du = centres[u] - centres[s];
      // Rows along the image's x: u the neighbour to the right.
      if (du.x() <= 0 || std::abs(du.y()) > std::abs(du.x()) * std::tan(M_PI / 6)) continue;
      for (int v : near) {
        const Eigen::Vector2d dv = centres[v] - centres[s];
        // v at +want degrees from u (image y down: the board's y follows v).
        const double ang = std::atan2(du.x() * dv.y() - du.y() * dv.x(), du.dot(dv)) * 180 / M_PI;
        if (std::abs(ang - want) > kBasisAngleTolDeg) continue;
        Growth g = Grow(centres, layout, s, u, v);
        if (g.at.size() > best_count) {
          best_count = g.at.size();
          best = g;
        }
      }
    }
    if (best_count >= 0.8 * n) break;
  }
  return best;
}

// The board's image fitted to the grown lattice: RANSAC, then homography and
// radial distortion (LatticeFit), the residual gate of the inliers. src/who:
// the lattice points' board positions and their centres; mask: inliers.
bool FitBoardImage(const std::vector<Eigen::Vector2d>& centres, const Growth& best,
                   const BoardLayout& layout, double spacing, int image_width, int image_height,
                   LatticeFit* fit_out, std::vector<cv::Point2d>* src_out,
                   std::vector<int>* who_out, std::vector<unsigned char>* mask_out,
                   double* inlier_gate_out) {
  // Mismatches out by RANSAC (a gate of a tenth of the neighbour distance:
  // the lens bends the rows by more than a pixel), then the homography and
  // the radial distortion on the rest.
  std::vector<cv::Point2d>& src = *src_out;
  std::vector<int>& who = *who_out;
  std::vector<unsigned char>& mask = *mask_out;
  LatticeFit& fit = *fit_out;
  std::vector<cv::Point2d> dst;
  for (const auto& [ij, k] : best.at) {
    const Eigen::Vector2d b = layout.Position(ij.first, ij.second);
    src.emplace_back(b.x(), b.y());
    dst.emplace_back(centres[k].x(), centres[k].y());
    who.push_back(k);
  }
  const cv::Mat hm =
      cv::findHomography(src, dst, cv::RANSAC, kRansacShare * spacing, mask, 2000, 0.999);
  if (hm.empty()) {
    fit.message = Message("layout '", layout.source, "': the homography fit failed");
    return false;
  }
  Eigen::Matrix3d h0;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) h0(r, c) = hm.at<double>(r, c);
  if (image_width > 0 && image_height > 0) {
    fit.centre = Eigen::Vector2d(0.5 * (image_width - 1), 0.5 * (image_height - 1));
    fit.scale = 0.5 * std::hypot(image_width, image_height);
  } else {
    Eigen::Vector2d lo = centres[0], hi = centres[0];
    for (const auto& c : centres) {
      lo = lo.cwiseMin(c);
      hi = hi.cwiseMax(c);
    }
    fit.centre = 0.5 * (lo + hi);
    fit.scale = std::max(1.0, 0.5 * (hi - lo).norm());
  }
  std::vector<Eigen::Vector2d> fb, fi;
  for (size_t q = 0; q < who.size(); ++q)
    if (mask[q]) {
      fb.emplace_back(src[q].x, src[q].y);
      fi.push_back(centres[who[q]]);
    }
  {
    Eigen::Matrix3d hl = h0;
    FitTransform(fb, fi, &hl);  // least squares on the RANSAC inliers
    double ss = 0;
    for (size_t q = 0; q < fb.size(); ++q) ss += (Apply(hl, fb[q]) - fi[q]).squaredNorm();
    fit.rms_homography_px = std::sqrt(ss / std::max<size_t>(fb.size(), 1));
    h0 = hl;
  }
  const DistortedParams dp = FitDistorted(fb, fi, h0, fit.centre, fit.scale);
  fit.image_from_board << dp(0), dp(1), dp(2), dp(3), dp(4), dp(5), dp(6), dp(7), 1.0;
  fit.k1 = dp(8);
  fit.k2 = dp(9);
  std::vector<double> abs_res;
  for (size_t q = 0; q < who.size(); ++q)
    abs_res.push_back((centres[who[q]] - fit.Project(Eigen::Vector2d(src[q].x, src[q].y))).norm());
  const double inlier_gate = std::max(1.0, 4.0 * MedianOf(abs_res));
  *inlier_gate_out = inlier_gate;
  mask.assign(who.size(), 0);
  for (size_t q = 0; q < who.size(); ++q) mask[q] = abs_res[q] <= inlier_gate;
  return true;
}

}  // namespace

namespace detail {
// board_list_fit.cpp
LatticeFit FitListLayout(const std::vector<Eigen::Vector2d>& centres, const BoardLayout& layout);
}  // namespace detail

Eigen::Vector2d BoardLayout::Position(int i, int j) const {
  if (kind == Kind::kHex) return Eigen::Vector2d((i + 0.5 * j) * pitch, j * kSqrt3Half * pitch);
  return Eigen::Vector2d(i * pitch, j * pitch);
}

BoardLayout BoardLayout::Load(const std::string& path) {
  io::YamlMap m = io::YamlMap::Load(path);
  BoardLayout b;
  b.source = path;
  if (m.Has("pitch_mm")) {  // ringgrid's target JSON
    m.String("schema", "");
    m.String("name", "");
    b.kind = Kind::kHex;
    b.pitch = m.RequiredDouble("pitch_mm", 1e-6, 1e6, "mm");
    b.rows = m.Int("rows", 0, 0, 100000);
    b.cols = m.Int("long_row_cols", 0, 0, 100000);
    b.marker_diameter = 2.0 * m.Double("marker_outer_radius_mm", 0.0, 0.0, 1e6, "mm");
    m.Double("marker_inner_radius_mm", 0.0, 0.0, 1e6, "mm");
    m.Double("marker_ring_width_mm", 0.0, 0.0, 1e6, "mm");
  } else {
    const std::string kind = m.RequiredString("lattice", {"hex", "square", "list"});
    b.kind = kind == "hex" ? Kind::kHex : kind == "square" ? Kind::kSquare : Kind::kList;
    b.marker_diameter = m.Double("marker_diameter", 0.0, 0.0, 1e6, "mm");
    if (b.kind == Kind::kList) {
      const YAML::Node list = m.Node("positions");
      if (!list || !list.IsSequence() || list.size() < 4)
        m.Fail("positions", "must be a list of at least 4 [x, y] pairs [mm]");
      for (const auto& p : list) {
        if (!p.IsSequence() || p.size() != 2) m.Fail("positions", "every entry must be [x, y]");
        b.positions.emplace_back(p[0].as<double>(), p[1].as<double>());
      }
    } else {
      b.pitch = m.RequiredDouble("pitch", 1e-6, 1e6, "mm");
      b.rows = m.Int("rows", 0, 0, 100000);
      b.cols = m.Int("cols", 0, 0, 100000);
    }
  }
  m.CheckNoUnknownKeys();
  return b;
}

Eigen::Vector2d LatticeFit::Project(const Eigen::Vector2d& board) const {
  DistortedParams x;
  const Eigen::Matrix3d& h = image_from_board;
  x << h(0, 0), h(0, 1), h(0, 2), h(1, 0), h(1, 1), h(1, 2), h(2, 0), h(2, 1), k1, k2;
  return Distorted(x, board, centre, scale);
}

LatticeFit FitLattice(const std::vector<Eigen::Vector2d>& centres,
                      const std::vector<double>& outer_diameters, const BoardLayout& layout,
                      int image_width, int image_height) {
  LatticeFit fit;
  if (layout.kind == BoardLayout::Kind::kList) return detail::FitListLayout(centres, layout);
  const int n = static_cast<int>(centres.size());
  if (n < 6) {
    fit.message = Message("layout '", layout.source, "': ", n,
                          " circles, at least 6 are needed to fit the board");
    return fit;
  }
  double spacing = 0.0;
  const Growth best = GrowFromSeeds(centres, layout, &spacing);
  const size_t best_count = best.at.size();
  if (best_count < 6) {
    fit.message =
        Message("layout '", layout.source, "' does not fit: no ",
                layout.kind == BoardLayout::Kind::kHex ? "hex" : "square",
                " lattice of neighbours at ", layout.kind == BoardLayout::Kind::kHex ? 60 : 90,
                " deg found among the ", n, " circles (a wrong lattice kind?)");
    return fit;
  }
  std::vector<cv::Point2d> src;
  std::vector<int> who;
  std::vector<unsigned char> mask;
  double inlier_gate = 0.0;
  if (!FitBoardImage(centres, best, layout, spacing, image_width, image_height, &fit, &src, &who,
                     &mask, &inlier_gate))
    return fit;
  // Numbering: rows from the top of the image, columns from the left.
  int jmin = 1 << 30, jmax = -(1 << 30), hmin = 1 << 30, hmax = -(1 << 30);
  const bool hex = layout.kind == BoardLayout::Kind::kHex;
  for (const auto& [ij, k] : best.at) {
    const int hcol = hex ? 2 * ij.first + ij.second : ij.first;
    jmin = std::min(jmin, ij.second);
    jmax = std::max(jmax, ij.second);
    hmin = std::min(hmin, hcol);
    hmax = std::max(hmax, hcol);
  }
  // Image rows: does lattice j grow downwards? Then row = j - jmin.
  const Eigen::Vector2d p0 = fit.Project(layout.Position(0, 0));
  const Eigen::Vector2d p1 = fit.Project(layout.Position(0, 1));
  const bool down = p1.y() > p0.y();
  fit.rows_seen = jmax - jmin + 1;
  fit.cols_seen = hex ? (hmax - hmin) / 2 + 1 : hmax - hmin + 1;
  const int width = layout.cols > 0 ? layout.cols : fit.cols_seen;
  double ss = 0;
  int inl = 0;
  std::vector<double> ratios;
  for (size_t q = 0; q < who.size(); ++q) {
    const int k = who[q];
    const auto ij = best.index[k];
    LatticeMarker m;
    m.observation = k;
    m.row = down ? ij.second - jmin : jmax - ij.second;
    const int hcol = hex ? 2 * ij.first + ij.second : ij.first;
    m.col = hex ? (hcol - hmin) / 2 : hcol - hmin;
    m.id = m.row * width + m.col;
    m.board = layout.Position(ij.first, ij.second);
    m.residual = centres[k] - fit.Project(m.board);
    m.inlier = mask[q] != 0;
    if (m.inlier) {
      ss += m.residual.squaredNorm();
      ++inl;
    }
    if (static_cast<size_t>(k) < outer_diameters.size() && outer_diameters[k] > 0) {
      const double local =
          (fit.Project(layout.Position(ij.first + 1, ij.second)) - fit.Project(m.board)).norm();
      ratios.push_back(outer_diameters[k] / local);
    }
    fit.markers.push_back(m);
  }
  std::sort(fit.markers.begin(), fit.markers.end(),
            [](const LatticeMarker& a, const LatticeMarker& b) { return a.id < b.id; });
  for (int k = 0; k < n; ++k)
    if (!best.assigned[k]) fit.off_lattice.push_back(k);
  fit.rms_px = inl > 0 ? std::sqrt(ss / inl) : 0.0;
  fit.size_ratio = MedianOf(ratios);
  if (layout.rows > 0 && fit.rows_seen > layout.rows) {
    fit.message = Message("layout '", layout.source, "' does not fit: the circles span ",
                          fit.rows_seen, " lattice rows, the board has ", layout.rows);
    return fit;
  }
  if (layout.cols > 0 && fit.cols_seen > layout.cols + 1) {
    fit.message = Message("layout '", layout.source, "' does not fit: the circles span ",
                          fit.cols_seen, " lattice columns, the board has ", layout.cols);
    return fit;
  }
  if (inl < 0.8 * static_cast<int>(who.size())) {
    fit.message =
        Message("layout '", layout.source, "' does not fit: only ", inl, " of ", who.size(),
                " lattice markers within ", inlier_gate, " px of the board's image");
    return fit;
  }
  if (layout.marker_diameter > 0 && fit.size_ratio > 0) {
    const double expected = layout.marker_diameter / layout.pitch;
    if (std::abs(fit.size_ratio / expected - 1.0) > kSizeTolerance) {
      fit.warning = Message("layout '", layout.source, "': the markers measure ", fit.size_ratio,
                            " pitches across (outer edge), the layout says ", expected, " (",
                            layout.marker_diameter, " mm on a ", layout.pitch,
                            " mm pitch): the pitch or the marker size in the layout is wrong "
                            "(the numbering does not depend on it; lengths on the board do)");
    }
  }
  fit.ok = true;
  return fit;
}

}  // namespace targets
}  // namespace slope_monitor
