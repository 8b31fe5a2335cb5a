#include "slope_monitor/core/common/site_crs.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <mutex>

#include <proj.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace {

constexpr char kWgs84_3d[] = "EPSG:4979";

std::string ProjError(PJ_CONTEXT* ctx) {
  const int code = proj_context_errno(ctx);
  const char* text = proj_context_errno_string(ctx, code);
  return text ? text : "unknown PROJ error";
}

std::string Fixed(double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.12f", v);
  return buf;
}

}  // namespace

void SiteCrsOptions::Check() const {
  if (crs.empty()) throw InvalidArgument("site crs is empty (expected EPSG:NNNN or a PROJ string)");
  if (!origin.allFinite()) {
    throw InvalidArgument(Message("site origin [", origin.x(), ", ", origin.y(), ", ", origin.z(),
                                  "] is not finite"));
  }
}

SiteCrsOptions::Frame ParseSiteFrame(const std::string& name) {
  if (name == "local_enu") return SiteCrsOptions::Frame::kLocalEnu;
  if (name == "shifted_crs") return SiteCrsOptions::Frame::kShiftedCrs;
  throw InvalidArgument(Message("site frame '", name, "' is not local_enu or shifted_crs"));
}

struct SiteCrs::Impl {
  SiteCrsOptions options;
  Eigen::Vector3d origin_wgs84 = Eigen::Vector3d::Zero();
  PJ_CONTEXT* ctx = nullptr;
  PJ* crs = nullptr;           // the site CRS
  PJ* crs_to_wgs84 = nullptr;  // site CRS (x east, y north) -> WGS 84 (lon, lat, h)
  PJ* wgs84_to_enu = nullptr;  // WGS 84 (lon, lat deg, h) -> ENU at the origin
  std::string map_crs;         // MapCrs()
  int map_epsg = 0;
  PJ* wgs84_to_map = nullptr;  // kLocalEnu: WGS 84 (lon, lat, h) -> UTM (E, N, h)
  mutable std::mutex mutex;

  ~Impl() {
    for (PJ* p : {crs, crs_to_wgs84, wgs84_to_enu, wgs84_to_map}) {
      if (p) proj_destroy(p);
    }
    if (ctx) proj_context_destroy(ctx);
  }

  // Runs `pj` forward or inverse on one point; throws naming `what`.
  Eigen::Vector3d Trans(PJ* pj, PJ_DIRECTION dir, const Eigen::Vector3d& x,
                        const char* what) const {
    std::lock_guard<std::mutex> lock(mutex);
    proj_errno_reset(pj);
    const PJ_COORD out = proj_trans(pj, dir, proj_coord(x.x(), x.y(), x.z(), 0.0));
    Eigen::Vector3d y(out.xyzt.x, out.xyzt.y, out.xyzt.z);
    if (proj_errno(pj) != 0 || !y.allFinite()) {
      throw InvalidArgument(Message(what, " [", x.x(), ", ", x.y(), ", ", x.z(), "] (site crs '",
                                    options.crs, "'): PROJ cannot convert it: ", ProjError(ctx)));
    }
    return y;
  }
};

SiteCrs::SiteCrs(const SiteCrsOptions& options) : impl_(std::make_unique<Impl>()) {
  options.Check();
  Impl& m = *impl_;
  m.options = options;
  m.ctx = proj_context_create();
  proj_log_level(m.ctx, PJ_LOG_NONE);  // errors are reported by our exceptions
  m.crs = proj_create(m.ctx, options.crs.c_str());
  if (!m.crs) {
    throw InvalidArgument(
        Message("site crs '", options.crs, "' is not a CRS PROJ knows: ", ProjError(m.ctx)));
  }
  PJ* raw = proj_create_crs_to_crs(m.ctx, options.crs.c_str(), kWgs84_3d, nullptr);
  if (!raw) {
    throw InvalidArgument(
        Message("site crs '", options.crs, "': no conversion to WGS 84: ", ProjError(m.ctx)));
  }
  m.crs_to_wgs84 = proj_normalize_for_visualization(m.ctx, raw);
  proj_destroy(raw);
  if (!m.crs_to_wgs84) {
    throw InvalidArgument(Message("site crs '", options.crs,
                                  "': cannot order its axes east, north: ", ProjError(m.ctx)));
  }
  m.origin_wgs84 = m.Trans(m.crs_to_wgs84, PJ_FWD, options.origin, "site origin");
  const std::string enu =
      "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad +step +proj=cart "
      "+ellps=WGS84 +step +proj=topocentric +ellps=WGS84 +lon_0=" +
      Fixed(m.origin_wgs84.x()) + " +lat_0=" + Fixed(m.origin_wgs84.y()) +
      " +h_0=" + Fixed(m.origin_wgs84.z());
  m.wgs84_to_enu = proj_create(m.ctx, enu.c_str());
  if (!m.wgs84_to_enu) {
    throw InvalidArgument(Message("site origin of crs '", options.crs,
                                  "': PROJ cannot set up the local frame: ", ProjError(m.ctx)));
  }
  PJ* map = m.crs;
  if (options.frame == SiteCrsOptions::Frame::kShiftedCrs) {
    m.map_crs = options.crs;
  } else {
    const double lon = m.origin_wgs84.x(), lat = m.origin_wgs84.y();
    const int zone = std::clamp(static_cast<int>(std::floor((lon + 180.0) / 6.0)) + 1, 1, 60);
    m.map_crs = Message("EPSG:", (lat < 0.0 ? 32700 : 32600) + zone);
    PJ* to_map = proj_create_crs_to_crs(m.ctx, kWgs84_3d, m.map_crs.c_str(), nullptr);
    m.wgs84_to_map = to_map ? proj_normalize_for_visualization(m.ctx, to_map) : nullptr;
    if (to_map) proj_destroy(to_map);
    if (!m.wgs84_to_map) {
      throw InvalidArgument(Message("site origin of crs '", options.crs, "': PROJ cannot set up ",
                                    m.map_crs, ": ", ProjError(m.ctx)));
    }
    map = proj_create(m.ctx, m.map_crs.c_str());
  }
  const char* auth = map ? proj_get_id_auth_name(map, 0) : nullptr;
  const char* code = map ? proj_get_id_code(map, 0) : nullptr;
  if (auth && code && std::string(auth) == "EPSG") m.map_epsg = std::atoi(code);
  if (map && map != m.crs) proj_destroy(map);
}

SiteCrs SiteCrs::LocalEnuAtWgs84(double latitude_deg, double longitude_deg, double height_m) {
  if (!std::isfinite(latitude_deg) || std::abs(latitude_deg) > 90.0) {
    throw InvalidArgument(
        Message("site origin latitude ", latitude_deg, " deg is outside [-90, 90]"));
  }
  if (!std::isfinite(longitude_deg) || std::abs(longitude_deg) > 180.0) {
    throw InvalidArgument(
        Message("site origin longitude ", longitude_deg, " deg is outside [-180, 180]"));
  }
  if (!std::isfinite(height_m) || std::abs(height_m) > 1e5) {
    throw InvalidArgument(Message("site origin height ", height_m, " m is outside [-1e5, 1e5]"));
  }
  SiteCrsOptions o;
  o.crs = kWgs84_3d;
  o.origin = Eigen::Vector3d(longitude_deg, latitude_deg, height_m);
  return SiteCrs(o);
}

SiteCrs::~SiteCrs() = default;
SiteCrs::SiteCrs(SiteCrs&&) noexcept = default;
SiteCrs& SiteCrs::operator=(SiteCrs&&) noexcept = default;

const SiteCrsOptions& SiteCrs::options() const { return impl_->options; }
const Eigen::Vector3d& SiteCrs::origin_wgs84() const { return impl_->origin_wgs84; }

const std::string& SiteCrs::MapCrs() const { return impl_->map_crs; }
int SiteCrs::MapEpsg() const { return impl_->map_epsg; }

std::string SiteCrs::CrsWkt() const {
  const Impl& m = *impl_;
  std::lock_guard<std::mutex> lock(m.mutex);
  PJ* crs = proj_create(m.ctx, m.map_crs.c_str());
  const char* wkt = crs ? proj_as_wkt(m.ctx, crs, PJ_WKT1_GDAL, nullptr) : nullptr;
  std::string out = wkt ? wkt : "";
  if (crs) proj_destroy(crs);
  if (out.empty())
    throw InvalidArgument(
        Message("site crs '", m.options.crs, "': PROJ cannot write ", m.map_crs, " as WKT"));
  return out;
}

Eigen::Vector3d SiteCrs::MapFromSite(const Eigen::Vector3d& x_in_site) const {
  if (impl_->options.frame == SiteCrsOptions::Frame::kShiftedCrs)
    return x_in_site + impl_->options.origin;
  return impl_->Trans(impl_->wgs84_to_map, PJ_FWD, Wgs84FromSite(x_in_site), "site point");
}

Eigen::Vector3d SiteCrs::SiteFromMap(const Eigen::Vector3d& x_in_map) const {
  if (impl_->options.frame == SiteCrsOptions::Frame::kShiftedCrs)
    return x_in_map - impl_->options.origin;
  return SiteFromWgs84(impl_->Trans(impl_->wgs84_to_map, PJ_INV, x_in_map, "map point"));
}

Eigen::Vector3d SiteCrs::SiteFromWgs84(const Eigen::Vector3d& lon_lat_h) const {
  if (impl_->options.frame == SiteCrsOptions::Frame::kShiftedCrs) {
    return impl_->Trans(impl_->crs_to_wgs84, PJ_INV, lon_lat_h, "WGS 84 point") -
           impl_->options.origin;
  }
  return impl_->Trans(impl_->wgs84_to_enu, PJ_FWD, lon_lat_h, "WGS 84 point");
}

Eigen::Vector3d SiteCrs::Wgs84FromSite(const Eigen::Vector3d& x_in_site) const {
  if (impl_->options.frame == SiteCrsOptions::Frame::kShiftedCrs) {
    return impl_->Trans(impl_->crs_to_wgs84, PJ_FWD, x_in_site + impl_->options.origin,
                        "site point");
  }
  return impl_->Trans(impl_->wgs84_to_enu, PJ_INV, x_in_site, "site point");
}

Eigen::Vector3d SiteCrs::SiteFromCrs(const Eigen::Vector3d& x_in_crs) const {
  if (impl_->options.frame == SiteCrsOptions::Frame::kShiftedCrs)
    return x_in_crs - impl_->options.origin;
  return SiteFromWgs84(
      impl_->Trans(impl_->crs_to_wgs84, PJ_FWD, x_in_crs, "point in the site crs"));
}

Eigen::Vector3d SiteCrs::CrsFromSite(const Eigen::Vector3d& x_in_site) const {
  if (impl_->options.frame == SiteCrsOptions::Frame::kShiftedCrs)
    return x_in_site + impl_->options.origin;
  return impl_->Trans(impl_->crs_to_wgs84, PJ_INV, Wgs84FromSite(x_in_site), "site point");
}

}  // namespace slope_monitor
