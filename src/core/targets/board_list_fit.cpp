// A board given as a list of marker positions (BoardLayout::Kind::kList)
// fitted to the detected centres without a pose: every triangle of a
// detection and its 2 nearest detections, against every listed position and
// two of its 3 nearest listed neighbours (both orders), gives an affine map
// (board -> image; mirrored ones are skipped); the one that brings the most
// listed positions within a quarter of the nearest-detection distance of a
// detection wins; then the map is refitted to those matches (affine under 6,
// else a homography) and the matching repeated with it (3 times). A listed
// marker's number is its index in the list (the list's order is the board's
// numbering, absolute, unlike a lattice's).
#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>
#include <opencv2/calib3d.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/targets/board_layout.h"

namespace slope_monitor {
namespace targets {
namespace detail {
namespace {

// A detection matches a projected listed position within this share of the
// hypothesis' neighbour distance; the final inlier gate (share of the median
// distance between neighbouring detections, at least 1 px; a homography has
// 8 parameters, so a wrong list of 6 matches still fits to a few px:
// board_list_test's wrong list, 2.8 px RMS at 113 px spacing). 80 % of the
// matches must be inliers.
constexpr double kListGate = 0.25, kListInlierShare = 0.03;
constexpr int kListNeighbours = 3, kListRefinements = 3;

Eigen::Vector2d ListApply(const Eigen::Matrix3d& h, const Eigen::Vector2d& p) {
  return (h * p.homogeneous()).hnormalized();
}

// Nearest other point of `pts` to pts[i] (-1 when alone).
std::vector<int> NearestOthers(const std::vector<Eigen::Vector2d>& pts, int i, int k) {
  std::vector<std::pair<double, int>> d;
  for (int j = 0; j < static_cast<int>(pts.size()); ++j)
    if (j != i) d.emplace_back((pts[j] - pts[i]).squaredNorm(), j);
  const int take = std::min<int>(k, d.size());
  std::partial_sort(d.begin(), d.begin() + take, d.end());
  std::vector<int> out;
  out.reserve(take);
  for (int q = 0; q < take; ++q) out.push_back(d[q].second);
  return out;
}

// For each listed position, the nearest detection within `gate` px of its
// image (-1: none); a detection is taken by one position only (the nearer).
std::vector<int> MatchList(const std::vector<Eigen::Vector2d>& centres,
                           const std::vector<Eigen::Vector2d>& positions, const Eigen::Matrix3d& h,
                           double gate) {
  std::vector<int> match(positions.size(), -1);
  std::vector<double> best(centres.size(), gate);
  std::vector<int> owner(centres.size(), -1);
  for (size_t a = 0; a < positions.size(); ++a) {
    const Eigen::Vector2d p = ListApply(h, positions[a]);
    for (size_t k = 0; k < centres.size(); ++k) {
      const double d = (centres[k] - p).norm();
      if (d < best[k]) {
        best[k] = d;
        owner[k] = static_cast<int>(a);
      }
    }
  }
  for (size_t k = 0; k < centres.size(); ++k)
    if (owner[k] >= 0) match[owner[k]] = static_cast<int>(k);
  return match;
}

int CountMatches(const std::vector<int>& match) {
  return static_cast<int>(std::count_if(match.begin(), match.end(), [](int k) { return k >= 0; }));
}

// The affine map board -> image taking a, b, c to i, j, k; false when it
// mirrors (a board is not seen from behind) or is degenerate.
bool Affine3(const std::array<Eigen::Vector2d, 3>& board, const std::array<Eigen::Vector2d, 3>& img,
             Eigen::Matrix3d* h) {
  Eigen::Matrix2d b, m;
  b << board[1] - board[0], board[2] - board[0];
  m << img[1] - img[0], img[2] - img[0];
  if (std::abs(b.determinant()) < 1e-9 * b.squaredNorm()) return false;
  const Eigen::Matrix2d a = m * b.inverse();
  if (!(a.determinant() > 0)) return false;
  h->setIdentity();
  h->topLeftCorner<2, 2>() = a;
  h->topRightCorner<2, 1>() = img[0] - a * board[0];
  return h->allFinite();
}

// The best affine map over the triangles (see the file comment); its gate [px].
Eigen::Matrix3d BestAffine(const std::vector<Eigen::Vector2d>& centres,
                           const std::vector<Eigen::Vector2d>& positions, double* gate) {
  Eigen::Matrix3d best = Eigen::Matrix3d::Identity();
  int best_count = -1;
  for (int i = 0; i < static_cast<int>(centres.size()); ++i) {
    const std::vector<int> ni = NearestOthers(centres, i, 2);
    if (ni.size() < 2) continue;
    const double dij = (centres[ni[0]] - centres[i]).norm();
    for (int a = 0; a < static_cast<int>(positions.size()); ++a) {
      const std::vector<int> na = NearestOthers(positions, a, kListNeighbours);
      for (int b : na) {
        for (int c : na) {
          Eigen::Matrix3d h;
          if (b == c || !Affine3({positions[a], positions[b], positions[c]},
                                 {centres[i], centres[ni[0]], centres[ni[1]]}, &h))
            continue;
          const int count = CountMatches(MatchList(centres, positions, h, kListGate * dij));
          if (count > best_count) {
            best_count = count;
            best = h;
            *gate = kListGate * dij;
          }
        }
      }
    }
  }
  return best;
}

// Least squares board -> image of the matches: affine under 6, else a
// homography.
bool RefitList(const std::vector<Eigen::Vector2d>& centres,
               const std::vector<Eigen::Vector2d>& positions, const std::vector<int>& match,
               Eigen::Matrix3d* h) {
  std::vector<cv::Point2d> src, dst;
  for (size_t a = 0; a < positions.size(); ++a) {
    if (match[a] < 0) continue;
    src.emplace_back(positions[a].x(), positions[a].y());
    dst.emplace_back(centres[match[a]].x(), centres[match[a]].y());
  }
  if (src.size() < 3) return false;
  cv::Mat m;
  if (src.size() < 6) {
    m = cv::estimateAffine2D(src, dst, cv::noArray(), cv::LMEDS);
    if (m.empty()) return false;
    m.push_back(cv::Mat((cv::Mat_<double>(1, 3) << 0, 0, 1)));
  } else {
    m = cv::findHomography(src, dst, 0);
    if (m.empty()) return false;
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) (*h)(r, c) = m.at<double>(r, c) / m.at<double>(2, 2);
  return h->allFinite();
}

}  // namespace

LatticeFit FitListLayout(const std::vector<Eigen::Vector2d>& centres, const BoardLayout& layout) {
  LatticeFit fit;
  const std::vector<Eigen::Vector2d>& pos = layout.positions;
  if (centres.size() < 4) {
    fit.message = Message("layout '", layout.source, "': ", centres.size(),
                          " circles, at least 4 are needed to fit a list of positions");
    return fit;
  }
  double gate = 0.0;
  Eigen::Matrix3d h = BestAffine(centres, pos, &gate);
  std::vector<int> match = MatchList(centres, pos, h, gate);
  for (int it = 0; it < kListRefinements && RefitList(centres, pos, match, &h); ++it)
    match = MatchList(centres, pos, h, gate);
  const int matched = CountMatches(match);
  if (matched < 4 || matched < 0.5 * std::min(centres.size(), pos.size())) {
    fit.message =
        Message("layout '", layout.source, "' does not fit: at most ", matched, " of the ",
                pos.size(), " listed positions meet one of the ", centres.size(),
                " circles (a wrong list, or too few of its markers seen)");
    return fit;
  }
  fit.image_from_board = h;
  std::vector<double> nearest;
  nearest.reserve(centres.size());
  for (int k = 0; k < static_cast<int>(centres.size()); ++k)
    nearest.push_back((centres[NearestOthers(centres, k, 1)[0]] - centres[k]).norm());
  std::nth_element(nearest.begin(), nearest.begin() + nearest.size() / 2, nearest.end());
  const double inlier_gate = std::max(1.0, kListInlierShare * nearest[nearest.size() / 2]);
  std::vector<bool> used(centres.size(), false);
  double ss = 0;
  int inl = 0;
  for (size_t a = 0; a < pos.size(); ++a) {
    if (match[a] < 0) continue;
    LatticeMarker m;
    m.observation = match[a];
    m.id = m.row = static_cast<int>(a);
    m.board = pos[a];
    m.residual = centres[match[a]] - ListApply(h, pos[a]);
    m.inlier = m.residual.norm() <= inlier_gate;
    used[match[a]] = true;
    if (m.inlier) {
      ss += m.residual.squaredNorm();
      ++inl;
    }
    fit.markers.push_back(m);
  }
  for (size_t k = 0; k < centres.size(); ++k)
    if (!used[k]) fit.off_lattice.push_back(static_cast<int>(k));
  fit.rms_px = fit.rms_homography_px = inl > 0 ? std::sqrt(ss / inl) : 0.0;
  if (inl < 4 || inl < 0.8 * matched) {
    fit.message = Message("layout '", layout.source, "' does not fit: only ", inl, " of the ",
                          matched, " matched positions within ", inlier_gate,
                          " px of the board's image (a wrong list?)");
    return fit;
  }
  fit.rows_seen = static_cast<int>(fit.markers.size());
  fit.cols_seen = 1;
  fit.ok = true;
  return fit;
}

}  // namespace detail
}  // namespace targets
}  // namespace slope_monitor
