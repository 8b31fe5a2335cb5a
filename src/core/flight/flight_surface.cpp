#include "slope_monitor/core/flight/flight_surface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>

#include <Eigen/Dense>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/dense/surface.h"
#include "slope_monitor/core/io/image_file.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace flight {

namespace {

using Clock = std::chrono::steady_clock;

// Smallest JPEG DCT scale (1, 2, 4, 8) that brings the longer side to at most `size`.
int DecodeFactor(int width, int height, int size) {
  int f = 1;
  while (f < 8 && (std::max(width, height) + f - 1) / f > size) f *= 2;
  return f;
}

int ReducedFlag(int factor) {
  switch (factor) {
    case 2:
      return cv::IMREAD_REDUCED_COLOR_2;
    case 4:
      return cv::IMREAD_REDUCED_COLOR_4;
    case 8:
      return cv::IMREAD_REDUCED_COLOR_8;
    default:
      return cv::IMREAD_COLOR;
  }
}

// The camera model of a photo decoded at 1 / factor (same interior in mm).
camera::CameraModel Scaled(const camera::CameraModel& m, int width, int height, int factor) {
  camera::Sensor s = m.sensor();
  s.width = width;
  s.height = height;
  s.pixel_size *= factor;
  return camera::CameraModel(s, m.model(), m.interior());
}

double Percentile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const size_t i = static_cast<size_t>(std::lround(q * (v.size() - 1)));
  return v[std::min(i, v.size() - 1)];
}

// Median ground sample distance [m] of the working photos: median tie-point
// depth times pixel pitch over principal distance, median over photos.
double GroundSample(const std::vector<dense::OrientedImage>& images,
                    const adjustment::Scene& scene) {
  std::vector<double> gsd;
  for (const dense::OrientedImage& im : images) {
    const Rigid3 optical_from_site = im.pose.OpticalFromSite();
    std::vector<double> depth;
    const size_t step = std::max<size_t>(1, scene.points.size() / 500);
    for (size_t i = 0; i < scene.points.size(); i += step) {
      const double z = (optical_from_site * scene.points[i].position).z();
      if (z > 0) depth.push_back(z);
    }
    if (depth.empty()) continue;
    gsd.push_back(UpperMedian(depth) * im.camera.sensor().pixel_size /
                  im.camera.principal_distance());
  }
  if (gsd.empty())
    throw InvalidArgument("flight surface: no tie point in front of any oriented photo");
  return UpperMedian(gsd);
}

// The oriented photos, decoded at 1 / factor in colour, with scaled cameras.
std::vector<dense::OrientedImage> DecodePhotos(const FlightPhotos& photos,
                                               const FlightResult& result, int factor,
                                               std::vector<std::string>* skipped) {
  std::vector<dense::OrientedImage> out;
  for (size_t i = 0; i < result.scene.images.size(); ++i) {
    const adjustment::Image& im = result.scene.images[i];
    const FlightPhoto& p = photos.photos[result.photo_of_image[i]];
    const camera::CameraModel& model = result.scene.cameras[im.camera].model;
    cv::Mat bgr = io::ReadImageChecked(p.path, ReducedFlag(factor), photos.options.image);
    const int w = (model.sensor().width + factor - 1) / factor,
              h = (model.sensor().height + factor - 1) / factor;
    if (bgr.cols != w || bgr.rows != h) {
      skipped->push_back(Message(p.path, ": decoded at 1/", factor, " as ", bgr.cols, " x ",
                                 bgr.rows, " px, expected ", w, " x ", h,
                                 " (EXIF rotation?): left out of the surface"));
      continue;
    }
    dense::OrientedImage o;
    o.name = p.name;
    o.image = bgr;
    o.camera = Scaled(model, w, h, factor);
    o.pose = im.exterior;
    o.oriented = true;
    out.push_back(std::move(o));
  }
  return out;
}

// Bilinear BGR at (x, y); false outside.
bool Bilinear(const cv::Mat& bgr, double x, double y, cv::Vec3f* c) {
  if (x < 0 || y < 0 || x > bgr.cols - 1 || y > bgr.rows - 1) return false;
  const int x0 = std::min(static_cast<int>(x), bgr.cols - 2),
            y0 = std::min(static_cast<int>(y), bgr.rows - 2);
  const double fx = x - x0, fy = y - y0;
  const cv::Vec3b& a = bgr.at<cv::Vec3b>(y0, x0);
  const cv::Vec3b& b = bgr.at<cv::Vec3b>(y0, x0 + 1);
  const cv::Vec3b& d = bgr.at<cv::Vec3b>(y0 + 1, x0);
  const cv::Vec3b& e = bgr.at<cv::Vec3b>(y0 + 1, x0 + 1);
  for (int k = 0; k < 3; ++k)
    (*c)[k] = static_cast<float>((1 - fy) * ((1 - fx) * a[k] + fx * b[k]) +
                                 fy * ((1 - fx) * d[k] + fx * e[k]));
  return true;
}

// Ortho cells [rows x cols] the photo can see: the DEM cells, every
// kFootprintStride-th row and column, projected into the photo; the box of
// those that land inside it, widened by the stride (any viewing direction:
// oblique photos too). Empty when none lands inside.
constexpr int kFootprintStride = 4;
cv::Rect FootprintCells(const dense::OrientedImage& im, const io::GeoRaster& dem, int subdivision) {
  const camera::Sensor& s = im.camera.sensor();
  int r0 = dem.height, r1 = -1, c0 = dem.width, c1 = -1;
  for (int r = 0; r < dem.height; r += kFootprintStride)
    for (int c = 0; c < dem.width; c += kFootprintStride) {
      const float z = dem.At(dense::kHeight, r, c);
      if (dem.IsNoData(z)) continue;
      const Eigen::Vector2d xy = dem.CellCentre(r, c);
      Eigen::Vector2d px;
      if (!im.camera.Project(im.pose, Eigen::Vector3d(xy.x(), xy.y(), z), &px)) continue;
      if (px.x() < 0 || px.y() < 0 || px.x() > s.width - 1 || px.y() > s.height - 1) continue;
      r0 = std::min(r0, r), r1 = std::max(r1, r), c0 = std::min(c0, c), c1 = std::max(c1, c);
    }
  if (r1 < 0) return cv::Rect();
  r0 = std::max(0, r0 - kFootprintStride), c0 = std::max(0, c0 - kFootprintStride);
  r1 = std::min(dem.height, r1 + kFootprintStride + 1),
  c1 = std::min(dem.width, c1 + kFootprintStride + 1);
  return cv::Rect(c0 * subdivision, r0 * subdivision, (c1 - c0) * subdivision,
                  (r1 - r0) * subdivision);
}

// DEM height at (x, y): bilinear, else the cell's own (NaN in a hole).
double DemHeight(const io::GeoRaster& dem, double x, double y) {
  const double v = dem.Interpolate(dense::kHeight, x, y);
  if (!std::isnan(v)) return v;
  int r, c;
  if (!dem.CellOf(x, y, &r, &c)) return NAN;
  const float z = dem.At(dense::kHeight, r, c);
  return dem.IsNoData(z) ? NAN : z;
}

void PutFloat(std::string* s, float v) { s->append(reinterpret_cast<const char*>(&v), sizeof v); }

// Block mean of a DEM's height band over factor x factor cells (nodata where
// fewer than half the cells hold a height), and the stable flag of a block
// (any stable cell).
void Coarsen(const io::GeoRaster& dem, const std::vector<uint8_t>& stable, int f, cv::Mat* z,
             cv::Mat* st) {
  const int h = dem.height / f, w = dem.width / f;
  *z = cv::Mat(h, w, CV_32F, cv::Scalar(NAN));
  *st = cv::Mat::zeros(h, w, CV_8U);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      double sum = 0;
      int n = 0;
      for (int i = 0; i < f; ++i)
        for (int j = 0; j < f; ++j) {
          const size_t k = static_cast<size_t>(r * f + i) * dem.width + c * f + j;
          const float v = dem.bands[dense::kHeight][k];
          if (!dem.IsNoData(v)) sum += v, ++n;
          if (stable[k]) st->at<uint8_t>(r, c) = 1;
        }
      if (2 * n >= f * f) z->at<float>(r, c) = static_cast<float>(sum / n);
    }
}

// NMAD of after(r + di, c + dj) - ref(r, c) over stable cells with both,
// about the least-squares plane of dz (two flights oriented by GNSS differ by
// a tilt too); -1: fewer than `need` cells; *count: how many.
double ShiftScore(const cv::Mat& ref, const cv::Mat& aft, const cv::Mat& st, int di, int dj,
                  int need, int* count) {
  std::vector<Eigen::Vector3d> p;  // col, row, dz
  for (int r = std::max(0, -di); r < std::min(ref.rows, ref.rows - di); ++r)
    for (int c = std::max(0, -dj); c < std::min(ref.cols, ref.cols - dj); ++c) {
      if (!st.at<uint8_t>(r, c)) continue;
      const float a = ref.at<float>(r, c), b = aft.at<float>(r + di, c + dj);
      if (a == a && b == b) p.emplace_back(c, r, static_cast<double>(b) - a);
    }
  *count = static_cast<int>(p.size());
  if (*count < std::max(need, 4)) return -1;
  Eigen::Matrix3d n = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& q : p) {
    const Eigen::Vector3d a(1.0, q.x(), q.y());
    n += a * a.transpose();
    rhs += a * q.z();
  }
  const Eigen::Vector3d plane = n.ldlt().solve(rhs);
  std::vector<double> dz(p.size());
  for (size_t k = 0; k < p.size(); ++k)
    dz[k] = p[k].z() - plane[0] - plane[1] * p[k].x() - plane[2] * p[k].y();
  const double med = UpperMedian(dz);
  for (double& v : dz) v = std::abs(v - med);
  return UpperMedian(dz);
}

// Best (di, dj) within +-radius cells around (i0, j0): the smallest NMAD
// among the shifts whose overlap is at least half the largest overlap (a
// shift that leaves a few cells of smooth ground in common must not win).
cv::Point BestShift(const cv::Mat& ref, const cv::Mat& aft, const cv::Mat& st, int i0, int j0,
                    int radius, int need) {
  std::vector<std::pair<double, int>> score;
  std::vector<cv::Point> shift;
  int most = 0;
  for (int di = i0 - radius; di <= i0 + radius; ++di)
    for (int dj = j0 - radius; dj <= j0 + radius; ++dj) {
      int n = 0;
      const double s = ShiftScore(ref, aft, st, di, dj, need, &n);
      if (s < 0) continue;
      score.push_back({s, n});
      shift.emplace_back(dj, di);
      most = std::max(most, n);
    }
  cv::Point best(j0, i0);
  double best_score = 1e300;
  for (size_t k = 0; k < score.size(); ++k)
    if (2 * score[k].second >= most && score[k].first < best_score)
      best_score = score[k].first, best = shift[k];
  return best;
}

// The after DEM read at whole cells (row + di, col + dj): exact, no resampling.
io::GeoRaster ShiftCells(const io::GeoRaster& d, int di, int dj) {
  io::GeoRaster out = d;
  for (auto& b : out.bands) std::fill(b.begin(), b.end(), NAN);
  for (int r = 0; r < d.height; ++r)
    for (int c = 0; c < d.width; ++c) {
      const int rr = r + di, cc = c + dj;
      if (rr < 0 || cc < 0 || rr >= d.height || cc >= d.width) continue;
      for (int b = 0; b < d.num_bands(); ++b) out.At(b, r, c) = d.At(b, rr, cc);
    }
  return out;
}

std::string Pct(double share) {
  std::ostringstream s;
  s.precision(3);
  s << 100.0 * share;
  return s.str();
}

}  // namespace

void FlightSurfaceOptions::Check() const {
  RequireOption("flight surface", working_size >= 100 && working_size <= 100000, "working_size",
                Message("= ", working_size, " must be in [100, 100000]"));
  RequireOption("flight surface", cell_size >= 0 && std::isfinite(cell_size), "cell_size",
                Message("= ", cell_size, " m must be >= 0"));
  RequireOption("flight surface", ortho_subdivision >= 1 && ortho_subdivision <= 16,
                "ortho_subdivision", Message("= ", ortho_subdivision, " must be in [1, 16]"));
  RequireOption("flight surface", max_dem_megabytes > 0, "max_dem_megabytes",
                Message("= ", max_dem_megabytes, " MB must be > 0"));
  dense.Check();
}

std::string FlightSurfaceSummary::BriefReport() const {
  std::ostringstream s;
  s.precision(3);
  s << "surface: " << dense.filled_cells << " of " << dense.cells << " cells at " << cell_size
    << " m, " << dense.points << " points from " << dense.pairs_measured << " of "
    << dense.candidate_pairs << " pairs (" << photos << " photos at " << working_width << " x "
    << working_height << " px, ground sample " << ground_sample << " m)";
  return s.str();
}

Eigen::Vector4d TiePointRegion(const FlightResult& result, double cell) {
  std::vector<double> xs, ys;
  for (const adjustment::ObjectPoint& p : result.scene.points) {
    xs.push_back(p.position.x());
    ys.push_back(p.position.y());
  }
  if (xs.size() < 3)
    throw InvalidArgument(
        Message("flight surface: ", xs.size(), " tie points; need 3 to place the grid"));
  auto lo = [&](const std::vector<double>& v) {
    return std::floor(Percentile(v, 0.005) / cell) * cell;
  };
  auto hi = [&](const std::vector<double>& v) {
    return std::ceil(Percentile(v, 0.995) / cell) * cell;
  };
  Eigen::Vector4d r(lo(xs), hi(xs), lo(ys), hi(ys));
  if (r[1] <= r[0]) r[1] = r[0] + cell;
  if (r[3] <= r[2]) r[3] = r[2] + cell;
  return r;
}

io::GeoRaster ColourOrthophoto(const io::GeoRaster& dem,
                               const std::vector<dense::OrientedImage>& photos, int subdivision) {
  io::GeoRaster o(dem.width * subdivision, dem.height * subdivision, dem.origin_x, dem.origin_y,
                  dem.cell_size / subdivision);
  o.epsg = dem.epsg;
  o.srs_wkt = dem.srs_wkt;
  o.AddBand("red");
  o.AddBand("green");
  o.AddBand("blue");
  std::vector<float> best(static_cast<size_t>(o.width) * o.height,
                          std::numeric_limits<float>::infinity());
  for (const dense::OrientedImage& im : photos) {
    const cv::Rect cells = FootprintCells(im, dem, subdivision);
    const camera::Sensor& s = im.camera.sensor();
    const Eigen::Vector2d centre = im.camera.MmToPixel(Eigen::Vector2d::Zero());
    const double scale = 1.0 / (s.width * s.width + s.height * s.height);
    for (int r = cells.y; r < cells.y + cells.height; ++r)
      for (int c = cells.x; c < cells.x + cells.width; ++c) {
        const Eigen::Vector2d xy = o.CellCentre(r, c);
        const double z = DemHeight(dem, xy.x(), xy.y());
        if (std::isnan(z)) continue;
        Eigen::Vector2d px;
        if (!im.camera.Project(im.pose, Eigen::Vector3d(xy.x(), xy.y(), z), &px)) continue;
        const float score = static_cast<float>((px - centre).squaredNorm() * scale);
        const size_t i = static_cast<size_t>(r) * o.width + c;
        if (score >= best[i]) continue;
        cv::Vec3f bgr;
        if (!Bilinear(im.image, px.x(), px.y(), &bgr)) continue;
        best[i] = score;
        for (int k = 0; k < 3; ++k) o.bands[k][i] = bgr[2 - k];
      }
  }
  return o;
}

FlightSurface MeasureFlightSurface(const FlightPhotos& photos, const FlightResult& result,
                                   const FlightSurfaceOptions& options,
                                   const Eigen::Vector4d& region,
                                   const std::function<void(const std::string&)>& progress) {
  options.Check();
  if (result.scene.images.empty() || result.scene.cameras.empty())
    throw InvalidArgument("flight surface: no oriented photo");
  FlightSurface out;
  FlightSurfaceSummary& sum = out.summary;
  auto t0 = Clock::now();
  const camera::Sensor& full = result.scene.cameras.front().model.sensor();
  sum.decode_factor = DecodeFactor(full.width, full.height, options.working_size);
  std::vector<std::string> skipped;
  std::vector<dense::OrientedImage> images =
      DecodePhotos(photos, result, sum.decode_factor, &skipped);
  if (images.size() < 2)
    throw InvalidArgument(Message("flight surface: ", images.size(), " photo(s) usable; need 2"));
  sum.photos = static_cast<int>(images.size());
  sum.working_width = images.front().image.cols;
  sum.working_height = images.front().image.rows;
  sum.ground_sample = GroundSample(images, result.scene);
  sum.seconds["decode"] = SecondsSince(t0);

  dense::EpochSurfaceOptions d = options.dense;
  const int spacing = d.surface.correlation.final_grid_spacing;
  const double cell = options.cell_size > 0
                          ? options.cell_size
                          : std::ceil(spacing * sum.ground_sample * 100.0 - 1e-9) / 100.0;
  sum.cell_size = cell;
  d.surface.cell_size = cell;
  d.max_dem_megabytes = options.max_dem_megabytes;
  d.region = region.isZero() ? TiePointRegion(result, cell) : region;
  dense::EpochSurfaceInput in;
  in.epoch = 1;
  for (auto& im : images) in.images.push_back({im, dense::ImageKind::kUav, "uav"});
  for (const adjustment::ObjectPoint& p : result.scene.points)
    in.adjusted_points.push_back(p.position);
  t0 = Clock::now();
  dense::EpochSurfaceResult s = dense::MeasureEpochSurface(in, d, progress);
  for (const std::string& k : skipped) s.summary.pair_errors.push_back(k);
  sum.dense = s.summary;
  sum.seconds["matching"] = SecondsSince(t0);
  in.images.clear();
  t0 = Clock::now();
  out.ortho = ColourOrthophoto(s.dem, images, options.ortho_subdivision);
  sum.seconds["ortho"] = SecondsSince(t0);
  out.dem = std::move(s.dem);
  out.cloud = std::move(s.points);
  return out;
}

io::GeoRaster InCrs(const io::GeoRaster& raster, const FlightFrame& frame) {
  io::GeoRaster r = raster;
  if (frame.crs.empty()) return r;
  r.origin_x += frame.origin.x();
  r.origin_y += frame.origin.y();
  const int h = r.BandIndex("height");
  if (h >= 0 && frame.origin.z() != 0.0)
    for (float& v : r.bands[h])
      if (!r.IsNoData(v)) v = static_cast<float>(v + frame.origin.z());
  if (frame.crs.rfind("EPSG:", 0) == 0) {
    r.epsg = std::atoi(frame.crs.c_str() + 5);
    r.srs_wkt.clear();
  } else {
    r.srs_wkt = frame.wkt;
  }
  return r;
}

io::GeoRaster InSite(const io::GeoRaster& raster, const FlightFrame& frame,
                     const std::string& what) {
  const int want = frame.crs.rfind("EPSG:", 0) == 0 ? std::atoi(frame.crs.c_str() + 5) : 0;
  if (frame.crs.empty() != (raster.epsg == 0 && raster.srs_wkt.empty()) ||
      (want > 0 && raster.epsg != want))
    throw InvalidArgument(Message(
        what, ": its CRS (", raster.epsg > 0 ? Message("EPSG:", raster.epsg) : "none or not EPSG",
        ") is not this run's (", frame.crs.empty() ? "model frame" : frame.crs,
        "): the flights cannot be compared"));
  io::GeoRaster r = raster;
  r.origin_x -= frame.origin.x();
  r.origin_y -= frame.origin.y();
  const int h = r.BandIndex("height");
  if (h >= 0 && frame.origin.z() != 0.0)
    for (float& v : r.bands[h])
      if (!r.IsNoData(v)) v = static_cast<float>(v - frame.origin.z());
  r.epsg = 0;
  r.srs_wkt.clear();
  return r;
}

void WriteCloudPly(const std::vector<dense::EpochPoint>& cloud, const std::string& path) {
  std::string s = Message(
      "ply\nformat binary_little_endian 1.0\ncomment slope_monitor: dense cloud, site frame\n",
      "element vertex ", cloud.size(),
      "\nproperty float x\nproperty float y\nproperty float z\nproperty float sigma_z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n");
  s.reserve(s.size() + cloud.size() * 19);
  for (const dense::EpochPoint& p : cloud) {
    for (int k = 0; k < 3; ++k) PutFloat(&s, static_cast<float>(p.x_in_site[k]));
    PutFloat(&s, p.sigma_z);
    for (int k = 2; k >= 0; --k) s.push_back(static_cast<char>(p.bgr[k]));
  }
  io::WriteFileAtomically(path, s);
}

void FlightChangeOptions::Check() const {
  change.Check();
  RequireOption(
      "flight change", search_radius >= 0 && search_radius <= change.max_shift, "search_radius",
      Message("= ", search_radius, " m must be in [0, change.max_shift = ", change.max_shift, "]"));
  RequireOption("flight change", search_cell > 0, "search_cell",
                Message("= ", search_cell, " m must be > 0"));
}

std::string FlightChangeSummary::BriefReport() const {
  const dense::Coregistration& c = dem.coregistration;
  std::ostringstream s;
  s.precision(3);
  s << "co-registration (search " << searched_shift.x() << ", " << searched_shift.y()
    << " m) shift (" << c.shift.x() << " +- " << c.shift_sigma.x() << ", " << c.shift.y() << " +- "
    << c.shift_sigma.y() << ") m, vertical " << c.vertical << " +- " << c.level_sigma << " m on "
    << c.inliers << " stable cells; stable median dz " << stable_median << " m, NMAD "
    << stable_nmad << " m, flagged " << Pct(stable_flagged) << " % of stable, " << Pct(flagged)
    << " % of " << common_cells << " common cells";
  if (!dem.error_model.empty())
    s << " (LoD by slope x roughness, " << dem.error_model.bins.size()
      << " bins; held-out stable cells flagged " << Pct(dem.holdout_flagged) << " % of "
      << dem.holdout_cells << ")";
  s << "; gain " << dem.volume_fill << " +- " << dem.sigma_fill << " m3, loss " << dem.volume_cut
    << " +- " << dem.sigma_cut << " m3";
  return s.str();
}

FlightChange CompareFlights(const FlightChangeInput& in, const FlightChangeOptions& options) {
  options.Check();
  if (!in.reference || !in.after) throw InvalidArgument("compare flights: a DEM is missing");
  const io::GeoRaster& ref = *in.reference;
  const io::GeoRaster& aft = *in.after;
  if (ref.width != aft.width || ref.height != aft.height ||
      std::abs(ref.origin_x - aft.origin_x) > 1e-6 ||
      std::abs(ref.origin_y - aft.origin_y) > 1e-6 ||
      std::abs(ref.cell_size - aft.cell_size) > 1e-9)
    throw InvalidArgument(
        "compare flights: the DEMs are not on one grid (measure the later flight on the "
        "reference's region and cell size)");
  FlightChange out;
  FlightChangeSummary& sum = out.summary;
  const size_t n = ref.bands[dense::kHeight].size();
  std::vector<uint8_t> common(n, 0);
  for (size_t i = 0; i < n; ++i) {
    common[i] =
        !ref.IsNoData(ref.bands[dense::kHeight][i]) && !aft.IsNoData(aft.bands[dense::kHeight][i]);
    sum.common_cells += common[i];
  }
  const int need = options.change.min_stable_cells;
  if (sum.common_cells < need)
    throw InvalidArgument(Message("compare flights: no overlap with the reference: ",
                                  sum.common_cells, " cells hold a height in both surfaces; need ",
                                  need, " (min_stable_cells): nothing compared"));
  std::vector<uint8_t> mask;
  if (!in.stable.empty()) {
    // Inside any stable polygon = outside none of them.
    const std::vector<uint8_t> outside = dense::StableMask(ref, in.stable, {}, "");
    mask.resize(n);
    int inside = 0, filled = 0;
    for (size_t i = 0; i < n; ++i) {
      mask[i] = !outside[i];
      inside += mask[i];
      filled += mask[i] && common[i];
    }
    if (inside == 0)
      throw InvalidArgument(Message("compare flights: ", in.stable_name,
                                    " lies outside the surface (grid x ", ref.origin_x, " .. ",
                                    ref.origin_x + ref.width * ref.cell_size, ", y ",
                                    ref.origin_y - ref.height * ref.cell_size, " .. ", ref.origin_y,
                                    " m): nothing compared"));
    if (filled < need)
      throw InvalidArgument(Message("compare flights: holes over the stable area: ", filled, " of ",
                                    inside, " cells of ", in.stable_name,
                                    " hold a height in both surfaces; need ", need,
                                    " (min_stable_cells): nothing compared"));
  }
  const std::vector<uint8_t> stable = dense::StableMask(ref, in.moving, mask, in.stable_name);
  cv::Point cells(0, 0);
  if (options.search_radius > 0) {
    const int f = std::max(2, static_cast<int>(std::lround(options.search_cell / ref.cell_size)));
    cv::Mat zr, za, st, unused;
    Coarsen(ref, stable, f, &zr, &st);
    Coarsen(aft, stable, f, &za, &unused);
    const int coarse_need = std::max(4, need / (f * f));
    const cv::Point coarse = BestShift(
        zr, za, st, 0, 0, static_cast<int>(std::ceil(options.search_radius / (f * ref.cell_size))),
        coarse_need);
    cv::Mat fr, fa, fs;
    Coarsen(ref, stable, 1, &fr, &fs);
    Coarsen(aft, stable, 1, &fa, &unused);
    cells = BestShift(fr, fa, fs, coarse.y * f, coarse.x * f, f, options.change.min_stable_cells);
  }
  sum.searched_shift = Eigen::Vector2d(cells.x * ref.cell_size, -cells.y * ref.cell_size);
  const io::GeoRaster shifted = cells == cv::Point(0, 0) ? aft : ShiftCells(aft, cells.y, cells.x);
  out.result = dense::DemChange(ref, shifted, in.moving, stable, options.change);
  out.result.summary.coregistration.shift += sum.searched_shift;
  sum.dem = out.result.summary;
  const io::GeoRaster& ch = out.result.change;
  std::vector<double> dz;
  int flagged = 0, stable_flagged = 0;
  for (size_t i = 0; i < n; ++i) {
    const float v = ch.bands[dense::kChange][i];
    if (ch.IsNoData(v)) continue;
    const bool f = ch.bands[dense::kClass][i] != 0.0f;
    flagged += f;
    if (!stable[i]) continue;
    dz.push_back(v);
    stable_flagged += f;
  }
  const int compared = sum.dem.cells_compared;
  sum.flagged = compared > 0 ? static_cast<double>(flagged) / compared : 0.0;
  sum.stable_common = static_cast<int>(dz.size());
  if (!dz.empty()) {
    sum.stable_median = UpperMedian(dz);
    std::vector<double> dev(dz.size());
    for (size_t i = 0; i < dz.size(); ++i) dev[i] = std::abs(dz[i] - sum.stable_median);
    sum.stable_nmad = 1.4826 * UpperMedian(dev);
    sum.stable_flagged = static_cast<double>(stable_flagged) / dz.size();
  }
  return out;
}

void WriteSurfaceReport(const FlightSurfaceSummary& s, const FlightChangeSummary* change,
                        const std::string& reference, const std::string& json_path,
                        const std::string& md_path) {
  std::ostringstream j, m;
  j.precision(6);
  m.precision(4);
  j << "{\n  \"photos\": " << s.photos << ",\n  \"working_size_px\": [" << s.working_width << ", "
    << s.working_height << "],\n  \"decode_factor\": " << s.decode_factor
    << ",\n  \"ground_sample_m\": " << s.ground_sample << ",\n  \"cell_size_m\": " << s.cell_size
    << ",\n  \"pairs_measured\": " << s.dense.pairs_measured
    << ",\n  \"pairs_considered\": " << s.dense.candidate_pairs
    << ",\n  \"points\": " << s.dense.points << ",\n  \"cells\": " << s.dense.cells
    << ",\n  \"filled_cells\": " << s.dense.filled_cells << ",\n  \"seconds\": {";
  m << "# Surface\n\n" << s.BriefReport() << "\n\n| stage | s |\n|---|---|\n";
  bool first = true;
  for (const auto& [k, v] : s.seconds) {
    j << (first ? "" : ", ") << "\"" << k << "\": " << v;
    m << "| " << k << " | " << v << " |\n";
    first = false;
  }
  j << "}";
  if (!s.dense.pair_errors.empty())
    m << "\nPairs not measured (" << s.dense.pair_errors.size() << "):\n\n";
  for (const std::string& e : s.dense.pair_errors) m << "* " << e << "\n";
  if (change) {
    const dense::DemChangeSummary& d = change->dem;
    const dense::Coregistration& c = d.coregistration;
    m << "\n# Change against " << reference << "\n\n" << change->BriefReport() << "\n";
    j << ",\n  \"change\": {\"reference\": \"" << reference << "\", \"shift_m\": [" << c.shift.x()
      << ", " << c.shift.y() << "], \"searched_shift_m\": [" << change->searched_shift.x() << ", "
      << change->searched_shift.y() << "], \"shift_sigma_m\": [" << c.shift_sigma.x() << ", "
      << c.shift_sigma.y() << "], \"vertical_m\": " << c.vertical
      << ", \"vertical_sigma_m\": " << c.level_sigma << ", \"tilt\": [" << c.tilt.x() << ", "
      << c.tilt.y() << "], \"stable_cells\": " << c.inliers
      << ", \"residual_before_m\": " << c.residual_before << ", \"residual_m\": " << c.residual
      << ", \"stable_median_m\": " << change->stable_median
      << ", \"stable_nmad_m\": " << change->stable_nmad
      << ", \"stable_flagged\": " << change->stable_flagged
      << ", \"common_cells\": " << change->common_cells << ", \"flagged\": " << change->flagged
      << ", \"gain_m3\": [" << d.volume_fill << ", " << d.sigma_fill << "], \"loss_m3\": ["
      << d.volume_cut << ", " << d.sigma_cut << "], \"net_m3\": [" << d.volume_net << ", "
      << d.sigma_net << "], \"lod_model\": \""
      << (d.error_model.empty() ? "global" : "slope_roughness") << "\"";
    if (!d.error_model.empty()) {
      j << ", \"holdout_flagged\": " << d.holdout_flagged
        << ", \"holdout_cells\": " << d.holdout_cells
        << ", \"holdout_block_m\": " << d.holdout_block << ", \"error_bins\": [";
      for (size_t i = 0; i < d.error_model.bins.size(); ++i) {
        const dense::ErrorBin& b = d.error_model.bins[i];
        j << (i ? ", " : "") << "{\"slope_deg\": [" << b.slope_min << ", " << b.slope_max
          << "], \"roughness_m\": [" << b.roughness_min << ", " << b.roughness_max
          << "], \"cells\": " << b.cells << ", \"median_m\": " << b.median
          << ", \"sigma_m\": " << b.sigma << "}";
      }
      j << "]";
      m << "\n| slope [deg] | roughness [m] | stable cells | median dz [m] | sigma [m] |\n"
        << "|---|---|---|---|---|\n";
      for (const dense::ErrorBin& b : d.error_model.bins)
        m << "| " << b.slope_min << " .. " << b.slope_max << " | " << b.roughness_min << " .. "
          << b.roughness_max << " | " << b.cells << " | " << b.median << " | " << b.sigma << " |\n";
    }
    j << "}";
  }
  j << "\n}\n";
  io::WriteFileAtomically(json_path, j.str());
  io::WriteFileAtomically(md_path, m.str());
}

}  // namespace flight
}  // namespace slope_monitor
