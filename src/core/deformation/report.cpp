#include "slope_monitor/core/deformation/report.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <sstream>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/deformation/units.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/map_raster.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace deformation {
namespace {

std::string JsonEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof(buf), "\\u%04x", c);
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out;
}

std::string Num(double v, int digits = 6) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream o;
  o << std::setprecision(digits) << std::fixed << v;
  std::string s = o.str();
  if (s.find('.') != std::string::npos) {
    while (!s.empty() && s.back() == '0') s.pop_back();
    if (!s.empty() && s.back() == '.') s.pop_back();
  }
  return s == "-0" ? "0" : s;
}

std::string SourcesText(const PointState& p) {
  std::string s;
  for (Source src : p.sources) s += (s.empty() ? "" : "+") + SourceName(src);
  return s;
}

cv::Scalar AlertColour(AlertLevel a) {  // BGR
  switch (a) {
    case AlertLevel::kWatch:
      return cv::Scalar(0, 200, 255);  // amber
    case AlertLevel::kWarning:
      return cv::Scalar(0, 120, 255);  // orange
    case AlertLevel::kAlarm:
      return cv::Scalar(0, 0, 230);  // red
    default:
      return cv::Scalar(60, 160, 40);  // green
  }
}

void WriteImage(const std::string& path, const cv::Mat& image) {
  std::vector<uchar> png;
  try {
    if (!cv::imencode(".png", image, png)) throw IoError(Message("cannot encode PNG '", path, "'"));
  } catch (const cv::Exception& e) {
    throw IoError(Message("cannot encode PNG '", path, "': ", e.what()));
  }
  io::WriteFileAtomically(path, std::string(png.begin(), png.end()));
}

// A file name part for a point id: [A-Za-z0-9_-] kept, the rest '_'. An id
// longer than io::kMaxIdLength (refused at the message boundary, but perhaps
// stored by an older version) is cut and made unique by an FNV-1a hash.
std::string FileNamePart(const std::string& id) {
  std::string safe = id;
  for (char& c : safe)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
  if (safe.size() <= io::kMaxIdLength) return safe;
  uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : id) hash = (hash ^ c) * 1099511628211ull;
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(hash));
  return safe.substr(0, io::kMaxIdLength - 17) + "_" + hex;
}

// A "nice" number near x (1, 2, 5 x 10^n).
double Nice(double x) {
  if (!(x > 0)) return 1.0;
  const double e = std::pow(10.0, std::floor(std::log10(x)));
  const double f = x / e;
  return (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0) * e;
}

void Text(cv::Mat& img, const std::string& s, cv::Point p, double scale = 0.5,
          const cv::Scalar& c = cv::Scalar(0, 0, 0), int thick = 1) {
  cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, c, thick, cv::LINE_AA);
}

}  // namespace

std::optional<SiteCrs> ReportSiteCrs(const ReportOptions& options) {
  if (options.site_crs) return SiteCrs(*options.site_crs);
  if (!options.geodetic_origin) return std::nullopt;
  const Eigen::Vector3d& g = *options.geodetic_origin;
  return SiteCrs::LocalEnuAtWgs84(g(0), g(1), g(2));
}

void ReportOptions::Check() const {
  if (!(grid_resolution > 0.0))
    throw ConfigError(Message("report grid_resolution = ", grid_resolution, " m must be > 0"));
  if (!(grid_margin >= 0.0))
    throw ConfigError(Message("report grid_margin = ", grid_margin, " m must be >= 0"));
  if (!(idw_power > 0.0))
    throw ConfigError(Message("report idw_power = ", idw_power, " must be > 0"));
  if (!(idw_radius > 0.0))
    throw ConfigError(Message("report idw_radius = ", idw_radius, " m must be > 0"));
  if (map_width < 200 || map_width > 8000)
    throw ConfigError(Message("report map_width = ", map_width, " px must be in [200, 8000]"));
  if (series_width < 200 || series_height < 150)
    throw ConfigError(
        Message("report series size ", series_width, "x", series_height, " px is too small"));
  if (!(arrow_scale >= 0.0))
    throw ConfigError(Message("report arrow_scale = ", arrow_scale, " must be >= 0"));
}

Eigen::Vector3d SiteToGeodetic(const Eigen::Vector3d& enu, const Eigen::Vector3d& origin) {
  return SiteCrs::LocalEnuAtWgs84(origin(0), origin(1), origin(2)).Wgs84FromSite(enu);
}

std::string WriteCsv(const Snapshot& s, const std::string& path) {
  return WriteCsv(s, path, ReportOptions());
}

std::string WriteCsv(const Snapshot& s, const std::string& path, const ReportOptions& options) {
  const std::optional<SiteCrs> site = ReportSiteCrs(options);
  std::ostringstream o;
  // reference_epoch, reference_time_utc: what every displacement is measured from.
  o << "id,x,y,z,lon,lat,h,time_utc,reference_epoch,reference_time_utc,dx_mm,dy_mm,dz_mm,d_mm,"
       "sigma_dx_mm,sigma_dy_mm,sigma_dz_mm,vx_"
       "mm_per_day,"
       "vy_mm_per_day,vz_mm_per_day,speed_mm_per_day,sigma_speed_mm_per_day,alert,forecast_valid,"
       "forecast_failure_time_utc,forecast_sigma_h,forecast_window_h,sources,sources_disagree,"
       "reason\n";
  for (const PointState& p : s.points) {
    o << CsvQuote(p.id) << ',' << Num(p.reference_position.x(), 4) << ','
      << Num(p.reference_position.y(), 4) << ',' << Num(p.reference_position.z(), 4);
    if (site) {
      const Eigen::Vector3d g = site->Wgs84FromSite(p.reference_position);
      o << ',' << Num(g.x(), 9) << ',' << Num(g.y(), 9) << ',' << Num(g.z(), 4);
    } else {
      o << ",,,";
    }
    o << ',' << Utc(s.stamp) << ',' << s.reference_epoch << ','
      << (s.has_reference ? Utc(s.reference_stamp) : "");
    for (int k = 0; k < 3; ++k) o << ',' << Num(p.displacement(k) * 1e3, 3);
    o << ',' << Num(p.displacement.norm() * 1e3, 3);
    for (int k = 0; k < 3; ++k)
      o << ',' << Num(std::sqrt(p.displacement_covariance(k, k)) * 1e3, 3);
    for (int k = 0; k < 3; ++k) o << ',' << Num(p.velocity(k) * kMmPerDay, 3);
    o << ',' << Num(p.speed * kMmPerDay, 3) << ',' << Num(p.speed_sigma * kMmPerDay, 3) << ','
      << AlertName(p.alert) << ',' << (p.forecast.valid ? 1 : 0) << ','
      << (p.forecast.valid ? Utc(p.forecast.failure_time) : "") << ','
      << (p.forecast.valid ? Num(p.forecast.sigma / 3600.0, 2) : "") << ','
      << (p.forecast.valid ? Num(p.forecast.window / 3600.0, 2) : "") << ',' << SourcesText(p)
      << ',' << (p.sources_disagree ? 1 : 0) << ',' << CsvQuote(p.alert_reason) << '\n';
  }
  io::WriteFileAtomically(path, o.str());
  return path;
}

namespace {

// RFC 7946 GeoJSON is WGS 84 longitude, latitude: a site without a georeference has none.
SiteCrs GeoJsonSite(const ReportOptions& options, const std::string& path) {
  std::optional<SiteCrs> site = ReportSiteCrs(options);
  if (!site)
    throw InvalidArgument(Message("GeoJSON '", path,
                                  "': the site has no georeference (a site file, or the "
                                  "estimator's geodetic_origin) and GeoJSON is WGS 84 (RFC 7946)"));
  return std::move(*site);
}

// A FeatureCollection of `features` (each "{...}"), nothing else.
void WriteCollection(const std::vector<std::string>& features, const std::string& path) {
  std::string o = "{\n  \"type\": \"FeatureCollection\",\n  \"features\": [";
  for (size_t i = 0; i < features.size(); ++i)
    o += (i ? "," : "") + std::string("\n    ") + features[i];
  o += "\n  ]\n}\n";
  io::WriteFileAtomically(path, o);
}

}  // namespace

std::string WriteGeoJson(const Snapshot& s, const std::string& path, const ReportOptions& options) {
  const SiteCrs site = GeoJsonSite(options, path);
  std::vector<std::string> features;
  for (const PointState& p : s.points) {
    const Eigen::Vector3d c = site.Wgs84FromSite(p.reference_position);
    // Flat properties: one number or word each (no lists, no nested objects).
    std::ostringstream o;
    o << "{\"type\": \"Feature\", \"geometry\": {\"type\": \"Point\", \"coordinates\": ["
      << Num(c(0), 9) << ", " << Num(c(1), 9) << ", " << Num(c(2), 4)
      << "]},\n     \"properties\": {"
      << "\"id\": \"" << JsonEscape(p.id) << "\", \"time_utc\": \"" << Utc(s.stamp)
      << "\", \"reference_epoch\": " << s.reference_epoch;
    const char* axes = "xyz";
    for (int k = 0; k < 3; ++k)
      o << ", \"d" << axes[k] << "_mm\": " << Num(p.displacement(k) * 1e3, 3);
    o << ", \"d_mm\": " << Num(p.displacement.norm() * 1e3, 3);
    for (int k = 0; k < 3; ++k)
      o << ", \"sigma_d" << axes[k]
        << "_mm\": " << Num(std::sqrt(p.displacement_covariance(k, k)) * 1e3, 3);
    for (int k = 0; k < 3; ++k)
      o << ", \"v" << axes[k] << "_mm_per_day\": " << Num(p.velocity(k) * kMmPerDay, 3);
    o << ", \"speed_mm_per_day\": " << Num(p.speed * kMmPerDay, 3)
      << ", \"sigma_speed_mm_per_day\": " << Num(p.speed_sigma * kMmPerDay, 3) << ", \"alert\": \""
      << AlertName(p.alert) << "\", \"alert_level\": " << static_cast<int>(p.alert)
      << ", \"alert_reason\": \"" << JsonEscape(p.alert_reason) << "\", \"sources\": \""
      << SourcesText(p) << "\", \"sources_disagree\": " << (p.sources_disagree ? 1 : 0)
      << ", \"forecast_valid\": " << (p.forecast.valid ? 1 : 0);
    if (p.forecast.valid) {
      o << ", \"forecast_failure_time_utc\": \"" << Utc(p.forecast.failure_time)
        << "\", \"forecast_sigma_h\": " << Num(p.forecast.sigma / 3600.0, 2)
        << ", \"forecast_window_h\": " << Num(p.forecast.window / 3600.0, 2)
        << ", \"forecast_alpha\": " << Num(p.forecast.alpha, 2);
    } else {
      o << ", \"forecast_reason\": \"" << JsonEscape(p.forecast.reason) << "\"";
    }
    o << "}}";
    features.push_back(o.str());
  }
  WriteCollection(features, path);
  return path;
}

std::string WriteAreasGeoJson(const Snapshot& s, const std::string& path,
                              const ReportOptions& options) {
  const SiteCrs site = GeoJsonSite(options, path);
  std::vector<std::string> features;
  for (const AreaState& a : s.areas) {
    std::ostringstream o;
    // RFC 7946: exterior ring counter-clockwise, holes clockwise, each closed.
    const auto ring = [&](std::vector<Eigen::Vector2d> pts, bool exterior) {
      double twice_area = 0.0;
      for (size_t k = 0; k < pts.size(); ++k) {
        const Eigen::Vector2d &u = pts[k], &v = pts[(k + 1) % pts.size()];
        twice_area += u.x() * v.y() - v.x() * u.y();
      }
      if ((twice_area > 0.0) != exterior) std::reverse(pts.begin(), pts.end());
      o << "[";
      for (size_t k = 0; k <= pts.size(); ++k) {  // closed: the first vertex again
        const Eigen::Vector2d& v = pts[k % pts.size()];
        const Eigen::Vector3d c = site.Wgs84FromSite(Eigen::Vector3d(v.x(), v.y(), 0.0));
        o << (k ? ", " : "") << "[" << Num(c(0), 9) << ", " << Num(c(1), 9) << "]";
      }
      o << "]";
    };
    o << "{\"type\": \"Feature\", \"geometry\": {\"type\": \"Polygon\", \"coordinates\": [";
    ring(a.area.outline, true);
    for (const auto& h : a.area.holes) {
      o << ", ";
      ring(h, false);
    }
    o << "]},\n     \"properties\": {\"id\": \"" << JsonEscape(a.id)
      << "\", \"kind\": \"change_area\", \"source\": \"surface\""
      << ", \"epoch\": " << a.epoch << ", \"time_utc\": \"" << Utc(a.stamp)
      << "\", \"sign\": " << a.area.sign << ", \"area_m2\": " << Num(a.area.area, 2)
      << ", \"volume_m3\": " << Num(a.area.volume, 3)
      << ", \"mean_change_m\": " << Num(a.area.mean_change, 3)
      << ", \"max_change_m\": " << Num(a.area.max_change, 3)
      << ", \"growth_m2\": " << Num(a.growth, 2) << ", \"alert\": \"" << AlertName(a.alert)
      << "\", \"alert_level\": " << static_cast<int>(a.alert) << ", \"alert_reason\": \""
      << JsonEscape(a.reason) << "\"}}";
    features.push_back(o.str());
  }
  WriteCollection(features, path);
  return path;
}

std::string WriteDisplacementGeoTiff(const Snapshot& s, const std::string& path,
                                     const ReportOptions& options) {
  if (s.points.empty())
    throw InvalidArgument(Message("no points to interpolate for GeoTIFF '", path, "'"));
  // The grid is north-up in the map CRS (SiteCrs::MapFromSite: a shifted CRS
  // itself, or the UTM zone of a local_enu site's origin; the site frame
  // without a georeference); every cell centre is taken to the site frame by
  // PROJ and the field interpolated there, so nothing is resampled.
  const std::optional<SiteCrs> site = ReportSiteCrs(options);
  const auto to_map = [&site](const Eigen::Vector3d& x) { return site ? site->MapFromSite(x) : x; };
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  std::vector<cv::Point2f> xy, hull;  // map x, y relative to the grid's corner
  std::vector<Eigen::Vector2d> in_map;
  for (const PointState& p : s.points) {
    in_map.push_back(to_map(p.reference_position).head<2>());
    lo = lo.cwiseMin(in_map.back());
    hi = hi.cwiseMax(in_map.back());
  }
  const double cell = options.grid_resolution;
  const double x0 = std::floor((lo.x() - options.grid_margin) / cell) * cell;
  const double y1 = std::ceil((hi.y() + options.grid_margin) / cell) * cell;
  const int width = static_cast<int>(std::ceil((hi.x() + options.grid_margin - x0) / cell));
  const int height = static_cast<int>(std::ceil((y1 - (lo.y() - options.grid_margin)) / cell));
  if (static_cast<double>(width) * height > 5e7)
    throw InvalidArgument(Message("GeoTIFF '", path, "' would have ", width, " x ", height,
                                  " cells; increase grid_resolution"));
  // nodata NaN, the band's nodata value, as in every GeoTIFF of the package (io::GeoRaster)
  io::GeoRaster r(std::max(1, width), std::max(1, height), x0, y1, cell);
  if (site) io::SetMapCrs(&r, *site);
  // Cells farther than grid_margin outside the points' convex hull stay nodata
  // (float precision: coordinates relative to the grid's corner).
  for (const Eigen::Vector2d& m : in_map) xy.emplace_back(m.x() - x0, m.y() - y1);
  cv::convexHull(xy, hull);
  r.AddBand("displacement_magnitude_m");
  r.AddBand("dx_m");
  r.AddBand("dy_m");
  r.AddBand("dz_m");
  r.AddBand("vx_mm_per_day");
  r.AddBand("vy_mm_per_day");
  r.AddBand("vz_mm_per_day");
  // Displacement [m] and velocity [mm/day] of a point, interpolated alike.
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  auto field = [](const PointState& p) {
    Vector6d f;
    f << p.displacement, p.velocity * kMmPerDay;
    return f;
  };
  // Cell centres at the origin's height (map z of site z = 0).
  const double map_z = site ? to_map(Eigen::Vector3d::Zero()).z() : 0.0;
  for (int row = 0; row < r.height; ++row) {
    for (int col = 0; col < r.width; ++col) {
      const Eigen::Vector2d m = r.CellCentre(row, col);
      if (cv::pointPolygonTest(hull, cv::Point2f(m.x() - x0, m.y() - y1), true) <
          -options.grid_margin)
        continue;
      const Eigen::Vector2d c =
          site ? site->SiteFromMap(Eigen::Vector3d(m.x(), m.y(), map_z)).head<2>().eval() : m;
      Vector6d sum = Vector6d::Zero();
      double wsum = 0.0;
      for (const PointState& p : s.points) {
        const double dist = (p.reference_position.head<2>() - c).norm();
        if (dist > options.idw_radius) continue;
        if (dist < 1e-9) {  // IDW is exact at a point
          sum = field(p);
          wsum = 1.0;
          break;
        }
        const double w = 1.0 / std::pow(dist, options.idw_power);
        sum += w * field(p);
        wsum += w;
      }
      if (wsum <= 0.0) continue;
      const Vector6d f = sum / wsum;
      r.At(0, row, col) = static_cast<float>(f.head<3>().norm());
      for (int k = 0; k < 6; ++k) r.At(1 + k, row, col) = static_cast<float>(f(k));
    }
  }
  io::WriteGeoTiff(path, r);
  return path;
}

std::string WriteDisplacementMap(const Snapshot& s, const std::string& path,
                                 const ReportOptions& options) {
  Eigen::Vector2d lo(0, 0), hi(1, 1);
  if (!s.points.empty()) {
    lo = Eigen::Vector2d(1e300, 1e300);
    hi = -lo;
    for (const PointState& p : s.points) {
      lo = lo.cwiseMin(p.reference_position.head<2>());
      hi = hi.cwiseMax(p.reference_position.head<2>());
    }
  }
  const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1.0});
  // Arrow scale: the largest horizontal displacement spans 15 % of the
  // points' extent unless fixed; the map then grows to hold every arrow tip.
  double max_h = 0.0;
  for (const PointState& p : s.points) max_h = std::max(max_h, p.displacement.head<2>().norm());
  const double scale =
      options.arrow_scale > 0 ? options.arrow_scale : (max_h > 0 ? 0.15 * span / max_h : 1.0);
  for (const PointState& p : s.points) {
    const Eigen::Vector2d tip = p.reference_position.head<2>() + scale * p.displacement.head<2>();
    lo = lo.cwiseMin(tip);
    hi = hi.cwiseMax(tip);
  }
  lo -= Eigen::Vector2d::Constant(0.1 * span);
  hi += Eigen::Vector2d::Constant(0.1 * span);
  const int margin_left = 70, margin_top = 60, margin_bottom = 110, margin_right = 30;
  const int plot_w = options.map_width - margin_left - margin_right;
  const double m_per_px = (hi.x() - lo.x()) / plot_w;
  const int plot_h = std::max(200, static_cast<int>(std::ceil((hi.y() - lo.y()) / m_per_px)));
  cv::Mat img(margin_top + plot_h + margin_bottom, options.map_width, CV_8UC3,
              cv::Scalar(255, 255, 255));
  auto to_px = [&](const Eigen::Vector2d& xy) {
    return cv::Point(
        margin_left + static_cast<int>(std::lround((xy.x() - lo.x()) / m_per_px)),
        margin_top + plot_h - static_cast<int>(std::lround((xy.y() - lo.y()) / m_per_px)));
  };
  // Frame, grid and axes.
  const double grid = Nice((hi.x() - lo.x()) / 6.0);
  for (double x = std::ceil(lo.x() / grid) * grid; x <= hi.x(); x += grid) {
    const cv::Point a = to_px({x, lo.y()}), b = to_px({x, hi.y()});
    cv::line(img, cv::Point(a.x, margin_top), cv::Point(a.x, margin_top + plot_h),
             cv::Scalar(225, 225, 225), 1);
    Text(img, Num(x, 0), cv::Point(a.x - 12, margin_top + plot_h + 18), 0.45);
    (void)b;
  }
  for (double y = std::ceil(lo.y() / grid) * grid; y <= hi.y(); y += grid) {
    const cv::Point a = to_px({lo.x(), y});
    if (a.y < margin_top || a.y > margin_top + plot_h) continue;
    cv::line(img, cv::Point(margin_left, a.y), cv::Point(margin_left + plot_w, a.y),
             cv::Scalar(225, 225, 225), 1);
    Text(img, Num(y, 0), cv::Point(8, a.y + 5), 0.45);
  }
  cv::rectangle(img, cv::Point(margin_left, margin_top),
                cv::Point(margin_left + plot_w, margin_top + plot_h), cv::Scalar(0, 0, 0), 1);
  Text(img, "site x (east) [m]", cv::Point(margin_left + plot_w / 2 - 60, margin_top + plot_h + 38),
       0.5);
  Text(img, "y (north) [m]", cv::Point(5, margin_top - 10), 0.5);
  Text(img,
       Message("Horizontal displacement since epoch ", s.reference_epoch, " (",
               Utc(s.reference_stamp), ") to ", Utc(s.stamp),
               "   slope alert: ", AlertName(s.alert)),
       cv::Point(margin_left, 25), 0.55, cv::Scalar(0, 0, 0), 1);
  for (const PointState& p : s.points) {
    const Eigen::Vector2d from = p.reference_position.head<2>();
    const Eigen::Vector2d to = from + scale * p.displacement.head<2>();
    const cv::Scalar colour = AlertColour(p.alert);
    cv::circle(img, to_px(from), 4, colour, cv::FILLED, cv::LINE_AA);
    if ((to_px(to) - to_px(from)).dot(to_px(to) - to_px(from)) > 4)
      cv::arrowedLine(img, to_px(from), to_px(to), colour, 2, cv::LINE_AA, 0, 0.2);
    // Error ellipse (1 sigma, horizontal part) at the arrow head, same scale.
    const Eigen::Matrix2d C = p.displacement_covariance.topLeftCorner<2, 2>();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(C);
    const Eigen::Vector2d ev = es.eigenvalues().cwiseMax(0.0).cwiseSqrt() * scale / m_per_px;
    const double ang = std::atan2(es.eigenvectors()(1, 1), es.eigenvectors()(0, 1)) * 180.0 / M_PI;
    cv::ellipse(
        img, to_px(to),
        cv::Size(std::max(1, (int)std::lround(ev(1))), std::max(1, (int)std::lround(ev(0)))), -ang,
        0, 360, colour, 1, cv::LINE_AA);
    Text(img, Message(p.id, " ", Num(p.displacement.norm() * 1e3, 1), " mm"),
         to_px(from) + cv::Point(6, -6), 0.4, cv::Scalar(40, 40, 40));
  }
  // Scale bars: map metres and displacement millimetres.
  const int y_bar = margin_top + plot_h + 70;
  const double map_bar = Nice((hi.x() - lo.x()) / 5.0);
  const int map_bar_px = static_cast<int>(std::lround(map_bar / m_per_px));
  cv::line(img, cv::Point(margin_left, y_bar), cv::Point(margin_left + map_bar_px, y_bar),
           cv::Scalar(0, 0, 0), 3);
  Text(img, Message(Num(map_bar, 0), " m (map)"), cv::Point(margin_left, y_bar + 22), 0.5);
  if (max_h > 0) {
    const double disp_bar = Nice(max_h * 0.6);  // metres of displacement
    const int disp_px = static_cast<int>(std::lround(disp_bar * scale / m_per_px));
    const int x = margin_left + map_bar_px + 80;
    cv::arrowedLine(img, cv::Point(x, y_bar), cv::Point(x + disp_px, y_bar), cv::Scalar(0, 0, 0), 2,
                    cv::LINE_AA, 0, 0.15);
    Text(img, Message(Num(disp_bar * 1e3, 1), " mm (displacement)"), cv::Point(x, y_bar + 22), 0.5);
  }
  // Legend.
  int lx = options.map_width - margin_right - 330;
  for (AlertLevel a :
       {AlertLevel::kNone, AlertLevel::kWatch, AlertLevel::kWarning, AlertLevel::kAlarm}) {
    cv::rectangle(img, cv::Rect(lx, y_bar - 8, 14, 14), AlertColour(a), cv::FILLED);
    Text(img, AlertName(a), cv::Point(lx + 18, y_bar + 4), 0.45);
    lx += 82;
  }
  WriteImage(path, img);
  return path;
}

std::string WriteTimeSeries(const std::string& point_id, const std::vector<SeriesSample>& series,
                            const Thresholds& thresholds, const std::string& path,
                            const ReportOptions& options) {
  const int W = options.series_width, H = options.series_height;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 80, right = 20, top = 40, gap = 50, bottom = 45;
  const int panel_h = (H - top - gap - bottom) / 2;
  const int plot_w = W - left - right;
  Text(img, Message("Point ", point_id, ": displacement and speed"), cv::Point(left, 25), 0.6);
  if (series.empty()) {
    Text(img, "no estimates yet", cv::Point(left, top + panel_h), 0.7, cv::Scalar(0, 0, 200));
    WriteImage(path, img);
    return path;
  }
  const double t0 = series.front().stamp;
  const double t1 = std::max(series.back().stamp, t0 + 3600.0);
  const double hours = (t1 - t0) / 3600.0;
  auto tx = [&](double t) {
    return left + static_cast<int>(std::lround((t - t0) / (t1 - t0) * plot_w));
  };
  struct Panel {
    int y0;
    double lo, hi;
  };
  double dmax = 0.0, vmax = thresholds.warning * kMmPerDay * 1.1;
  for (size_t i = 0; i < series.size(); ++i) {
    const SeriesSample& s = series[i];
    dmax = std::max(dmax, (s.displacement.norm() + s.sigma) * 1e3);
    // The first tenth is the filter settling: it may leave the speed axis.
    if (i >= series.size() / 10) vmax = std::max(vmax, (s.speed + s.speed_sigma) * kMmPerDay);
  }
  if (vmax > thresholds.alarm * kMmPerDay * 0.7)
    vmax = std::max(vmax, thresholds.alarm * kMmPerDay * 1.1);
  dmax = Nice(std::max(dmax, 1.0) * 1.1) * 1.0;
  const Panel pd{top, 0.0, std::max(dmax, 1.0)}, pv{top + panel_h + gap, 0.0, vmax * 1.05};
  auto ty = [&](const Panel& p, double v) {
    return p.y0 + panel_h - static_cast<int>(std::lround((v - p.lo) / (p.hi - p.lo) * panel_h));
  };
  const double tick_h = Nice(hours / 8.0);
  for (const Panel* p : {&pd, &pv}) {
    cv::rectangle(img, cv::Point(left, p->y0), cv::Point(left + plot_w, p->y0 + panel_h),
                  cv::Scalar(0, 0, 0), 1);
    const double step = Nice((p->hi - p->lo) / 5.0);
    for (double v = 0.0; v <= p->hi; v += step) {
      const int y = ty(*p, v);
      cv::line(img, cv::Point(left, y), cv::Point(left + plot_w, y), cv::Scalar(230, 230, 230), 1);
      Text(img, Num(v, step < 1 ? 1 : 0), cv::Point(8, y + 5), 0.42);
    }
    for (double h = 0.0; h <= hours + 1e-9; h += tick_h) {
      const int x = tx(t0 + h * 3600.0);
      cv::line(img, cv::Point(x, p->y0), cv::Point(x, p->y0 + panel_h), cv::Scalar(230, 230, 230),
               1);
      Text(img, Num(h, tick_h < 1 ? 1 : 0), cv::Point(x - 8, p->y0 + panel_h + 16), 0.42);
    }
  }
  Text(img, "|d| [mm] (band: 1 sigma)", cv::Point(left + 5, pd.y0 + 16), 0.45,
       cv::Scalar(120, 60, 0));
  Text(img, "speed [mm/day] (band: 1 sigma)", cv::Point(left + 5, pv.y0 + 16), 0.45,
       cv::Scalar(120, 60, 0));
  Text(img, Message("hours since ", Utc(t0)), cv::Point(left + plot_w / 2 - 90, H - 8), 0.5);
  // Threshold lines.
  for (AlertLevel a : {AlertLevel::kWatch, AlertLevel::kWarning, AlertLevel::kAlarm}) {
    const double v = thresholds.Of(a) * kMmPerDay;
    if (v > pv.hi) continue;
    const int y = ty(pv, v);
    cv::line(img, cv::Point(left, y), cv::Point(left + plot_w, y), AlertColour(a), 1, cv::LINE_AA);
    Text(img, Message(AlertName(a), " ", Num(v, 1)), cv::Point(left + plot_w - 120, y - 4), 0.42,
         AlertColour(a));
  }
  // Curves with sigma bands.
  for (size_t i = 1; i < series.size(); ++i) {
    const SeriesSample &a = series[i - 1], &b = series[i];
    const double da = a.displacement.norm() * 1e3, db = b.displacement.norm() * 1e3;
    cv::line(img, cv::Point(tx(a.stamp), ty(pd, da + a.sigma * 1e3)),
             cv::Point(tx(b.stamp), ty(pd, db + b.sigma * 1e3)), cv::Scalar(230, 190, 150), 1,
             cv::LINE_AA);
    cv::line(img, cv::Point(tx(a.stamp), ty(pd, std::max(0.0, da - a.sigma * 1e3))),
             cv::Point(tx(b.stamp), ty(pd, std::max(0.0, db - b.sigma * 1e3))),
             cv::Scalar(230, 190, 150), 1, cv::LINE_AA);
    cv::line(img, cv::Point(tx(a.stamp), ty(pd, da)), cv::Point(tx(b.stamp), ty(pd, db)),
             cv::Scalar(160, 60, 0), 2, cv::LINE_AA);
    const double va = a.speed * kMmPerDay, vb = b.speed * kMmPerDay;
    const double sa = a.speed_sigma * kMmPerDay, sb = b.speed_sigma * kMmPerDay;
    cv::line(img, cv::Point(tx(a.stamp), ty(pv, std::min(pv.hi, va + sa))),
             cv::Point(tx(b.stamp), ty(pv, std::min(pv.hi, vb + sb))), cv::Scalar(230, 190, 150), 1,
             cv::LINE_AA);
    cv::line(img, cv::Point(tx(a.stamp), ty(pv, std::max(0.0, va - sa))),
             cv::Point(tx(b.stamp), ty(pv, std::max(0.0, vb - sb))), cv::Scalar(230, 190, 150), 1,
             cv::LINE_AA);
    cv::line(img, cv::Point(tx(a.stamp), ty(pv, std::min(pv.hi, va))),
             cv::Point(tx(b.stamp), ty(pv, std::min(pv.hi, vb))), cv::Scalar(160, 60, 0), 2,
             cv::LINE_AA);
  }
  WriteImage(path, img);
  return path;
}

std::vector<std::string> WriteReports(const Estimator& estimator, const std::string& root,
                                      const std::string& subfolder,
                                      const std::vector<std::string>& formats_in,
                                      const ReportOptions& options) {
  options.Check();
  std::vector<std::string> formats = formats_in;
  if (formats.empty()) formats = {"csv", "geojson", "geotiff", "gpkg", "png"};
  for (const std::string& f : formats)
    if (f != "csv" && f != "geojson" && f != "geotiff" && f != "gpkg" && f != "png")
      throw InvalidArgument(
          Message("unknown report format '", f, "' (csv, geojson, geotiff, gpkg, png)"));
  if (root.empty()) throw InvalidArgument("report folder is empty");
  const std::string directory = io::ResolveSubfolder(root, subfolder);
  const Snapshot s = estimator.GetSnapshot();
  const std::string base = directory + "/deformation";
  std::vector<std::string> files;
  for (const std::string& f : formats) {
    if (f == "csv") files.push_back(WriteCsv(s, base + ".csv", options));
    if (f == "gpkg") files.push_back(WriteGeoPackage(s, base + ".gpkg", options));
    // RFC 7946 GeoJSON is WGS 84: written for a georeferenced site only.
    if (f == "geojson" && ReportSiteCrs(options)) {
      files.push_back(WriteGeoJson(s, base + ".geojson", options));
      files.push_back(WriteAreasGeoJson(s, base + "_areas.geojson", options));
    }
    if (f == "geotiff" && !s.points.empty())
      files.push_back(WriteDisplacementGeoTiff(s, base + ".tif", options));
    if (f == "png") {
      files.push_back(WriteDisplacementMap(s, base + "_map.png", options));
      for (const auto& [id, series] : estimator.Series())
        files.push_back(WriteTimeSeries(id, series, estimator.ThresholdsOf(id),
                                        base + "_series_" + FileNamePart(id) + ".png", options));
    }
  }
  return files;
}

}  // namespace deformation
}  // namespace slope_monitor
