// The simulated slope scene: a triangulated height field with a landslide
// body, a multi-scale ground texture, target plates (AprilTag tag36h11 from
// libapriltag's own tag images, circular targets) and occluding obstacles
// (trees, boulders). Scene::AtTime(t) gives the geometry of one instant: the
// height field, plates and obstacles moved by the displacement field.
//
// Geometry is exact: the surface IS the triangle mesh over the grid (two
// triangles per cell, split along the (i, j)-(i+1, j+1) diagonal); plates are
// planar squares / discs; obstacles are spheres (boulders) and a vertical
// cylinder trunk under an ellipsoid crown (trees).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace sim {

// A regular grid of heights: vertex (i, j) at x = xmin + i * spacing,
// y = ymin + j * spacing; height z[j * nx + i].
struct HeightGrid {
  double xmin = 0.0, ymin = 0.0, spacing = 1.0;
  int nx = 0, ny = 0;
  std::vector<double> z;

  double X(int i) const { return xmin + i * spacing; }
  double Y(int j) const { return ymin + j * spacing; }
  double Z(int i, int j) const { return z[static_cast<size_t>(j) * nx + i]; }
  Eigen::Vector3d Vertex(int i, int j) const { return {X(i), Y(j), Z(i, j)}; }
  // Height of the triangle mesh at (x, y); NaN outside the grid.
  double HeightAt(double x, double y) const;
  // Unit normal of the mesh at (x, y) (of the triangle containing it).
  Eigen::Vector3d NormalAt(double x, double y) const;
  int NumCells() const { return (nx - 1) * (ny - 1); }
  // Triangle t = 2 * (j * (nx - 1) + i) + {0, 1}: its three vertices.
  void Triangle(int t, Eigen::Vector3d* a, Eigen::Vector3d* b, Eigen::Vector3d* c) const;
  // Ray (origin o, unit direction d) against triangle t: distance, or < 0.
  double IntersectTriangle(int t, const Eigen::Vector3d& o, const Eigen::Vector3d& d) const;
  // First intersection of a ray with the mesh by walking the grid (slow, exact;
  // for visibility checks of a few points). Returns the distance or infinity.
  double IntersectRay(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double t_max) const;
};

// A target plate at one instant.
struct Plate {
  int target = 0;  // index into Scene::targets()
  bool is_tag = true;
  Eigen::Vector3d centre{0, 0, 0};
  Eigen::Vector3d normal{0, 0, 1};
  Eigen::Vector3d right{1, 0, 0};     // in-plane, the tag's x (columns)
  Eigen::Vector3d up{0, 1, 0};        // in-plane, the tag's top
  double half = 0.5;                  // [m] tag: half side of the whole plate; circle: plate radius
  double disc_radius = 0.0;           // [m] circle: bright disc radius
  double cell = 0.1;                  // [m] tag cell size (size / width_at_border)
  int cells = 10;                     // tag: total_width
  std::vector<std::uint8_t> pattern;  // tag: cells x cells, row 0 at the top (libapriltag image)

  // Intersect: distance along the ray and the plate's reflectance there
  // (0..1), or a negative distance when the ray misses the plate / hits its back.
  double Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double* albedo) const;
  // Points on the outline of the plate (n of them) in site.
  std::vector<Eigen::Vector3d> Outline(int n) const;
  double BoundingRadius() const { return is_tag ? half * std::sqrt(2.0) : half; }
};

struct TerrainOptions {
  Eigen::Vector4d extent{0.0, 200.0, 0.0, 150.0};  // [m] xmin xmax ymin ymax
  double grid_spacing = 0.5;                       // [m]
  double relief = 40.0;                            // [m] height difference foot -> crest
  double undulation = 1.5;                         // [m] amplitude of the rolling relief
  double undulation_wavelength = 40.0;             // [m] longest wavelength of it
};

struct TextureOptions {
  double contrast = 0.35;             // [-] relative amplitude of the fine texture
  double vegetation_fraction = 0.3;   // [-] share of the ground under vegetation-like patches
  double rock_fraction = 0.2;         // [-] share under rock outcrops
  double finest_wavelength = 0.02;    // [m] finest texture scale
  double coarsest_wavelength = 16.0;  // [m]
};

struct Lighting {
  Eigen::Vector3d sun{0.3, -0.5, 0.81};  // unit vector towards the sun (site)
  double ambient = 0.35;                 // [-] share of light that is not direct sun
  double sky = 0.85;                     // radiance of rays that hit nothing
};

// Spec of a target to place: position (x, y) on the reference surface.
struct TargetPlacement {
  std::string family = "tag36h11";  // tag36h11 | circle
  int id = 0;
  double size = 0.6;  // [m] tag: black border edge; circle: bright disc diameter
  io::TargetRole role = io::TargetRole::kControl;
  Eigen::Vector2d xy{0, 0};    // [m] site
  double mount_height = 0.03;  // [m] plate above the ground (flat plates: along the normal;
                               //     facing plates: the post height of the plate centre)
  // Facing plates: a plate on a post turned towards this site point (e.g. the
  // fixed cameras), as crews mount targets for cameras on the opposite side.
  // Without it the plate lies flat on the ground (normal = the surface's).
  bool facing = false;
  Eigen::Vector3d face_toward{0, 0, 0};  // [m] site
};

struct SceneSpec {
  unsigned int seed = 7;
  TerrainOptions terrain;
  TextureOptions texture;
  Lighting lighting;
  LandslideModel landslide;
  Scarp scarp;
  std::vector<Obstacle> obstacles;  // base z is filled from the terrain when NaN
  // Wind in the tree crowns (off by default: every image as before). On:
  // Scene::AtTime(t) sways each crown horizontally by up to
  // foliage_sway * radius (its silhouette edge moves) and gives it a leaf
  // pattern (clusters ~0.12 m with gaps) that is new at every stamp;
  // deterministic from the seed and t (rounded to 1 ms). The crowns are then
  // unmatchable between any two images of different stamps.
  bool foliage_motion = false;
  double foliage_sway = 0.15;  // [-] largest crown displacement / crown radius, [0, 1]
  std::vector<TargetPlacement> targets;
};

// Colour reflectance (r, g, b) in [0, 1]; mono images use its mean.
using Rgb = Eigen::Vector3f;

class Scene {
 public:
  explicit Scene(const SceneSpec& spec);  // throws InvalidArgument naming the bad value

  const SceneSpec& spec() const { return spec_; }
  const HeightGrid& reference_grid() const { return reference_; }
  const std::vector<TargetTruth>& targets() const { return targets_; }  // positions: reference only
  const std::vector<Obstacle>& obstacles() const { return obstacles_; }

  // The analytic reference surface height (the mesh samples it at the vertices).
  double AnalyticHeight(double x, double y) const;

  // Geometry at time t.
  struct State {
    double t = 0.0;
    HeightGrid grid;
    std::vector<Plate> plates;
    std::vector<Obstacle> obstacles;
  };
  State AtTime(double t) const;

  // Ground reflectance at the reference position x_ref, low-passed for a
  // pixel footprint of `footprint` metres (octaves finer than ~2 footprints
  // fade out, which is the renderer's anti-aliasing).
  Rgb GroundAlbedo(const Eigen::Vector2d& x_ref, double footprint) const;
  // Obstacle reflectance at a point of its surface (trees change with the epoch: wind).
  Rgb ObstacleAlbedo(const Obstacle& o, const Eigen::Vector3d& p, int epoch_salt) const;

 private:
  // The constructor's stages, in this order.
  void BuildTexture();
  void BuildReferenceGrid();
  void PlaceObstacles();
  void PlaceTargets();
  Plate PlateGeometry(const TargetPlacement& p, int k) const;
  double ScarpDrop(double x, double y) const;
  struct Octave {
    double wavelength;  // [m]
    double amplitude;   // [-]
  };
  SceneSpec spec_;
  std::vector<Octave> octaves_;                   // GroundAlbedo's texture, coarsest first
  double octave_amplitude_sum_ = 0.0;             // their amplitudes' sum
  double cos_azimuth_ = 1.0, sin_azimuth_ = 0.0;  // of the landslide's motion azimuth
  HeightGrid reference_;
  std::vector<TargetTruth> targets_;
  std::vector<Plate> reference_plates_;
  std::vector<Obstacle> obstacles_;
};

// Ray against an obstacle: distance or < 0; *normal the outward normal there.
double IntersectObstacle(const Obstacle& o, const Eigen::Vector3d& origin, const Eigen::Vector3d& d,
                         Eigen::Vector3d* normal);

// Deterministic hash noise in [-1, 1] on the integer lattice.
float LatticeNoise(std::int64_t ix, std::int64_t iy, std::uint32_t salt);

}  // namespace sim
}  // namespace slope_monitor
