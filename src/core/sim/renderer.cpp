#include "slope_monitor/core/sim/renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

struct Item {
  int index = 0;  // plate or obstacle index
  bool plate = true;
  int c0 = 0, c1 = -1, r0 = 0, r1 = -1;  // pixel bbox (inclusive)
};

float Luma(const Rgb& c) { return 0.114f * c.z() + 0.587f * c.y() + 0.299f * c.x(); }

// Stage 1: every grid vertex in front of the camera projected to pixels
// (with the lens distortion) and its depth; a margin of 60 % beyond the
// frame keeps the triangles that cross its edge.
struct ProjectedMesh {
  std::vector<float> vx, vy, vd;    // [px], [px], [m] per vertex
  std::vector<std::uint8_t> valid;  // 1: projected
};

ProjectedMesh ProjectVertices(const HeightGrid& grid, const camera::CameraModel& model,
                              const Eigen::Matrix3d& m, const Eigen::Vector3d& origin) {
  const int w = model.sensor().width, h = model.sensor().height;
  const double c = model.principal_distance();
  const double ps = model.sensor().pixel_size;
  const size_t nv = static_cast<size_t>(grid.nx) * grid.ny;
  ProjectedMesh mesh;
  mesh.vx.assign(nv, 0.0f);
  mesh.vy.assign(nv, 0.0f);
  mesh.vd.assign(nv, 0.0f);
  mesh.valid.assign(nv, 0);
  std::vector<float>&vx = mesh.vx, &vy = mesh.vy, &vd = mesh.vd;
  std::vector<std::uint8_t>& valid = mesh.valid;
  const double half_w_mm = 0.5 * w * ps, half_h_mm = 0.5 * h * ps;
  for (int j = 0; j < grid.ny; ++j) {
    for (int i = 0; i < grid.nx; ++i) {
      const size_t k = static_cast<size_t>(j) * grid.nx + i;
      const Eigen::Vector3d u = m * (grid.Vertex(i, j) - origin);
      if (u.z() > -0.05) continue;  // behind or at the camera
      const double xu = -c * u.x() / u.z(), yu = -c * u.y() / u.z();
      if (std::abs(xu) > 1.6 * half_w_mm || std::abs(yu) > 1.6 * half_h_mm) continue;
      const Eigen::Vector2d px = model.MmToPixel(model.DistortMm(Eigen::Vector2d(xu, yu)));
      vx[k] = static_cast<float>(px.x());
      vy[k] = static_cast<float>(px.y());
      vd[k] = static_cast<float>(-u.z());
      valid[k] = 1;
    }
  }
  return mesh;
}

// Stage 2: the z-buffer, as the id of the nearest terrain triangle per
// pixel (-1: none).
std::vector<int> TriangleIds(const HeightGrid& grid, const ProjectedMesh& mesh, int w, int h) {
  const std::vector<float>&vx = mesh.vx, &vy = mesh.vy, &vd = mesh.vd;
  const std::vector<std::uint8_t>& valid = mesh.valid;
  std::vector<float> zbuf(static_cast<size_t>(w) * h, std::numeric_limits<float>::infinity());
  std::vector<int> tri(static_cast<size_t>(w) * h, -1);
  for (int j = 0; j + 1 < grid.ny; ++j) {
    for (int i = 0; i + 1 < grid.nx; ++i) {
      const size_t k00 = static_cast<size_t>(j) * grid.nx + i, k10 = k00 + 1, k01 = k00 + grid.nx,
                   k11 = k01 + 1;
      for (int half = 0; half < 2; ++half) {
        const size_t ka = k00, kb = half == 0 ? k10 : k11, kc = half == 0 ? k11 : k01;
        if (!valid[ka] || !valid[kb] || !valid[kc]) continue;
        const float ax = vx[ka], ay = vy[ka], bx = vx[kb], by = vy[kb], cx = vx[kc], cy = vy[kc];
        const float area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if (std::abs(area) < 1e-12f) continue;
        const int c0 = std::max(0, static_cast<int>(std::ceil(std::min({ax, bx, cx}))));
        const int c1 = std::min(w - 1, static_cast<int>(std::floor(std::max({ax, bx, cx}))));
        const int r0 = std::max(0, static_cast<int>(std::ceil(std::min({ay, by, cy}))));
        const int r1 = std::min(h - 1, static_cast<int>(std::floor(std::max({ay, by, cy}))));
        if (c0 > c1 || r0 > r1) continue;
        const int id = 2 * (j * (grid.nx - 1) + i) + half;
        const float inv = 1.0f / area;
        for (int r = r0; r <= r1; ++r) {
          for (int cc = c0; cc <= c1; ++cc) {
            const float px = static_cast<float>(cc), py = static_cast<float>(r);
            const float l0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) * inv;
            const float l1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) * inv;
            const float l2 = 1.0f - l0 - l1;
            if (l0 < -1e-6f || l1 < -1e-6f || l2 < -1e-6f) continue;
            const float depth = l0 * vd[ka] + l1 * vd[kb] + l2 * vd[kc];
            const size_t p = static_cast<size_t>(r) * w + cc;
            if (depth < zbuf[p]) {
              zbuf[p] = depth;
              tri[p] = id;
            }
          }
        }
      }
    }
  }
  return tri;
}

// Stage 3: the image boxes of the target plates and obstacles (where rays
// are tested against them and supersampled).
std::vector<Item> ImageBoxes(const Scene::State& state, const camera::CameraModel& model,
                             const camera::ExteriorOrientation& pose, const Eigen::Matrix3d& m,
                             const Eigen::Vector3d& origin) {
  const int w = model.sensor().width, h = model.sensor().height;
  const double c = model.principal_distance();
  const double ps = model.sensor().pixel_size;
  const double focal_px = c / ps;
  std::vector<Item> items;
  auto add_item = [&](int index, bool plate, const Eigen::Vector3d& centre, double radius) {
    const Eigen::Vector3d u = m * (centre - origin);
    const double depth = -u.z();
    if (depth <= radius + 0.05) return;
    Eigen::Vector2d px;
    model.Project(pose, centre, &px);
    if (!px.allFinite()) return;
    const double r_px = 1.15 * focal_px * radius / (depth - radius) + 2.0;
    Item it;
    it.index = index;
    it.plate = plate;
    it.c0 = std::max(0, static_cast<int>(std::floor(px.x() - r_px)));
    it.c1 = std::min(w - 1, static_cast<int>(std::ceil(px.x() + r_px)));
    it.r0 = std::max(0, static_cast<int>(std::floor(px.y() - r_px)));
    it.r1 = std::min(h - 1, static_cast<int>(std::ceil(px.y() + r_px)));
    if (it.c0 <= it.c1 && it.r0 <= it.r1) items.push_back(it);
  };
  for (size_t k = 0; k < state.plates.size(); ++k) {
    add_item(static_cast<int>(k), true, state.plates[k].centre, state.plates[k].BoundingRadius());
  }
  for (size_t k = 0; k < state.obstacles.size(); ++k) {
    const Obstacle& o = state.obstacles[k];
    const double r = std::max(o.radius, 0.5 * o.height) + 0.2;
    add_item(static_cast<int>(k), false,
             o.base + Eigen::Vector3d(0, 0, 0.5 * o.height) + o.crown_offset,
             std::hypot(r, 0.5 * o.height));
  }
  return items;
}

// Distance along the ray `d` from `origin` to the terrain, starting from the
// z-buffer's triangle at pixel (pc, pr) and its neighbours; *hit_tri the
// triangle hit (-1: none, kInf returned).
double TerrainHit(const HeightGrid& grid, const std::vector<int>& tri, int w, int h,
                  const Eigen::Vector3d& origin, const Eigen::Vector3d& d, int pc, int pr,
                  int* hit_tri) {
  pc = std::clamp(pc, 0, w - 1);
  pr = std::clamp(pr, 0, h - 1);
  const int t0 = tri[static_cast<size_t>(pr) * w + pc];
  *hit_tri = -1;
  if (t0 < 0) return kInf;
  double t = grid.IntersectTriangle(t0, origin, d);
  if (t > 0.0) {
    *hit_tri = t0;
    return t;
  }
  // Neighbouring cells (the rasteriser used straight edges in the image).
  // A cell whose square the ray's ground track (the line through origin
  // along d's x-y part) misses holds no hit and is skipped: the line meets a
  // square of side s centred on c iff |d_xy x (c - o_xy)| <= (|dx| + |dy|) s/2
  // (kept with a relative margin far above the rounding of the triangle
  // test, so the nearest hit, and so the image, is the same as testing all).
  const int cell = t0 >> 1;
  const int ci = cell % (grid.nx - 1), cj = cell / (grid.nx - 1);
  const double reach = (std::abs(d.x()) + std::abs(d.y())) * 0.5 * grid.spacing * (1.0 + 1e-6);
  double best = kInf;
  for (int dj = -2; dj <= 2; ++dj) {
    for (int di = -2; di <= 2; ++di) {
      const int ni = ci + di, nj = cj + dj;
      if (ni < 0 || nj < 0 || ni >= grid.nx - 1 || nj >= grid.ny - 1) continue;
      const double cx = grid.X(ni) + 0.5 * grid.spacing - origin.x();
      const double cy = grid.Y(nj) + 0.5 * grid.spacing - origin.y();
      if (std::abs(d.x() * cy - d.y() * cx) > reach) continue;
      for (int hh = 0; hh < 2; ++hh) {
        const int id = 2 * (nj * (grid.nx - 1) + ni) + hh;
        const double tt = grid.IntersectTriangle(id, origin, d);
        if (tt > 0.0 && tt < best) {
          best = tt;
          *hit_tri = id;
        }
      }
    }
  }
  return best;
}

// Stage 4: the radiance of one ray `d` through pixel (pc, pr): the nearest
// of the plates and obstacles whose image boxes hold the pixel (`here`) and
// the terrain, lit by the sun; the sky where nothing is hit. *plate_hit the
// plate index seen (-1: none).
struct RayShading {
  const Scene& scene;
  const Scene::State& state;
  const RenderOptions& options;
  const Lighting& light;
  Eigen::Vector3d sun;
  const HeightGrid& grid;
  const std::vector<int>& tri;  // TriangleIds
  int w, h;
  Eigen::Vector3d origin;
  double c, ps;  // [mm] principal distance, pixel size
  bool moved;
  const LandslideModel::InverseAt& reference_of;

  Rgb Shade(const Eigen::Vector3d& d, int pc, int pr, const std::vector<const Item*>& here,
            int* plate_hit) const {
    *plate_hit = -1;
    int hit_tri = -1;
    const double t_ground = TerrainHit(grid, tri, w, h, origin, d, pc, pr, &hit_tri);
    double t_obst = kInf;
    int obst = -1;
    Eigen::Vector3d obst_normal(0, 0, 1);
    double t_plate = kInf;
    int plate = -1;
    double plate_albedo = 0.0;
    for (const Item* it : here) {
      if (it->plate) {
        double a = 0.0;
        const double t = state.plates[it->index].Intersect(origin, d, &a);
        if (t > 0.0 && t < t_plate) {
          t_plate = t;
          plate = it->index;
          plate_albedo = a;
        }
      } else {
        Eigen::Vector3d n;
        const double t = IntersectObstacle(state.obstacles[it->index], origin, d, &n);
        if (t > 0.0 && t < t_obst) {
          t_obst = t;
          obst = it->index;
          obst_normal = n;
        }
      }
    }
    auto lit = [&](const Eigen::Vector3d& n) {
      return static_cast<float>(light.ambient + (1.0 - light.ambient) * std::max(0.0, n.dot(sun)));
    };
    if (plate >= 0 && t_plate <= t_ground + options.plate_tolerance && t_plate < t_obst) {
      *plate_hit = plate;
      const float a = static_cast<float>(plate_albedo) * lit(state.plates[plate].normal);
      return Rgb(a, a, a);
    }
    if (obst >= 0 && t_obst < t_ground) {
      const Eigen::Vector3d p = origin + t_obst * d;
      return scene.ObstacleAlbedo(state.obstacles[obst], p, options.epoch_salt) * lit(obst_normal);
    }
    if (hit_tri >= 0 && std::isfinite(t_ground)) {
      const Eigen::Vector3d p = origin + t_ground * d;
      Eigen::Vector3d a, b, cc;
      grid.Triangle(hit_tri, &a, &b, &cc);
      Eigen::Vector3d n = (b - a).cross(cc - a).normalized();
      if (n.z() < 0.0) n = -n;
      const double cos_inc = std::max(0.2, std::abs(n.dot(d)));
      const double footprint = t_ground * ps / c / cos_inc;
      Eigen::Vector2d xr = p.head<2>();
      if (moved) xr = reference_of(p).head<2>();
      return scene.GroundAlbedo(xr, footprint) * lit(n);
    }
    const float s = static_cast<float>(light.sky);
    return Rgb(s, s, s);
  }
};

}  // namespace

Renderer::Renderer(const Scene& scene, const camera::CameraModel& model)
    : scene_(scene), model_(model) {
  model_.Check();
  const int w = model_.sensor().width, h = model_.sensor().height;
  table_w_ = w + 2;
  table_h_ = h + 2;
  ideal_.resize(2 * static_cast<size_t>(table_w_) * table_h_);
  const double x0 = model_.interior()[camera::kX0], y0 = model_.interior()[camera::kY0];
  for (int r = 0; r < table_h_; ++r) {
    for (int c = 0; c < table_w_; ++c) {
      const Eigen::Vector2d mm = model_.PixelToMm(Eigen::Vector2d(c - 1, r - 1));
      // UndistortMm returns ideal coordinates relative to the principal point.
      Eigen::Vector2d ideal = model_.UndistortMm(mm);
      (void)x0;
      (void)y0;
      const size_t k = 2 * (static_cast<size_t>(r) * table_w_ + c);
      ideal_[k] = ideal.x();
      ideal_[k + 1] = ideal.y();
    }
  }
}

Eigen::Vector2d Renderer::IdealAt(double col, double row) const {
  const double gx = std::clamp(col + 1.0, 0.0, table_w_ - 1.000001);
  const double gy = std::clamp(row + 1.0, 0.0, table_h_ - 1.000001);
  const int ix = std::min(static_cast<int>(gx), table_w_ - 2),
            iy = std::min(static_cast<int>(gy), table_h_ - 2);
  const double fx = gx - ix, fy = gy - iy;
  const size_t k00 = 2 * (static_cast<size_t>(iy) * table_w_ + ix);
  const size_t k10 = k00 + 2, k01 = k00 + 2 * static_cast<size_t>(table_w_), k11 = k01 + 2;
  Eigen::Vector2d out;
  for (int a = 0; a < 2; ++a) {
    out[a] = (1 - fy) * ((1 - fx) * ideal_[k00 + a] + fx * ideal_[k10 + a]) +
             fy * ((1 - fx) * ideal_[k01 + a] + fx * ideal_[k11 + a]);
  }
  return out;
}

RenderResult Renderer::Render(const Scene::State& state, const camera::ExteriorOrientation& pose,
                              const RenderOptions& options) const {
  if (options.target_supersampling < 1 || options.target_supersampling > 32) {
    throw InvalidArgument(Message("render option target_supersampling = ",
                                  options.target_supersampling, " is outside [1, 32]"));
  }
  if (options.obstacle_supersampling < 1 || options.obstacle_supersampling > 16) {
    throw InvalidArgument(Message("render option obstacle_supersampling = ",
                                  options.obstacle_supersampling, " is outside [1, 16]"));
  }
  const int w = model_.sensor().width, h = model_.sensor().height;
  const double c = model_.principal_distance();
  const double ps = model_.sensor().pixel_size;
  const Eigen::Matrix3d m = camera::RotationFromAngles(pose.angles);  // cam_from_site
  const Eigen::Matrix3d site_from_cam = m.transpose();
  const Eigen::Vector3d origin = pose.position;
  const HeightGrid& grid = state.grid;
  const LandslideModel& landslide = scene_.spec().landslide;
  const LandslideModel::InverseAt reference_of(landslide, state.t);
  const bool moved = reference_of.moved();
  const Lighting& light = scene_.spec().lighting;
  const Eigen::Vector3d sun = light.sun.normalized();

  // ---- 1. project the mesh vertices -------------------------------------
  const ProjectedMesh mesh = ProjectVertices(grid, model_, m, origin);

  // ---- 2. z-buffer of triangle ids --------------------------------------
  const std::vector<int> tri = TriangleIds(grid, mesh, w, h);

  // ---- 3. image boxes of plates and obstacles ---------------------------
  const std::vector<Item> items = ImageBoxes(state, model_, pose, m, origin);

  // ---- 4. shade ----------------------------------------------------------
  const int channels = options.colour ? 3 : 1;
  RenderResult result;
  result.radiance = cv::Mat(h, w, channels == 3 ? CV_32FC3 : CV_32FC1);
  const int nthreads = std::max(1, options.threads);
  std::vector<std::vector<double>> coverage(nthreads,
                                            std::vector<double>(state.plates.size(), 0.0));

  const RayShading shading{scene_, state, options, light, sun, grid,  tri,
                           w,      h,     origin,  c,     ps,  moved, reference_of};

  auto ray_at = [&](double col, double row) {
    const Eigen::Vector2d ideal = IdealAt(col, row);
    return (site_from_cam * Eigen::Vector3d(ideal.x(), ideal.y(), -c)).normalized();
  };

  auto work = [&](int thread_index) {
    std::vector<const Item*> here;
    std::vector<double>& cov = coverage[thread_index];
    for (int r = thread_index; r < h; r += nthreads) {
      float* row_ptr = result.radiance.ptr<float>(r);
      for (int col = 0; col < w; ++col) {
        here.clear();
        bool near_plate = false, near_obstacle = false;
        for (const Item& it : items) {
          if (col >= it.c0 && col <= it.c1 && r >= it.r0 && r <= it.r1) {
            here.push_back(&it);
            (it.plate ? near_plate : near_obstacle) = true;
          }
        }
        const int n = near_plate ? options.target_supersampling
                                 : (near_obstacle ? options.obstacle_supersampling : 1);
        Rgb sum(0, 0, 0);
        int plate_hit = -1;
        if (n == 1) {
          sum = shading.Shade(ray_at(col, r), col, r, here, &plate_hit);
          if (plate_hit >= 0) cov[plate_hit] += 1.0;
        } else {
          const double w_s = 1.0 / (n * n);
          for (int sy = 0; sy < n; ++sy) {
            const double row = r - 0.5 + (sy + 0.5) / n;
            for (int sx = 0; sx < n; ++sx) {
              const double cl = col - 0.5 + (sx + 0.5) / n;
              sum += shading.Shade(ray_at(cl, row), col, r, here, &plate_hit);
              if (plate_hit >= 0) cov[plate_hit] += w_s;
            }
          }
          sum *= static_cast<float>(w_s);
        }
        if (channels == 3) {
          float* bgr = row_ptr + 3 * static_cast<ptrdiff_t>(col);
          bgr[0] = sum.z();
          bgr[1] = sum.y();
          bgr[2] = sum.x();
        } else {
          row_ptr[col] = Luma(sum);
        }
      }
    }
  };
  if (nthreads == 1) {
    work(0);
  } else {
    std::vector<std::thread> pool;
    pool.reserve(nthreads);
    for (int k = 0; k < nthreads; ++k) pool.emplace_back(work, k);
    for (auto& t : pool) t.join();
  }
  result.target_coverage.assign(state.plates.size(), 0.0);
  for (const auto& cv : coverage)
    for (size_t k = 0; k < cv.size(); ++k) result.target_coverage[k] += cv[k];
  return result;
}

cv::Mat Expose(const cv::Mat& radiance, const ExposureOptions& o, std::mt19937* rng) {
  if (radiance.depth() != CV_32F || (radiance.channels() != 1 && radiance.channels() != 3)) {
    throw InvalidArgument("Expose needs a CV_32FC1 or CV_32FC3 radiance image");
  }
  const int ch = radiance.channels();
  cv::Mat out(radiance.rows, radiance.cols, ch == 3 ? CV_8UC3 : CV_8UC1);
  const double cx = 0.5 * (radiance.cols - 1), cy = 0.5 * (radiance.rows - 1);
  const double r_corner2 = cx * cx + cy * cy;
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int r = 0; r < radiance.rows; ++r) {
    const float* in = radiance.ptr<float>(r);
    std::uint8_t* dst = out.ptr<std::uint8_t>(r);
    for (int c = 0; c < radiance.cols; ++c) {
      const double rr = ((c - cx) * (c - cx) + (r - cy) * (r - cy)) / r_corner2;
      const double vig = 1.0 - o.vignetting * rr;
      for (int k = 0; k < ch; ++k) {
        double dn = o.gain * o.exposure * vig * in[ch * c + k];
        if (o.noise) {
          const double sigma =
              std::sqrt(o.read_noise * o.read_noise + o.shot_noise * std::max(dn, 0.0));
          dn += sigma * normal(*rng);
        }
        dst[ch * c + k] = static_cast<std::uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
      }
    }
  }
  return out;
}

}  // namespace sim
}  // namespace slope_monitor
