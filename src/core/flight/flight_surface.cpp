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
#include "slope_monitor/core/io/json_text.h"
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

FlightChangeOptions::FlightChangeOptions() {
  change.coregistration_iterations = 10;  // a consumer GNSS shift of metres needs a few passes
  change.max_shift = 10.0;
  change.min_stable_cells = 100;
  // Heteroscedastic LoD: real surfaces' errors grow on steep and rough
  // ground (bushes, edges), one global residual flags them.
  // Each bin's spread from its 95 % quantile: real DoDs have heavy tails
  // (blunders of metres on 1 % of copr's cells) that the NMAD does not see
  // (copr split: 10.8 % flagged with NMAD bins, 4.1 % with quantile bins;
  // doc/real_surfaces.md).
  change.error_model.enabled = true;
  change.error_model.spread = dense::ErrorModelOptions::Spread::kQuantile;
  search_radius = 8.0;
}

FlightChange CompareFlights(const FlightChangeInput& input, const FlightChangeOptions& options) {
  return dense::CompareSurfaces(input, options);
}

void WriteSurfaceReport(const FlightSurfaceSummary& s, const FlightChangeSummary* change,
                        const std::string& reference, const std::string& json_path,
                        const std::string& md_path) {
  nlohmann::ordered_json seconds = nlohmann::ordered_json::object();
  for (const auto& [k, v] : s.seconds) seconds[k] = v;
  nlohmann::ordered_json j = {
      {"photos", s.photos},
      {"working_size_px", nlohmann::ordered_json::array({s.working_width, s.working_height})},
      {"decode_factor", s.decode_factor},
      {"ground_sample_m", s.ground_sample},
      {"cell_size_m", s.cell_size},
      {"pairs_measured", s.dense.pairs_measured},
      {"pairs_considered", s.dense.candidate_pairs},
      {"points", s.dense.points},
      {"cells", s.dense.cells},
      {"filled_cells", s.dense.filled_cells},
      {"seconds", std::move(seconds)}};
  std::ostringstream m;
  m.precision(4);
  m << "# Surface\n\n" << s.BriefReport() << "\n\n| stage | s |\n|---|---|\n";
  for (const auto& [k, v] : s.seconds) m << "| " << k << " | " << v << " |\n";
  if (!s.dense.pair_errors.empty())
    m << "\nPairs not measured (" << s.dense.pair_errors.size() << "):\n\n";
  for (const std::string& e : s.dense.pair_errors) m << "* " << e << "\n";
  if (change) {
    j["change"] = dense::ChangeReportJson(*change, reference);
    m << dense::ChangeReportMarkdown(*change, reference);
  }
  io::WriteFileAtomically(json_path, io::JsonText(j));
  io::WriteFileAtomically(md_path, m.str());
}

}  // namespace flight
}  // namespace slope_monitor
