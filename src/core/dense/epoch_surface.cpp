#include "slope_monitor/core/dense/epoch_surface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace dense {

namespace {

// Where a ray meets the plane z = a + b x + c y; false when parallel or behind.
bool MeetPlane(const camera::Ray& ray, const Eigen::Vector3d& plane, Eigen::Vector3d* x) {
  const Eigen::Vector3d n(-plane[1], -plane[2], 1.0);  // n . X = a
  const double denom = n.dot(ray.direction);
  if (std::abs(denom) < 1e-12) return false;
  const double t = (plane[0] - n.dot(ray.origin)) / denom;
  if (t <= 0) return false;
  *x = ray.origin + t * ray.direction;
  return true;
}

// Depth range [m] of the adjusted points in front of the camera, widened.
bool DepthRange(const OrientedImage& im, const std::vector<Eigen::Vector3d>& points, double margin,
                double* lo, double* hi) {
  const Rigid3 optical_from_site = im.pose.OpticalFromSite();
  *lo = 1e300;
  *hi = -1e300;
  for (const Eigen::Vector3d& p : points) {
    const double z = (optical_from_site * p).z();
    if (z <= 0) continue;
    *lo = std::min(*lo, z);
    *hi = std::max(*hi, z);
  }
  if (*hi <= 0) return false;
  const double span = std::max(*hi - *lo, 0.05 * *hi);
  *lo = std::max(0.05 * *lo, *lo - margin * span);
  *hi = *hi + margin * span;
  return true;
}

// Colour of the site point in the photo (nearest pixel; grey images repeat).
cv::Vec3b ColourAt(const OrientedImage& im, const Eigen::Vector3d& x) {
  Eigen::Vector2d px;
  if (!im.camera.Project(im.pose, x, &px)) return {0, 0, 0};
  const int c = static_cast<int>(std::lround(px.x())), r = static_cast<int>(std::lround(px.y()));
  if (r < 0 || c < 0 || r >= im.image.rows || c >= im.image.cols) return {0, 0, 0};
  if (im.image.type() == CV_8UC3) return im.image.at<cv::Vec3b>(r, c);
  double v = 0;
  if (im.image.type() == CV_8UC1)
    v = im.image.at<uchar>(r, c);
  else if (im.image.type() == CV_32FC1)
    v = im.image.at<float>(r, c);
  else if (im.image.type() == CV_16UC1)
    v = im.image.at<uint16_t>(r, c) / 256.0;
  const uchar g = cv::saturate_cast<uchar>(v);
  return {g, g, g};
}

void CheckMemory(const Eigen::Vector4d& region, const EpochSurfaceOptions& o) {
  if (region.isZero()) return;
  const double w = std::ceil((region[1] - region[0]) / o.surface.cell_size - 1e-9);
  const double h = std::ceil((region[3] - region[2]) / o.surface.cell_size - 1e-9);
  const double mb = w * h * (4 * 4 + 28) / 1e6;
  if (mb > o.max_dem_megabytes)
    throw InvalidArgument(Message("DEM of ", w, " x ", h, " cells (cell_size ", o.surface.cell_size,
                                  " m) needs ", mb, " MB, more than max_dem_megabytes = ",
                                  o.max_dem_megabytes, " MB: raise cell_size or the limit"));
}

}  // namespace

void EpochSurfaceOptions::Check() const {
  surface.Check();
  RequireOption("epoch surface", min_pair_overlap > 0 && min_pair_overlap <= 1, "min_pair_overlap",
                Message("= ", min_pair_overlap, " must be in (0, 1]"));
  RequireOption("epoch surface", depth_margin >= 0 && depth_margin <= 10, "depth_margin",
                Message("= ", depth_margin, " must be in [0, 10]"));
  RequireOption("epoch surface", max_pairs_per_image >= 1 && max_pairs_per_image <= 100,
                "max_pairs_per_image", Message("= ", max_pairs_per_image, " must be in [1, 100]"));
  RequireOption("epoch surface", max_dem_megabytes > 0 && max_dem_megabytes <= 1e5,
                "max_dem_megabytes", Message("= ", max_dem_megabytes, " MB must be in (0, 1e5]"));
  RequireOption("epoch surface",
                region.isZero() || (region[1] > region[0] && region[3] > region[2]), "region",
                "must be all zero or xmin < xmax, ymin < ymax");
}

std::string EpochSurfaceSummary::BriefReport() const {
  std::ostringstream s;
  s << "epoch " << epoch << " surface: " << pairs_measured << "/" << candidate_pairs
    << " pairs measured, " << points << " points, " << filled_cells << "/" << cells
    << " cells filled, " << seconds << " s";
  for (const std::string& e : pair_errors) s << "\n  skipped: " << e;
  return s.str();
}

Eigen::Vector3d GroundPlane(const std::vector<Eigen::Vector3d>& points) {
  if (points.empty()) throw InvalidArgument("GroundPlane: no adjusted points");
  if (points.size() < 3) {
    double z = 0;
    for (const auto& p : points) z += p.z();
    return Eigen::Vector3d(z / points.size(), 0, 0);
  }
  Eigen::MatrixXd a(points.size(), 3);
  Eigen::VectorXd b(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    a.row(i) << 1.0, points[i].x(), points[i].y();
    b[i] = points[i].z();
  }
  return a.colPivHouseholderQr().solve(b);
}

double FootprintOverlap(const OrientedImage& left, const OrientedImage& right,
                        const Eigen::Vector3d& plane) {
  const camera::Sensor& sl = left.camera.sensor();
  const camera::Sensor& sr = right.camera.sensor();
  int seen = 0, total = 0;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 16; ++j) {
      const Eigen::Vector2d px((j + 0.5) * sl.width / 16.0, (i + 0.5) * sl.height / 12.0);
      Eigen::Vector3d x;
      if (!MeetPlane(left.camera.ImageToRay(left.pose, px), plane, &x)) continue;
      ++total;
      Eigen::Vector2d q;
      if (right.camera.Project(right.pose, x, &q) && q.x() >= 0 && q.y() >= 0 && q.x() < sr.width &&
          q.y() < sr.height)
        ++seen;
    }
  return total > 0 ? static_cast<double>(seen) / total : 0.0;
}

std::vector<std::pair<int, int>> ChoosePairs(const EpochSurfaceInput& in,
                                             const EpochSurfaceOptions& o,
                                             const Eigen::Vector3d& plane,
                                             std::vector<std::string>* rejected) {
  std::vector<std::pair<int, int>> pairs;
  const int n = static_cast<int>(in.images.size());
  // UAV: every pair's overlap (the smaller of both directions), best partners first.
  std::vector<std::vector<std::pair<double, int>>> partners(n);
  for (int i = 0; i < n; ++i)
    for (int j = i + 1; j < n; ++j) {
      if (in.images[i].kind != ImageKind::kUav || in.images[j].kind != ImageKind::kUav) continue;
      const OrientedImage& a = in.images[i].image;
      const OrientedImage& b = in.images[j].image;
      const double ov = std::min(FootprintOverlap(a, b, plane), FootprintOverlap(b, a, plane));
      if (ov >= o.min_pair_overlap) {
        partners[i].push_back({ov, j});
      } else if (ov > 0) {
        rejected->push_back(Message("pair '", a.name, "'/'", b.name, "': footprints overlap ",
                                    100 * ov, " % < min_pair_overlap ", 100 * o.min_pair_overlap,
                                    " %"));
      }
    }
  for (int i = 0; i < n; ++i) {
    std::sort(partners[i].rbegin(), partners[i].rend());
    const int keep = std::min<int>(o.max_pairs_per_image, static_cast<int>(partners[i].size()));
    for (int k = 0; k < keep; ++k) pairs.push_back({i, partners[i][k].second});
  }
  // Fixed stereo pairs as configured.
  for (const auto& sp : in.stereo_pairs) {
    int l = -1, r = -1;
    for (int i = 0; i < n; ++i) {
      if (in.images[i].camera == sp.first) l = i;
      if (in.images[i].camera == sp.second) r = i;
    }
    if (l < 0 || r < 0) {
      rejected->push_back(Message("stereo pair '", sp.first, "'/'", sp.second, "': camera '",
                                  l < 0 ? sp.first : sp.second, "' has no image in epoch ",
                                  in.epoch));
      continue;
    }
    const double ov = FootprintOverlap(in.images[l].image, in.images[r].image, plane);
    if (ov <= 0) {
      rejected->push_back(
          Message("stereo pair '", sp.first, "'/'", sp.second, "': the images do not overlap"));
      continue;
    }
    pairs.push_back({l, r});
  }
  return pairs;
}

EpochSurfaceResult MeasureEpochSurface(const EpochSurfaceInput& in, const EpochSurfaceOptions& o,
                                       const std::function<void(const std::string&)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  o.Check();
  CheckMemory(o.region, o);
  EpochSurfaceResult result;
  EpochSurfaceSummary& sum = result.summary;
  sum.epoch = in.epoch;
  if (in.adjusted_points.empty())
    throw InvalidArgument(
        Message("epoch ", in.epoch, ": no adjusted points, so the ground cannot be placed"));
  const Eigen::Vector3d plane = GroundPlane(in.adjusted_points);
  const std::vector<std::pair<int, int>> pairs = ChoosePairs(in, o, plane, &sum.pair_errors);
  sum.candidate_pairs = static_cast<int>(pairs.size() + sum.pair_errors.size());
  std::vector<SurfacePoint> all;
  SurfaceConfig config;
  config.region = o.region;
  double per_window = 1.0;
  for (size_t k = 0; k < pairs.size(); ++k) {
    const OrientedImage& l = in.images[pairs[k].first].image;
    const OrientedImage& r = in.images[pairs[k].second].image;
    if (progress)
      progress(Message("epoch ", in.epoch, ": pair ", k + 1, "/", pairs.size(), " '", l.name, "'/'",
                       r.name, "'"));
    if (!DepthRange(l, in.adjusted_points, o.depth_margin, &config.min_depth, &config.max_depth)) {
      sum.pair_errors.push_back(Message("pair '", l.name, "'/'", r.name,
                                        "': no adjusted point in front of '", l.name, "'"));
      continue;
    }
    try {
      SurfaceSummary ps;
      SurfaceResult s = MeasureSurface(l, r, o.surface, config, &ps);
      ++sum.pairs_measured;
      const CorrelationOptions& c = o.surface.correlation;
      const int window = c.final_window > 0 ? c.final_window : c.window;
      per_window = std::max(1.0, std::pow(static_cast<double>(window) / c.final_grid_spacing, 2));
      for (const SurfacePoint& p : s.points) {
        all.push_back(p);
        result.points.push_back({p.x_in_site, p.sigma_z, ColourAt(l, p.x_in_site)});
      }
    } catch (const InvalidArgument& e) {
      sum.pair_errors.push_back(e.what());
    }
  }
  if (all.empty()) {
    std::string why;
    for (const std::string& e : sum.pair_errors) why += "; " + e;
    throw InvalidArgument(
        Message("epoch ", in.epoch, ": no surface point from ", pairs.size(), " pair(s)", why));
  }
  if (o.region.isZero()) {
    Eigen::Vector4d box(1e300, -1e300, 1e300, -1e300);
    for (const auto& p : all)
      box << std::min(box[0], p.x_in_site.x()), std::max(box[1], p.x_in_site.x()),
          std::min(box[2], p.x_in_site.y()), std::max(box[3], p.x_in_site.y());
    CheckMemory(box, o);
  }
  result.dem =
      GridSurface(all, o.surface.cell_size, o.surface.min_points_per_cell, o.region, per_window);
  sum.points = static_cast<int>(all.size());
  sum.cells = result.dem.width * result.dem.height;
  for (float v : result.dem.bands[kHeight]) sum.filled_cells += !result.dem.IsNoData(v);
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

Eigen::Vector4d RegionOf(const io::GeoRaster& dem) {
  return Eigen::Vector4d(dem.origin_x, dem.origin_x + dem.width * dem.cell_size,
                         dem.origin_y - dem.height * dem.cell_size, dem.origin_y);
}

std::string EpochFileName(const char* stem, int epoch, const char* extension) {
  char b[64];
  std::snprintf(b, sizeof b, "%s_e%02d.%s", stem, epoch, extension);
  return b;
}

std::string EpochSurfaceFileName(int epoch) { return EpochFileName("surface", epoch, "tif"); }
std::string EpochChangeFileName(int epoch) { return EpochFileName("change", epoch, "tif"); }
std::string EpochOrthoFileName(int epoch) { return EpochFileName("ortho", epoch, "tif"); }
std::string EpochCloudFileName(int epoch) { return EpochFileName("cloud", epoch, "ply"); }

}  // namespace dense
}  // namespace slope_monitor
