#include "slope_monitor/core/dense/surface_products.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include <Eigen/Dense>
#include <opencv2/core.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/io/json_text.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace dense {

namespace {

// Bilinear BGR at (x, y) of a BGR or grey (the same value thrice) photo;
// false outside.
bool Bilinear(const cv::Mat& image, double x, double y, cv::Vec3f* c) {
  if (x < 0 || y < 0 || x > image.cols - 1 || y > image.rows - 1) return false;
  const int x0 = std::min(static_cast<int>(x), image.cols - 2),
            y0 = std::min(static_cast<int>(y), image.rows - 2);
  const double fx = x - x0, fy = y - y0;
  auto mix = [&](double a, double b, double d, double e) {
    return static_cast<float>((1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * d + fx * e));
  };
  if (image.channels() == 1) {
    const float g = mix(image.at<uint8_t>(y0, x0), image.at<uint8_t>(y0, x0 + 1),
                        image.at<uint8_t>(y0 + 1, x0), image.at<uint8_t>(y0 + 1, x0 + 1));
    *c = cv::Vec3f(g, g, g);
    return true;
  }
  const cv::Vec3b& a = image.at<cv::Vec3b>(y0, x0);
  const cv::Vec3b& b = image.at<cv::Vec3b>(y0, x0 + 1);
  const cv::Vec3b& d = image.at<cv::Vec3b>(y0 + 1, x0);
  const cv::Vec3b& e = image.at<cv::Vec3b>(y0 + 1, x0 + 1);
  for (int k = 0; k < 3; ++k) (*c)[k] = mix(a[k], b[k], d[k], e[k]);
  return true;
}

// Ortho cells [rows x cols] the photo can see: the DEM cells, every
// kFootprintStride-th row and column, projected into the photo; the box of
// those that land inside it, widened by the stride (any viewing direction:
// oblique photos too). Empty when none lands inside.
constexpr int kFootprintStride = 4;
cv::Rect FootprintCells(const OrientedImage& im, const io::GeoRaster& dem, int subdivision) {
  const camera::Sensor& s = im.camera.sensor();
  int r0 = dem.height, r1 = -1, c0 = dem.width, c1 = -1;
  for (int r = 0; r < dem.height; r += kFootprintStride)
    for (int c = 0; c < dem.width; c += kFootprintStride) {
      const float z = dem.At(kHeight, r, c);
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
  const double v = dem.Interpolate(kHeight, x, y);
  if (!std::isnan(v)) return v;
  int r, c;
  if (!dem.CellOf(x, y, &r, &c)) return NAN;
  const float z = dem.At(kHeight, r, c);
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
          const size_t k =
              static_cast<size_t>(r * f + i) * dem.width + static_cast<size_t>(c) * f + j;
          const float v = dem.bands[kHeight][k];
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

io::GeoRaster ColourOrthophoto(const io::GeoRaster& dem, const std::vector<OrientedImage>& photos,
                               int subdivision) {
  io::GeoRaster o(dem.width * subdivision, dem.height * subdivision, dem.origin_x, dem.origin_y,
                  dem.cell_size / subdivision);
  o.epsg = dem.epsg;
  o.srs_wkt = dem.srs_wkt;
  o.rgb = true;  // an 8-bit RGB picture with alpha in the file (io::GeoRaster::rgb)
  o.AddBand("red");
  o.AddBand("green");
  o.AddBand("blue");
  std::vector<float> best(static_cast<size_t>(o.width) * o.height,
                          std::numeric_limits<float>::infinity());
  for (const OrientedImage& im : photos) {
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

void WriteCloudPly(const std::vector<EpochPoint>& cloud, const std::string& path) {
  std::string s = Message(
      "ply\nformat binary_little_endian 1.0\ncomment slope_monitor: dense cloud, site frame\n",
      "element vertex ", cloud.size(),
      "\nproperty float x\nproperty float y\nproperty float z\nproperty float sigma_z\n"
      "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n");
  s.reserve(s.size() + cloud.size() * 19);
  for (const EpochPoint& p : cloud) {
    for (int k = 0; k < 3; ++k) PutFloat(&s, static_cast<float>(p.x_in_site[k]));
    PutFloat(&s, p.sigma_z);
    for (int k = 2; k >= 0; --k) s.push_back(static_cast<char>(p.bgr[k]));
  }
  io::WriteFileAtomically(path, s);
}

void SurfaceChangeOptions::Check() const {
  change.Check();
  RequireOption(
      "surface change", search_radius >= 0 && search_radius <= change.max_shift, "search_radius",
      Message("= ", search_radius, " m must be in [0, change.max_shift = ", change.max_shift, "]"));
  RequireOption("surface change", search_cell > 0, "search_cell",
                Message("= ", search_cell, " m must be > 0"));
}

std::string SurfaceChangeSummary::BriefReport() const {
  const Coregistration& c = dem.coregistration;
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

CoregisteredChange CompareSurfaces(const SurfaceChangeInput& in,
                                   const SurfaceChangeOptions& options) {
  options.Check();
  if (!in.reference || !in.after) throw InvalidArgument("compare surfaces: a DEM is missing");
  const io::GeoRaster& ref = *in.reference;
  const io::GeoRaster& aft = *in.after;
  if (ref.width != aft.width || ref.height != aft.height ||
      std::abs(ref.origin_x - aft.origin_x) > 1e-6 ||
      std::abs(ref.origin_y - aft.origin_y) > 1e-6 ||
      std::abs(ref.cell_size - aft.cell_size) > 1e-9)
    throw InvalidArgument(
        "compare surfaces: the DEMs are not on one grid (measure the later flight on the "
        "reference's region and cell size)");
  CoregisteredChange out;
  SurfaceChangeSummary& sum = out.summary;
  const size_t n = ref.bands[kHeight].size();
  std::vector<uint8_t> common(n, 0);
  for (size_t i = 0; i < n; ++i) {
    common[i] = !ref.IsNoData(ref.bands[kHeight][i]) && !aft.IsNoData(aft.bands[kHeight][i]);
    sum.common_cells += common[i];
  }
  const int need = options.change.min_stable_cells;
  if (sum.common_cells < need)
    throw InvalidArgument(Message("compare surfaces: no overlap with the reference: ",
                                  sum.common_cells, " cells hold a height in both surfaces; need ",
                                  need, " (min_stable_cells): nothing compared"));
  std::vector<uint8_t> mask;
  if (!in.stable.empty()) {
    // Inside any stable polygon = outside none of them.
    const std::vector<uint8_t> outside = StableMask(ref, in.stable, {}, "");
    mask.resize(n);
    int inside = 0, filled = 0;
    for (size_t i = 0; i < n; ++i) {
      mask[i] = !outside[i];
      inside += mask[i];
      filled += mask[i] && common[i];
    }
    if (inside == 0)
      throw InvalidArgument(Message("compare surfaces: ", in.stable_name,
                                    " lies outside the surface (grid x ", ref.origin_x, " .. ",
                                    ref.origin_x + ref.width * ref.cell_size, ", y ",
                                    ref.origin_y - ref.height * ref.cell_size, " .. ", ref.origin_y,
                                    " m): nothing compared"));
    if (filled < need)
      throw InvalidArgument(Message("compare surfaces: holes over the stable area: ", filled,
                                    " of ", inside, " cells of ", in.stable_name,
                                    " hold a height in both surfaces; need ", need,
                                    " (min_stable_cells): nothing compared"));
  }
  if (!in.stable_mask.empty()) {
    StableMask(ref, {}, in.stable_mask, in.stable_name);  // throws naming it for a wrong size
    if (mask.empty()) mask.assign(n, 1);
    for (size_t i = 0; i < n; ++i) mask[i] = mask[i] && in.stable_mask[i];
  }
  const std::vector<uint8_t> stable = StableMask(ref, in.moving, mask, in.stable_name);
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
  out.result = DemChange(ref, shifted, in.moving, stable, options.change);
  out.result.summary.coregistration.shift += sum.searched_shift;
  sum.dem = out.result.summary;
  const io::GeoRaster& ch = out.result.change;
  std::vector<double> dz;
  int flagged = 0, stable_flagged = 0;
  for (size_t i = 0; i < n; ++i) {
    const float v = ch.bands[kChange][i];
    if (ch.IsNoData(v)) continue;
    const bool f = ch.bands[kClass][i] != 0.0f;
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

nlohmann::ordered_json ChangeReportJson(const SurfaceChangeSummary& change,
                                        const std::string& reference) {
  const DemChangeSummary& d = change.dem;
  const Coregistration& c = d.coregistration;
  auto pair = [](double a, double b) { return nlohmann::ordered_json::array({a, b}); };
  nlohmann::ordered_json j = {
      {"reference", reference},
      {"shift_m", pair(c.shift.x(), c.shift.y())},
      {"searched_shift_m", pair(change.searched_shift.x(), change.searched_shift.y())},
      {"shift_sigma_m", pair(c.shift_sigma.x(), c.shift_sigma.y())},
      {"vertical_m", c.vertical},
      {"vertical_sigma_m", c.level_sigma},
      {"tilt", pair(c.tilt.x(), c.tilt.y())},
      {"stable_cells", c.inliers},
      {"residual_before_m", c.residual_before},
      {"residual_m", c.residual},
      {"stable_median_m", change.stable_median},
      {"stable_nmad_m", change.stable_nmad},
      {"stable_flagged", change.stable_flagged},
      {"common_cells", change.common_cells},
      {"flagged", change.flagged},
      {"gain_m3", pair(d.volume_fill, d.sigma_fill)},
      {"loss_m3", pair(d.volume_cut, d.sigma_cut)},
      {"net_m3", pair(d.volume_net, d.sigma_net)},
      {"lod_model", d.error_model.empty() ? "global" : "slope_roughness"}};
  if (!d.error_model.empty()) {
    j["holdout_flagged"] = d.holdout_flagged;
    j["holdout_cells"] = d.holdout_cells;
    j["holdout_block_m"] = d.holdout_block;
    nlohmann::ordered_json bins = nlohmann::ordered_json::array();
    for (const ErrorBin& b : d.error_model.bins)
      bins.push_back({{"slope_deg", pair(b.slope_min, b.slope_max)},
                      {"roughness_m", pair(b.roughness_min, b.roughness_max)},
                      {"cells", b.cells},
                      {"median_m", b.median},
                      {"sigma_m", b.sigma}});
    j["error_bins"] = std::move(bins);
  }
  return j;
}

std::string ChangeReportMarkdown(const SurfaceChangeSummary& change, const std::string& reference) {
  const DemChangeSummary& d = change.dem;
  std::ostringstream m;
  m.precision(4);
  m << "\n# Change against " << reference << "\n\n" << change.BriefReport() << "\n";
  if (!d.error_model.empty()) {
    m << "\n| slope [deg] | roughness [m] | stable cells | median dz [m] | sigma [m] |\n"
      << "|---|---|---|---|---|\n";
    for (const ErrorBin& b : d.error_model.bins)
      m << "| " << b.slope_min << " .. " << b.slope_max << " | " << b.roughness_min << " .. "
        << b.roughness_max << " | " << b.cells << " | " << b.median << " | " << b.sigma << " |\n";
  }
  return m.str();
}

void WriteEpochSurfaceReport(const EpochSurfaceSummary& s, const SurfaceChangeSummary* change,
                             const std::string& reference, const std::string& json_path,
                             const std::string& md_path) {
  nlohmann::ordered_json j = {{"epoch", s.epoch},
                              {"pairs_measured", s.pairs_measured},
                              {"pairs_considered", s.candidate_pairs},
                              {"points", s.points},
                              {"cells", s.cells},
                              {"filled_cells", s.filled_cells},
                              {"seconds", {{"matching", s.seconds}}}};
  std::ostringstream m;
  m.precision(4);
  m << "# Surface\n\n" << s.BriefReport() << "\n";
  if (!s.pair_errors.empty()) m << "\nPairs not measured (" << s.pair_errors.size() << "):\n\n";
  for (const std::string& e : s.pair_errors) m << "* " << e << "\n";
  if (change) {
    j["change"] = ChangeReportJson(*change, reference);
    m << ChangeReportMarkdown(*change, reference);
  }
  io::WriteFileAtomically(json_path, io::JsonText(j));
  io::WriteFileAtomically(md_path, m.str());
}

}  // namespace dense
}  // namespace slope_monitor
