// Identification of circular markers on a known board: a layout (hex or
// square lattice with its pitch, or a list of positions) is fitted to the
// detected centres: the lattice is grown from a seed and its neighbours
// (local homography predictions), then cv::findHomography with RANSAC
// removes mismatches and a homography plus a two-term radial distortion is
// fitted to the rest; each marker gets its lattice index, and the fit's
// residual per marker and RMS are reported in pixels.
//
//   targets::BoardLayout board = targets::BoardLayout::Load("board_ringgrid.json");
//   targets::LatticeFit fit = targets::FitLattice(centres, outer_diameters_px, board);
//   if (!fit.ok) std::cerr << fit.message;   // e.g. the lattice does not fit
//
// Layout files (YAML; JSON is YAML too):
//   * ringgrid's target JSON: pitch_mm, rows, long_row_cols,
//     marker_outer_radius_mm (hex lattice, rows alternate long and short);
//   * our own form:
//       lattice: hex            # hex | square | list
//       pitch: 8.0              # [mm] centre distance of neighbours
//       rows: 15                # [-] optional extent (0: unbounded)
//       cols: 14                # [-] optional; hex: markers on a long row
//       marker_diameter: 9.6    # [mm] optional outer diameter (checked against the photo)
//       positions: [[x, y], ...]  # [mm] lattice: list only
//
// The board is numbered relative to the detections: row 0 is the lattice row
// of the detections nearest the top of the image, column 0 the leftmost
// lattice column seen (a photo rarely shows the whole board; an absolute
// number needs a code or a pose). A hex row's columns are counted in whole
// pitches; rows shifted by half a pitch take the column on their left.
//
// Pitch: a homography absorbs the board's scale, so a wrong pitch alone is
// seen only against the marker size: with marker_diameter given, the measured
// outer diameter / neighbour distance is compared with the layout's and a
// disagreement of more than 25 % is reported in LatticeFit::warning (the
// numbering is unaffected). A wrong lattice (square for hex) fails with a
// message.
//
// A list of positions (no pose needed): each detection and its nearest
// detection against each listed position and one of its 3 nearest listed
// neighbours give a similarity; the one that brings the most listed
// positions within a quarter of that distance of a detection wins, then a
// homography is fitted to the matches and the matching repeated. A listed
// marker's id (and row) is its index in the list (col 0): the list's order
// numbers the board absolutely. Fewer than half of the listed or detected
// markers matched (at least 4), or fewer than 80 % of the matches within 3 %
// of the neighbour distance of the fitted image: "does not fit". No
// distortion terms (a strong lens may need a lattice or a pose); a
// symmetric list (a regular lattice given as a list) has several equally
// good numberings, of which one is taken: give such a board as a lattice.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace targets {

struct BoardLayout {
  enum class Kind { kHex, kSquare, kList };
  Kind kind = Kind::kHex;
  double pitch = 0.0;                      // [mm]
  int rows = 0;                            // [-] 0: unbounded
  int cols = 0;                            // [-] hex: markers on a long row; 0: unbounded
  double marker_diameter = 0.0;            // [mm] outer diameter; 0: unknown
  std::vector<Eigen::Vector2d> positions;  // [mm] kList
  std::string source;                      // file it came from

  // Throws IoError (unreadable) or ConfigError naming the file and key.
  static BoardLayout Load(const std::string& path);
  // Board position [mm] of lattice index (i, j): hex axial i*(p, 0) + j*(p/2, p sqrt(3)/2),
  // square (i p, j p).
  Eigen::Vector2d Position(int i, int j) const;
};

struct LatticeMarker {
  int observation = -1;            // index into the centres given
  int row = 0, col = 0;            // lattice index (see the header comment)
  int id = 0;                      // row * (cols or columns seen) + col; list: index in the list
  Eigen::Vector2d board{0, 0};     // [mm] relative to the lattice origin
  Eigen::Vector2d residual{0, 0};  // [px] measured minus the fitted board position
  bool inlier = false;             // |residual| <= max(1 px, 4 x the median |residual|)
};

struct LatticeFit {
  bool ok = false;
  std::string message;  // why not ok
  std::string warning;  // ok, but something disagrees (marker size vs pitch)
  // The board's image: u = H b, then a radial distortion about `centre`
  // (r = |u - centre| / scale): x = centre + (u - centre)(1 + k1 r^2 + k2 r^4).
  // A strong lens (the real ring photo) bends a board's rows by pixels: a
  // homography alone leaves residuals of several px at the image's sides.
  Eigen::Matrix3d image_from_board = Eigen::Matrix3d::Identity();
  double k1 = 0.0, k2 = 0.0;
  Eigen::Vector2d centre{0, 0};
  double scale = 1.0;
  Eigen::Vector2d Project(const Eigen::Vector2d& board) const;
  double rms_homography_px = 0.0;  // the same markers with the homography alone (k1 = k2 = 0)
  std::vector<LatticeMarker> markers;
  std::vector<int> off_lattice;  // centres not on a lattice point (indices)
  double rms_px = 0.0;           // RMS of |residual| over the inliers
  int rows_seen = 0, cols_seen = 0;
  double size_ratio = 0.0;  // measured median outer diameter / neighbour distance (0: not given)
};

// centres [px]; outer_diameters [px] per centre (may be empty); the image
// size gives the distortion centre (its middle; 0 x 0: the centres' middle).
LatticeFit FitLattice(const std::vector<Eigen::Vector2d>& centres,
                      const std::vector<double>& outer_diameters, const BoardLayout& layout,
                      int image_width = 0, int image_height = 0);

}  // namespace targets
}  // namespace slope_monitor
