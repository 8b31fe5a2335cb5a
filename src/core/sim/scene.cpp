#include "slope_monitor/core/sim/scene.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <cstdlib>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {
namespace {

std::uint64_t SplitMix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

inline double Quintic(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

// LatticeNoise in two steps: the row's hash (of iy and the salt), shared by
// the lattice points of one row, then the point's value.
inline std::uint64_t RowHash(std::int64_t iy, std::uint32_t salt) {
  return SplitMix(static_cast<std::uint64_t>(iy) ^ (static_cast<std::uint64_t>(salt) << 32));
}
inline float LatticeValue(std::int64_t ix, std::uint64_t row_hash) {
  const std::uint64_t h = SplitMix(static_cast<std::uint64_t>(ix) * 0x8da6b343ULL ^ row_hash);
  return static_cast<float>(static_cast<double>(h >> 11) * (2.0 / 9007199254740992.0) - 1.0);
}

// Smooth value noise in [-1, 1] with unit lattice spacing.
double ValueNoise(double x, double y, std::uint32_t salt) {
  const double fx = std::floor(x), fy = std::floor(y);
  const auto ix = static_cast<std::int64_t>(fx), iy = static_cast<std::int64_t>(fy);
  const double tx = Quintic(x - fx), ty = Quintic(y - fy);
  const std::uint64_t row0 = RowHash(iy, salt), row1 = RowHash(iy + 1, salt);
  const double a = LatticeValue(ix, row0), b = LatticeValue(ix + 1, row0);
  const double c = LatticeValue(ix, row1), d = LatticeValue(ix + 1, row1);
  return (a + (b - a) * tx) * (1.0 - ty) + (c + (d - c) * tx) * ty;
}

double Smoothstep(double e0, double e1, double x) {
  const double q = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return q * q * (3.0 - 2.0 * q);
}

// Ray-sphere (centre c, radius r): nearest positive distance or -1.
double RaySphere(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const Eigen::Vector3d& c,
                 double r) {
  const Eigen::Vector3d oc = o - c;
  const double b = oc.dot(d);
  const double cc = oc.squaredNorm() - r * r;
  const double disc = b * b - cc;
  if (disc < 0.0) return -1.0;
  const double s = std::sqrt(disc);
  double t = -b - s;
  if (t <= 0.0) t = -b + s;
  return t > 0.0 ? t : -1.0;
}

}  // namespace

float LatticeNoise(std::int64_t ix, std::int64_t iy, std::uint32_t salt) {
  return LatticeValue(ix, RowHash(iy, salt));
}

// ---------------------------------------------------------------------------
// HeightGrid
// ---------------------------------------------------------------------------

void HeightGrid::Triangle(int t, Eigen::Vector3d* a, Eigen::Vector3d* b, Eigen::Vector3d* c) const {
  const int cell = t >> 1;
  const int i = cell % (nx - 1), j = cell / (nx - 1);
  if ((t & 1) == 0) {  // lower-right: (i,j) (i+1,j) (i+1,j+1)
    *a = Vertex(i, j);
    *b = Vertex(i + 1, j);
    *c = Vertex(i + 1, j + 1);
  } else {  // upper-left: (i,j) (i+1,j+1) (i,j+1)
    *a = Vertex(i, j);
    *b = Vertex(i + 1, j + 1);
    *c = Vertex(i, j + 1);
  }
}

double HeightGrid::IntersectTriangle(int t, const Eigen::Vector3d& o,
                                     const Eigen::Vector3d& d) const {
  Eigen::Vector3d a, b, c;
  Triangle(t, &a, &b, &c);
  // Moeller-Trumbore.
  const Eigen::Vector3d e1 = b - a, e2 = c - a;
  const Eigen::Vector3d p = d.cross(e2);
  const double det = e1.dot(p);
  if (std::abs(det) < 1e-14) return -1.0;
  const double inv = 1.0 / det;
  const Eigen::Vector3d s = o - a;
  const double u = s.dot(p) * inv;
  if (u < -1e-9 || u > 1.0 + 1e-9) return -1.0;
  const Eigen::Vector3d q = s.cross(e1);
  const double v = d.dot(q) * inv;
  if (v < -1e-9 || u + v > 1.0 + 1e-9) return -1.0;
  const double dist = e2.dot(q) * inv;
  return dist > 0.0 ? dist : -1.0;
}

double HeightGrid::HeightAt(double x, double y) const {
  const double gx = (x - xmin) / spacing, gy = (y - ymin) / spacing;
  if (!(gx >= 0.0 && gy >= 0.0 && gx <= nx - 1 && gy <= ny - 1))
    return std::numeric_limits<double>::quiet_NaN();
  int i = std::min(static_cast<int>(gx), nx - 2), j = std::min(static_cast<int>(gy), ny - 2);
  const double fx = gx - i, fy = gy - j;
  const double z00 = Z(i, j), z10 = Z(i + 1, j), z11 = Z(i + 1, j + 1), z01 = Z(i, j + 1);
  if (fx >= fy) return z00 + fx * (z10 - z00) + fy * (z11 - z10);  // lower-right triangle
  return z00 + fy * (z01 - z00) + fx * (z11 - z01);                // upper-left triangle
}

Eigen::Vector3d HeightGrid::NormalAt(double x, double y) const {
  const double gx = std::clamp((x - xmin) / spacing, 0.0, nx - 1.0),
               gy = std::clamp((y - ymin) / spacing, 0.0, ny - 1.0);
  int i = std::min(static_cast<int>(gx), nx - 2), j = std::min(static_cast<int>(gy), ny - 2);
  const int t = 2 * (j * (nx - 1) + i) + ((gx - i) >= (gy - j) ? 0 : 1);
  Eigen::Vector3d a, b, c;
  Triangle(t, &a, &b, &c);
  return (b - a).cross(c - a).normalized();
}

double HeightGrid::IntersectRay(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                                double t_max) const {
  const double step = 0.5 * spacing;
  double prev_t = 0.0;
  double prev_above = 0.0;
  bool have_prev = false;
  for (double t = 0.0; t <= t_max; t += step) {
    const Eigen::Vector3d p = o + t * d;
    const double h = HeightAt(p.x(), p.y());
    if (std::isnan(h)) {
      have_prev = false;
      continue;
    }
    const double above = p.z() - h;
    if (above <= 0.0) {
      if (!have_prev) return t;
      double lo = prev_t, hi = t;  // above at lo, below at hi
      for (int it = 0; it < 40; ++it) {
        const double mid = 0.5 * (lo + hi);
        const Eigen::Vector3d q = o + mid * d;
        const double hq = HeightAt(q.x(), q.y());
        if (std::isnan(hq) || q.z() > hq)
          lo = mid;
        else
          hi = mid;
      }
      return 0.5 * (lo + hi);
    }
    prev_t = t;
    prev_above = above;
    have_prev = true;
  }
  (void)prev_above;
  return std::numeric_limits<double>::infinity();
}

// ---------------------------------------------------------------------------
// Plate
// ---------------------------------------------------------------------------

double Plate::Intersect(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double* albedo) const {
  const double denom = normal.dot(d);
  if (denom >= -1e-12) return -1.0;  // parallel or the back side
  const double t = normal.dot(centre - o) / denom;
  if (t <= 0.0) return -1.0;
  const Eigen::Vector3d q = o + t * d - centre;
  const double a = right.dot(q), b = up.dot(q);
  if (is_tag) {
    if (std::abs(a) > half || std::abs(b) > half) return -1.0;
    int col = static_cast<int>(std::floor((a + half) / cell));
    int row = static_cast<int>(std::floor((half - b) / cell));
    col = std::clamp(col, 0, cells - 1);
    row = std::clamp(row, 0, cells - 1);
    *albedo = pattern[row * cells + col] > 127 ? 0.9 : 0.05;
    return t;
  }
  const double r2 = a * a + b * b;
  if (r2 > half * half) return -1.0;
  *albedo = r2 <= disc_radius * disc_radius ? 0.95 : 0.05;
  return t;
}

std::vector<Eigen::Vector3d> Plate::Outline(int n) const {
  std::vector<Eigen::Vector3d> out;
  out.reserve(n);
  for (int k = 0; k < n; ++k) {
    const double s = static_cast<double>(k) / n;
    double a, b;
    if (is_tag) {
      // Walk the square's perimeter.
      const double p = s * 4.0;
      const int side = static_cast<int>(p);
      const double f = p - side;
      const double h = half;
      switch (side) {
        case 0:
          a = -h + 2 * h * f;
          b = -h;
          break;
        case 1:
          a = h;
          b = -h + 2 * h * f;
          break;
        case 2:
          a = h - 2 * h * f;
          b = h;
          break;
        default:
          a = -h;
          b = h - 2 * h * f;
          break;
      }
    } else {
      a = half * std::cos(2 * M_PI * s);
      b = half * std::sin(2 * M_PI * s);
    }
    out.push_back(centre + a * right + b * up);
  }
  return out;
}

// ---------------------------------------------------------------------------
// Obstacles
// ---------------------------------------------------------------------------

double IntersectObstacle(const Obstacle& o, const Eigen::Vector3d& origin, const Eigen::Vector3d& d,
                         Eigen::Vector3d* normal) {
  if (o.kind == Obstacle::Kind::kBoulder) {
    const Eigen::Vector3d c = o.base + Eigen::Vector3d(0, 0, o.height);
    const double t = RaySphere(origin, d, c, o.radius);
    if (t > 0.0 && normal) *normal = (origin + t * d - c).normalized();
    return t;
  }
  // Tree: ellipsoid crown (semi-axes radius, radius, 0.35 h) centred at 0.65 h,
  // and a trunk cylinder (radius 0.06 h, at least 0.1 m) from the base to 0.4 h.
  double best = -1.0;
  const double cz = 0.35 * o.height;
  const Eigen::Vector3d cc = o.base + Eigen::Vector3d(0, 0, 0.65 * o.height) + o.crown_offset;
  const Eigen::Vector3d scale(1.0 / o.radius, 1.0 / o.radius, 1.0 / cz);
  const Eigen::Vector3d os = (origin - cc).cwiseProduct(scale);
  const Eigen::Vector3d ds = d.cwiseProduct(scale);
  const double a = ds.squaredNorm(), b = os.dot(ds), c = os.squaredNorm() - 1.0;
  const double disc = b * b - a * c;
  if (disc >= 0.0) {
    const double s = std::sqrt(disc);
    double t = (-b - s) / a;
    if (t <= 0.0) t = (-b + s) / a;
    if (t > 0.0) {
      best = t;
      if (normal) {
        const Eigen::Vector3d p = os + t * ds;
        *normal = p.cwiseProduct(scale).normalized();
      }
    }
  }
  const double tr = std::max(0.1, 0.06 * o.height);
  const Eigen::Vector2d o2 = (origin - o.base).head<2>();
  const Eigen::Vector2d d2 = d.head<2>();
  const double qa = d2.squaredNorm();
  if (qa > 1e-12) {
    const double qb = o2.dot(d2), qc = o2.squaredNorm() - tr * tr;
    const double qd = qb * qb - qa * qc;
    if (qd >= 0.0) {
      const double t = (-qb - std::sqrt(qd)) / qa;
      const double z = origin.z() + t * d.z() - o.base.z();
      if (t > 0.0 && z >= -1.0 && z <= 0.4 * o.height && (best < 0.0 || t < best)) {
        best = t;
        if (normal) {
          const Eigen::Vector2d n2 = (o2 + t * d2).normalized();
          *normal = Eigen::Vector3d(n2.x(), n2.y(), 0.0);
        }
      }
    }
  }
  return best;
}

// ---------------------------------------------------------------------------
// Scene
// ---------------------------------------------------------------------------

namespace {

void CheckSpec(const SceneSpec& spec) {
  const TerrainOptions& t = spec.terrain;
  if (!(t.extent[1] > t.extent[0] && t.extent[3] > t.extent[2])) {
    throw InvalidArgument("scene extent must have xmax > xmin and ymax > ymin");
  }
  if (!(t.grid_spacing > 0.0)) throw InvalidArgument("scene grid_spacing must be > 0");
  if (!(spec.foliage_sway >= 0.0 && spec.foliage_sway <= 1.0)) {
    throw InvalidArgument(Message("scene foliage_sway ", spec.foliage_sway, " outside [0, 1]"));
  }
}

// The plate's pattern: a tag36h11 code's cells, or a circle's disc and ring.
void SetPlatePattern(const TargetPlacement& p, apriltag_family_t* family, Plate* plate) {
  if (p.family == "tag36h11") {
    if (p.id < 0 || p.id >= static_cast<int>(family->ncodes)) {
      throw InvalidArgument(Message("tag36h11 id ", p.id, " is outside [0, ", family->ncodes, ")"));
    }
    image_u8_t* im = apriltag_to_image(family, p.id);
    plate->is_tag = true;
    plate->cells = im->width;
    plate->cell = p.size / family->width_at_border;
    plate->half = 0.5 * plate->cell * plate->cells;
    plate->pattern.resize(static_cast<size_t>(im->width) * im->height);
    for (int r = 0; r < im->height; ++r)
      for (int c = 0; c < im->width; ++c)
        plate->pattern[r * im->width + c] = im->buf[r * im->stride + c];
    // libapriltag 3.3 exports image_u8_destroy only from libapriltag-utils;
    // apriltag_to_image allocates the struct and its buffer with malloc.
    std::free(im->buf);
    std::free(im);
  } else if (p.family == "circle") {
    plate->is_tag = false;
    plate->disc_radius = 0.5 * p.size;
    plate->half = p.size;  // dark ring out to twice the disc diameter
  } else {
    throw InvalidArgument(
        Message("target family '", p.family, "' is not rendered (tag36h11 or circle)"));
  }
}

}  // namespace

Scene::Scene(const SceneSpec& spec) : spec_(spec) {
  CheckSpec(spec_);
  BuildTexture();
  BuildReferenceGrid();
  PlaceObstacles();
  PlaceTargets();
}

// The texture's octaves (GroundAlbedo), coarsest first: wavelength and amplitude.
void Scene::BuildTexture() {
  const TextureOptions& tx = spec_.texture;
  octave_amplitude_sum_ = 0.0;
  for (double lambda = tx.coarsest_wavelength; lambda >= tx.finest_wavelength * 0.999;
       lambda *= 0.5) {
    const double amp = 0.6 + 0.4 * std::clamp(std::log2(16.0 / lambda) / 8.0, 0.0, 1.0);
    octaves_.push_back({lambda, amp});
    octave_amplitude_sum_ += amp;
  }
  cos_azimuth_ = std::cos(spec_.landslide.azimuth);
  sin_azimuth_ = std::sin(spec_.landslide.azimuth);
}

void Scene::BuildReferenceGrid() {
  const TerrainOptions& t = spec_.terrain;
  reference_.xmin = t.extent[0];
  reference_.ymin = t.extent[2];
  reference_.spacing = t.grid_spacing;
  reference_.nx =
      static_cast<int>(std::floor((t.extent[1] - t.extent[0]) / t.grid_spacing + 1e-9)) + 1;
  reference_.ny =
      static_cast<int>(std::floor((t.extent[3] - t.extent[2]) / t.grid_spacing + 1e-9)) + 1;
  if (reference_.nx < 2 || reference_.ny < 2)
    throw InvalidArgument("scene grid has fewer than 2x2 vertices");
  reference_.z.resize(static_cast<size_t>(reference_.nx) * reference_.ny);
  for (int j = 0; j < reference_.ny; ++j)
    for (int i = 0; i < reference_.nx; ++i)
      reference_.z[static_cast<size_t>(j) * reference_.nx + i] =
          AnalyticHeight(reference_.X(i), reference_.Y(j));
}

// Obstacles on the ground.
void Scene::PlaceObstacles() {
  for (Obstacle o : spec_.obstacles) {
    if (std::isnan(o.base.z())) {
      const double h = reference_.HeightAt(o.base.x(), o.base.y());
      if (std::isnan(h))
        throw InvalidArgument(
            Message("obstacle at (", o.base.x(), ", ", o.base.y(), ") is outside the site"));
      o.base.z() = h;
    }
    o.moves = spec_.landslide.Weight(o.base.head<2>()) > 0.0;
    obstacles_.push_back(o);
  }
}

// Target plates and their truth.
void Scene::PlaceTargets() {
  const std::unique_ptr<apriltag_family_t, void (*)(apriltag_family_t*)> family(tag36h11_create(),
                                                                                tag36h11_destroy);
  for (size_t k = 0; k < spec_.targets.size(); ++k) {
    const TargetPlacement& p = spec_.targets[k];
    Plate plate = PlateGeometry(p, static_cast<int>(k));
    SetPlatePattern(p, family.get(), &plate);
    reference_plates_.push_back(plate);

    TargetTruth tt;
    tt.id = p.id;
    tt.family = p.family;
    tt.key = p.family + "/" + std::to_string(p.id);
    tt.size = p.size;
    tt.role = p.role;
    tt.normal = plate.normal;
    tt.up_in_plate = plate.up;
    tt.positions = {plate.centre};
    targets_.push_back(tt);
  }
}

// A plate's centre and axes on the reference surface: flat on the ground at
// its mount height, or on a vertical post turned towards face_toward.
Plate Scene::PlateGeometry(const TargetPlacement& p, int k) const {
  const double h = reference_.HeightAt(p.xy.x(), p.xy.y());
  if (std::isnan(h)) {
    throw InvalidArgument(Message("target ", p.family, "/", p.id, " at (", p.xy.x(), ", ", p.xy.y(),
                                  ") is outside the site"));
  }
  // Plate normal: the analytic surface normal averaged over +-1 m.
  const double e = 1.0;
  const double gx =
      (AnalyticHeight(p.xy.x() + e, p.xy.y()) - AnalyticHeight(p.xy.x() - e, p.xy.y())) / (2 * e);
  const double gy =
      (AnalyticHeight(p.xy.x(), p.xy.y() + e) - AnalyticHeight(p.xy.x(), p.xy.y() - e)) / (2 * e);
  const Eigen::Vector3d ground_normal = Eigen::Vector3d(-gx, -gy, 1.0).normalized();
  const Eigen::Vector3d ground(p.xy.x(), p.xy.y(), h);
  Eigen::Vector3d n = ground_normal;
  Eigen::Vector3d centre = ground + p.mount_height * n;
  if (p.facing) {  // on a vertical post, turned towards face_toward
    centre = ground + Eigen::Vector3d(0.0, 0.0, p.mount_height);
    const Eigen::Vector3d to = p.face_toward - centre;
    if (to.norm() < 1e-6) {
      throw InvalidArgument(
          Message("target ", p.family, "/", p.id, ": face_toward is the plate centre itself"));
    }
    n = to.normalized();
    if (n.z() <= 0.0) {
      throw InvalidArgument(
          Message("target ", p.family, "/", p.id, ": face_toward (", p.face_toward.transpose(),
                  ") is not above the plate's horizon; the plate would face the ground"));
    }
  }
  // The plate's top: site north projected into the plate (flat plates), site
  // up projected into it (facing plates, whose normal may point north).
  const Eigen::Vector3d top = p.facing ? Eigen::Vector3d::UnitZ() : Eigen::Vector3d::UnitY();
  Eigen::Vector3d up = top - top.dot(n) * n;
  if (up.norm() < 1e-6) up = Eigen::Vector3d::UnitY() - n.y() * n;  // facing straight up
  up.normalize();
  Plate plate;
  plate.target = k;
  plate.normal = n;
  plate.up = up;
  plate.right = up.cross(n).normalized();
  plate.centre = centre;
  if (p.facing) {  // the lower edge must clear the ground
    const double half_extent = (p.family == "circle" ? p.size : 0.5 * p.size * 10.0 / 8.0);
    const double lowest =
        centre.z() - half_extent * std::abs(up.z()) - half_extent * std::abs(plate.right.z());
    const double ground_below =
        std::max(h, AnalyticHeight(p.xy.x() + half_extent * n.x(), p.xy.y() + half_extent * n.y()));
    if (lowest < ground_below + 0.02) {
      throw InvalidArgument(Message(
          "target ", p.family, "/", p.id, ": mount_height ", p.mount_height, " m is too low for a ",
          p.size, " m plate turned to face_toward; its lower edge is ", ground_below - lowest,
          " m in the ground (raise mount_height)"));
    }
  }
  return plate;
}

double Scene::ScarpDrop(double x, double y) const {
  const LandslideModel& l = spec_.landslide;
  if (spec_.scarp.depth <= 0.0) return 0.0;
  const double dx = x - l.centre.x(), dy = y - l.centre.y();
  const double u = dx * std::cos(l.azimuth) + dy * std::sin(l.azimuth);
  const double v = -dx * std::sin(l.azimuth) + dy * std::cos(l.azimuth);
  const double rho = std::hypot(u / l.length, v / l.width);
  if (rho >= 1.0) return 0.0;
  const double step = std::clamp((1.0 - rho) / spec_.scarp.band, 0.0, 1.0);
  const double head = std::clamp((1.0 - u / l.length) / 2.0, 0.0, 1.0);
  return spec_.scarp.depth * step * head * head;
}

double Scene::AnalyticHeight(double x, double y) const {
  const TerrainOptions& t = spec_.terrain;
  const double s = std::clamp((y - t.extent[2]) / (t.extent[3] - t.extent[2]), 0.0, 1.0);
  double z = t.relief * (0.35 * s + 0.65 * s * s);
  // Rolling relief: three sinusoids at halving wavelengths, directions and
  // phases from the seed.
  double amp = t.undulation, lambda = t.undulation_wavelength;
  for (int k = 0; k < 3; ++k) {
    const std::uint64_t h = SplitMix(spec_.seed * 131ULL + k);
    const double dir = (h & 0xffff) / 65536.0 * 2.0 * M_PI;
    const double phase = ((h >> 16) & 0xffff) / 65536.0 * 2.0 * M_PI;
    z += amp * std::sin(2.0 * M_PI * (x * std::cos(dir) + y * std::sin(dir)) / lambda + phase);
    amp *= 0.5;
    lambda *= 0.5;
  }
  return z - ScarpDrop(x, y);
}

Scene::State Scene::AtTime(double t) const {
  State st;
  st.t = t;
  st.grid = reference_;
  const LandslideModel& l = spec_.landslide;
  if (l.Travel(t) != 0.0) {
    for (int j = 0; j < st.grid.ny; ++j) {
      for (int i = 0; i < st.grid.nx; ++i) {
        const Eigen::Vector3d now(st.grid.X(i), st.grid.Y(j), 0.0);
        const Eigen::Vector3d ref = l.ReferencePositionOf(now, t);
        if (l.Weight(ref.head<2>()) == 0.0) continue;
        const Eigen::Vector3d ref_on_ground(ref.x(), ref.y(), AnalyticHeight(ref.x(), ref.y()));
        st.grid.z[static_cast<size_t>(j) * st.grid.nx + i] =
            ref_on_ground.z() + l.DisplacementAt(ref_on_ground, t).z();
      }
    }
  }
  st.plates = reference_plates_;
  for (Plate& p : st.plates) p.centre += l.DisplacementAt(p.centre, t);
  st.obstacles = obstacles_;
  for (Obstacle& o : st.obstacles)
    if (o.moves) o.base += l.DisplacementAt(o.base, t);
  if (spec_.foliage_motion) {
    // Wind: a new sway and leaf pattern per stamp (1 ms), from seed and t.
    const std::uint64_t stamp = static_cast<std::uint64_t>(std::llround(t * 1000.0));
    for (size_t k = 0; k < st.obstacles.size(); ++k) {
      Obstacle& o = st.obstacles[k];
      if (o.kind != Obstacle::Kind::kTree) continue;
      const std::uint64_t h =
          SplitMix(SplitMix(stamp ^ (static_cast<std::uint64_t>(spec_.seed) << 40)) + k);
      const double angle = 2.0 * M_PI * static_cast<double>(h & 0xffff) / 65536.0;
      const double amount = 0.3 + 0.7 * static_cast<double>((h >> 16) & 0xffff) / 65535.0;
      const double sway = spec_.foliage_sway * o.radius * amount;
      o.crown_offset = Eigen::Vector3d(sway * std::cos(angle), sway * std::sin(angle), 0.0);
      o.foliage_phase = static_cast<std::uint32_t>(h >> 32) | 1u;  // never 0
    }
  }
  return st;
}

Rgb Scene::GroundAlbedo(const Eigen::Vector2d& x, double footprint) const {
  const TextureOptions& tx = spec_.texture;
  const std::uint32_t seed = spec_.seed * 7919u;
  // Material masks from low-frequency noise.
  const double veg_noise = 0.6 * ValueNoise(x.x() / 14.0, x.y() / 14.0, seed + 1) +
                           0.4 * ValueNoise(x.x() / 5.0, x.y() / 5.0, seed + 2);
  const double rock_noise = 0.6 * ValueNoise(x.x() / 18.0, x.y() / 18.0, seed + 3) +
                            0.4 * ValueNoise(x.x() / 6.0, x.y() / 6.0, seed + 4);
  // The noise is roughly uniform-ish in [-0.7, 0.7]: threshold by the share.
  const double veg_t = 0.7 - 1.4 * tx.vegetation_fraction;
  const double rock_t = 0.7 - 1.4 * tx.rock_fraction;
  const double veg = Smoothstep(veg_t - 0.05, veg_t + 0.05, veg_noise);
  const double rock = (1.0 - veg) * Smoothstep(rock_t - 0.04, rock_t + 0.04, rock_noise);
  const double soil = 1.0 - veg - rock;

  // Multi-scale texture: octaves from coarsest to finest (Scene::Scene),
  // faded out when finer than about two pixel footprints (anti-aliasing).
  double fbm = 0.0;
  for (size_t octave = 0; octave < octaves_.size(); ++octave) {
    const double lambda = octaves_[octave].wavelength;
    const double fade = std::clamp(lambda / (2.0 * std::max(footprint, 1e-6)) - 1.0, 0.0, 1.0);
    if (fade <= 0.0) continue;
    fbm +=
        fade * octaves_[octave].amplitude *
        ValueNoise(x.x() / lambda, x.y() / lambda, seed + 100 + static_cast<std::uint32_t>(octave));
  }
  const double norm = octave_amplitude_sum_;
  fbm /= std::max(norm, 1e-9) * 0.35;  // roughly unit amplitude

  // Low-texture scarp: fresh, uniform soil.
  double contrast = tx.contrast;
  Rgb base = soil * Rgb(0.55f, 0.45f, 0.35f) + veg * Rgb(0.20f, 0.33f, 0.14f) +
             rock * Rgb(0.62f, 0.61f, 0.58f);
  const LandslideModel& l = spec_.landslide;
  if (spec_.scarp.depth > 0.0) {
    const double dx = x.x() - l.centre.x(), dy = x.y() - l.centre.y();
    const double u = dx * cos_azimuth_ + dy * sin_azimuth_;
    const double v = -dx * sin_azimuth_ + dy * cos_azimuth_;
    const double rho = std::hypot(u / l.length, v / l.width);
    if (rho >= 1.0 - spec_.scarp.band && rho <= 1.0 && -u / l.length > spec_.scarp.head_fraction) {
      contrast *= 0.05;
      base = Rgb(0.62f, 0.52f, 0.40f);
    }
  }
  const float f = static_cast<float>(std::clamp(1.0 + contrast * fbm, 0.05, 2.0));
  return (base * f).cwiseMin(1.0f);
}

Rgb Scene::ObstacleAlbedo(const Obstacle& o, const Eigen::Vector3d& p, int epoch_salt) const {
  const Eigen::Vector3d q = p - o.base;
  if (o.kind == Obstacle::Kind::kBoulder) {
    const double n = ValueNoise(q.x() / 0.15 + q.z() * 3.0, q.y() / 0.15, spec_.seed + 900);
    return Rgb(0.5f, 0.5f, 0.48f) * static_cast<float>(1.0 + 0.3 * n);
  }
  if (q.z() < 0.4 * o.height && q.head<2>().norm() < std::max(0.1, 0.06 * o.height) + 1e-3) {
    return Rgb(0.25f, 0.18f, 0.12f);  // trunk
  }
  if (o.foliage_phase != 0) {
    // Foliage in the wind: leaf clusters (~0.12 m) with dark gaps, a new
    // pattern at every stamp, attached to the swaying crown.
    const Eigen::Vector3d c = q - o.crown_offset;
    const double n1 =
        ValueNoise(c.x() / 0.12 + c.z() * 5.0, c.y() / 0.12 - c.z() * 3.0, o.foliage_phase);
    const double n2 =
        ValueNoise(c.x() / 0.05 - c.z() * 9.0, c.y() / 0.05, o.foliage_phase ^ 0x5bd1e995u);
    const double leaf = std::clamp(1.0 + 0.7 * n1 + 0.3 * n2, 0.15, 2.0);
    const double gap = Smoothstep(-0.55, -0.35, n1);  // 0 in the gaps between clusters
    return Rgb(0.12f, 0.25f, 0.09f) * static_cast<float>(leaf * (0.35 + 0.65 * gap));
  }
  // Foliage: its pattern changes every epoch (wind) - matching must fail here.
  const double n =
      ValueNoise(q.x() / 0.08 + q.z() * 7.0, q.y() / 0.08, spec_.seed + 1000 + epoch_salt);
  return Rgb(0.12f, 0.25f, 0.09f) * static_cast<float>(1.0 + 0.6 * n);
}

}  // namespace sim
}  // namespace slope_monitor
