#include "slope_monitor/core/flight/flight_export.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "slope_monitor/core/camera/rotation.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/io/json_text.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace flight {
namespace {

std::string Fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

// v rounded to `digits` decimals (NaN stays NaN: written as null).
double Round(double v, int digits) {
  const double f = std::pow(10.0, digits);
  return std::round(v * f) / f;
}

// v rounded to n significant digits.
double Significant(double v, int n) {
  if (v == 0.0 || !std::isfinite(v)) return v;
  return Round(v, n - 1 - static_cast<int>(std::floor(std::log10(std::abs(v)))));
}

nlohmann::ordered_json JsonResiduals(const std::vector<PointResidual>& v) {
  nlohmann::ordered_json out = nlohmann::ordered_json::array();
  for (const PointResidual& r : v) {
    nlohmann::ordered_json p = {{"name", r.name}, {"picks", r.picks}, {"measured", r.measured}};
    if (r.measured) {
      p["dx"] = Round(r.residual.x(), 4);
      p["dy"] = Round(r.residual.y(), 4);
      p["dz"] = Round(r.residual.z(), 4);
      p["d3"] = Round(r.residual.norm(), 4);
      p["pick_rms_px"] = Round(r.pick_rms_px, 2);
    } else {
      p["message"] = r.message;
    }
    out.push_back(std::move(p));
  }
  return out;
}

std::string MdResiduals(const char* title, const std::vector<PointResidual>& v, double rms,
                        bool picks_rms) {
  if (v.empty()) return "";
  std::ostringstream o;
  o << "\n## " << title
    << "\n\n| point | picks | dx [m] | dy [m] | dz [m] | 3-D [m] | picks rms [px] |\n"
    << "|---|---|---|---|---|---|---|\n";
  for (const PointResidual& r : v) {
    if (r.measured)
      o << "| " << r.name << " | " << r.picks << " | " << Fmt("%.3f", r.residual.x()) << " | "
        << Fmt("%.3f", r.residual.y()) << " | " << Fmt("%.3f", r.residual.z()) << " | "
        << Fmt("%.3f", r.residual.norm()) << " | " << (picks_rms ? Fmt("%.1f", r.pick_rms_px) : "")
        << " |\n";
    else
      o << "| " << r.name << " | " << r.picks << " | " << r.message << " | | | | |\n";
  }
  o << "\nRMS (3-D): " << Fmt("%.3f", rms) << " m\n";
  return o.str();
}

}  // namespace

void WriteColmapModel(const FlightResult& block, const std::string& sparse_dir) {
  std::filesystem::create_directories(sparse_dir);
  const adjustment::Scene& sc = block.scene;
  const camera::OpenCvCamera cv = sc.cameras[0].model.ToOpenCv();
  auto d = [&](size_t i) { return i < cv.distortion.size() ? cv.distortion[i] : 0.0; };
  std::ostringstream cams;
  cams.precision(12);
  cams << "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, "
          "PARAMS[]\n"
       << "# Number of cameras: 1\n1 FULL_OPENCV " << cv.width << " " << cv.height << " "
       << cv.k(0, 0) << " " << cv.k(1, 1) << " " << cv.k(0, 2) + 0.5 << " " << cv.k(1, 2) + 0.5
       << " " << d(0) << " " << d(1) << " " << d(2) << " " << d(3) << " " << d(4) << " 0 0 0\n";
  io::WriteFileAtomically(sparse_dir + "/cameras.txt", cams.str());
  // Point index of each observation within its image (POINT2D_IDX).
  std::vector<std::vector<int>> obs_of_image(sc.images.size());
  std::vector<int> index_in_image(sc.observations.size());
  for (size_t k = 0; k < sc.observations.size(); ++k) {
    index_in_image[k] = static_cast<int>(obs_of_image[sc.observations[k].image].size());
    obs_of_image[sc.observations[k].image].push_back(static_cast<int>(k));
  }
  std::ostringstream ims;
  ims.precision(12);
  ims << "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, "
         "TZ, CAMERA_ID, NAME\n"
      << "#   POINTS2D[] as (X, Y, POINT3D_ID)\n# Number of images: " << sc.images.size() << "\n";
  for (size_t i = 0; i < sc.images.size(); ++i) {
    const Rigid3 r = sc.images[i].exterior.OpticalFromSite();
    ims << i + 1 << " " << r.rotation.w() << " " << r.rotation.x() << " " << r.rotation.y() << " "
        << r.rotation.z() << " " << r.translation.x() << " " << r.translation.y() << " "
        << r.translation.z() << " 1 " << sc.images[i].name << "\n";
    for (size_t j = 0; j < obs_of_image[i].size(); ++j) {
      const adjustment::Observation& o = sc.observations[obs_of_image[i][j]];
      ims << (j ? " " : "") << o.pixel.x() + 0.5 << " " << o.pixel.y() + 0.5 << " " << o.point + 1;
    }
    ims << "\n";
  }
  io::WriteFileAtomically(sparse_dir + "/images.txt", ims.str());
  std::vector<std::vector<int>> obs_of_point(sc.points.size());
  for (size_t k = 0; k < sc.observations.size(); ++k)
    obs_of_point[sc.observations[k].point].push_back(static_cast<int>(k));
  std::ostringstream pts;
  pts.precision(10);
  pts << "# 3D point list with one line of data per point:\n"
      << "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n"
      << "# Number of points: " << sc.points.size() << "\n";
  for (size_t p = 0; p < sc.points.size(); ++p) {
    const Eigen::Vector3d& x = sc.points[p].position;
    const int g = block.point_grey[p];
    pts << p + 1 << " " << x.x() << " " << x.y() << " " << x.z() << " " << g << " " << g << " " << g
        << " " << block.point_error_px[p];
    for (int k : obs_of_point[p])
      pts << " " << sc.observations[k].image + 1 << " " << index_in_image[k];
    pts << "\n";
  }
  io::WriteFileAtomically(sparse_dir + "/points3D.txt", pts.str());
}

void WritePointsPly(const FlightResult& block, const std::string& path) {
  const adjustment::Scene& sc = block.scene;
  std::vector<int> images(sc.points.size(), 0);
  for (const auto& o : sc.observations) ++images[o.point];
  std::ostringstream o;
  o << "ply\nformat ascii 1.0\ncomment slope_monitor: tie points in the site frame"
    << " (crs.txt says which)\nelement vertex " << sc.points.size()
    << "\nproperty double x\nproperty double y\nproperty double z\nproperty uchar red\nproperty "
       "uchar green\n"
    << "property uchar blue\nproperty float error_px\nproperty int images\nend_header\n";
  o.precision(10);
  for (size_t p = 0; p < sc.points.size(); ++p) {
    const Eigen::Vector3d& x = sc.points[p].position;
    const int g = block.point_grey[p];
    o << x.x() << " " << x.y() << " " << x.z() << " " << g << " " << g << " " << g << " "
      << Fmt("%.3f", block.point_error_px[p]) << " " << images[p] << "\n";
  }
  io::WriteFileAtomically(path, o.str());
}

void WriteCamerasCsv(const FlightResult& block, const std::string& path) {
  const adjustment::Scene& sc = block.scene;
  const auto& prec = block.bundle.precision;
  std::vector<int> n(sc.images.size(), 0);
  std::vector<double> ss(sc.images.size(), 0.0);
  for (size_t k = 0; k < sc.observations.size(); ++k) {
    ++n[sc.observations[k].image];
    ss[sc.observations[k].image] += block.observation_error_px[k] * block.observation_error_px[k];
  }
  std::ostringstream o;
  o << "image,x,y,z,theta_deg,phi_deg,kappa_deg,sigma_x,sigma_y,sigma_z,sigma_theta_deg,sigma_phi_"
       "deg,"
       "sigma_kappa_deg,observations,rms_px\n";
  const double deg = 180.0 / M_PI;
  for (size_t i = 0; i < sc.images.size(); ++i) {
    const auto& e = sc.images[i].exterior;
    o << sc.images[i].name << "," << Fmt("%.4f", e.position.x()) << ","
      << Fmt("%.4f", e.position.y()) << "," << Fmt("%.4f", e.position.z()) << ","
      << Fmt("%.5f", e.angles.theta * deg) << "," << Fmt("%.5f", e.angles.phi * deg) << ","
      << Fmt("%.5f", e.angles.kappa * deg);
    for (int j = 0; j < 6; ++j) {
      const double v = prec.valid && i < prec.exterior_covariance.size()
                           ? prec.exterior_covariance[i](j, j)
                           : NAN;
      o << "," << Fmt(j < 3 ? "%.4f" : "%.5f", std::sqrt(std::max(0.0, v)) * (j < 3 ? 1.0 : deg));
    }
    o << "," << n[i] << "," << Fmt("%.3f", n[i] ? std::sqrt(ss[i] / n[i]) : 0.0) << "\n";
  }
  io::WriteFileAtomically(path, o.str());
}

FlightFrame FrameOfSite(const SiteCrsOptions& crs) {
  FlightFrame f;
  f.crs = crs.crs;
  f.origin = crs.origin;
  const SiteCrs site(crs);
  f.wkt = site.CrsWkt();
  f.map_crs = site.MapCrs();
  f.local_enu = crs.frame == SiteCrsOptions::Frame::kLocalEnu;
  return f;
}

void WriteFrame(const FlightFrame& frame, const std::string& path) {
  std::ostringstream o;
  o.precision(12);
  if (frame.crs.empty()) {
    o << "crs: none (model frame: arbitrary scale and orientation)\n";
  } else {
    o << "crs: " << frame.crs << "\norigin: " << frame.origin.x() << " " << frame.origin.y() << " "
      << frame.origin.z()
      << (frame.local_enu ? "\n# site = east, north, up [m] on the tangent plane at the origin"
                          : "\n# site = CRS coordinates - origin (x east, y north, z up)")
      << "\nframe: " << (frame.local_enu ? "local_enu" : "shifted_crs")
      << (frame.local_enu ? "\nmap_crs: " + frame.map_crs + "\nmap_crs_wkt: " : "\nwkt: ")
      << frame.wkt << "\n";
  }
  io::WriteFileAtomically(path, o.str());
}

void WriteFlightReport(const FlightReportInput& in, const std::string& json_path,
                       const std::string& md_path) {
  const FlightSummary& s = in.result->summary;
  const auto& interior = in.result->scene.cameras.empty()
                             ? std::array<double, camera::kNumInterior>{}
                             : in.result->scene.cameras[0].model.interior();
  // The principal distance in pixels: where it started and where the
  // self-calibration took it (a wrong EXIF focal length, or a prior).
  const double pixel = in.photos->nominal.sensor().pixel_size;
  const double c0_px = in.photos->nominal.interior()[camera::kC] / pixel;
  const double c_px = in.result->scene.cameras.empty() ? c0_px : interior[camera::kC] / pixel;
  const double c_change = 100.0 * (c_px - c0_px) / c0_px;
  const std::string c_source =
      in.photos->focal_prior.empty() ? "EXIF focal length" : "prior: " + in.photos->focal_prior;
  nlohmann::ordered_json interior_json = nlohmann::ordered_json::object();
  for (int k = 0; k < camera::kNumInterior; ++k)  // [value, sigma]
    interior_json[camera::InteriorNames()[k]] = {Significant(interior[k], 6),
                                                 Significant(s.interior_sigma[k], 3)};
  nlohmann::ordered_json seconds = {{"features", Round(in.ties->feature_seconds, 2)},
                                    {"matching_wall", Round(in.ties->wall_seconds, 2)}};
  for (const auto& [k, v] : s.seconds) seconds[k] = Round(v, 2);
  seconds["total"] = Round(in.total_seconds, 2);
  const nlohmann::ordered_json j = {{"flight", in.flight},
                                    {"folder", in.folder},
                                    {"camera", in.photos->camera_label},
                                    {"photos", s.photos},
                                    {"skipped", in.photos->skipped.size()},
                                    {"oriented", s.oriented},
                                    {"points", s.points},
                                    {"observations", s.observations},
                                    {"pairs_tried", in.ties->pairs.size()},
                                    {"pairs_tied", in.ties->pairs_tied},
                                    {"tie_points", in.ties->tie_points},
                                    {"reprojection_rms_px", Round(s.rms_px, 4)},
                                    {"reprojection_mean_px", Round(s.mean_px, 4)},
                                    {"sigma0", Round(s.sigma0, 4)},
                                    {"datum", s.datum},
                                    {"covariance_note", s.covariance_note},
                                    {"crs", in.frame.crs},
                                    {"interior", std::move(interior_json)},
                                    {"focal",
                                     {{"source", c_source},
                                      {"start_px", Round(c0_px, 2)},
                                      {"adjusted_px", Round(c_px, 2)},
                                      {"change_percent", Round(c_change, 2)}}},
                                    {"control", JsonResiduals(s.control)},
                                    {"control_rms_m", Round(s.control_rms, 4)},
                                    {"check", JsonResiduals(s.check)},
                                    {"check_rms_m", Round(s.check_rms, 4)},
                                    {"leave_one_out", JsonResiduals(s.leave_one_out)},
                                    {"leave_one_out_rms_m", Round(s.leave_one_out_rms, 4)},
                                    {"seconds", std::move(seconds)},
                                    {"peak_memory_gb", Round(in.peak_memory_gb, 3)},
                                    {"not_oriented", s.not_oriented}};
  io::WriteFileAtomically(json_path, io::JsonText(j));

  std::ostringstream m;
  m << "# Flight " << in.flight << ": " << in.folder << "\n\n| | |\n|---|---|\n| camera | "
    << in.photos->camera_label << " |\n| principal distance | " << Fmt("%.1f", c_px) << " px, from "
    << Fmt("%.1f", c0_px) << " px (" << c_source << "), " << Fmt("%+.1f", c_change)
    << " % |\n| photos oriented | " << s.oriented << " of " << s.photos << " ("
    << in.photos->skipped.size() << " skipped) |\n| pairs tied / tried | " << in.ties->pairs_tied
    << " / " << in.ties->pairs.size() << " |\n| 3-D points | " << s.points
    << " |\n| reprojection error | rms " << Fmt("%.3f", s.rms_px) << " px, mean "
    << Fmt("%.3f", s.mean_px) << " px |\n| sigma0 | " << Fmt("%.3f", s.sigma0) << " |\n| datum | "
    << s.datum << (s.covariance_note.empty() ? "" : " (" + s.covariance_note + ")")
    << " |\n| CRS | " << (in.frame.crs.empty() ? "none" : in.frame.crs) << " |\n| time | "
    << Fmt("%.1f", in.total_seconds) << " s |\n| peak memory | " << Fmt("%.2f", in.peak_memory_gb)
    << " GB |\n";
  m << MdResiduals("Control points (in the adjustment)", s.control, s.control_rms, true)
    << MdResiduals("Check points (not in the adjustment)", s.check, s.check_rms, false)
    << MdResiduals("Leave one out (each control point left out in turn)", s.leave_one_out,
                   s.leave_one_out_rms, false);
  if (!s.not_oriented.empty()) {
    m << "\n## Photos not oriented\n\n";
    for (const std::string& n : s.not_oriented) m << "* " << n << "\n";
  }
  if (!in.photos->skipped.empty()) {
    m << "\n## Photos skipped\n\n";
    for (const SkippedPhoto& p : in.photos->skipped)
      m << "* " << p.path << ": " << p.reason << "\n";
  }
  io::WriteFileAtomically(md_path, m.str());
}

void WritePairsCsv(const FlightPhotos& photos, const FlightTies& ties, const std::string& path) {
  std::ostringstream o;
  o << "photo_a,photo_b,tie_points,epipolar_rms_px,why_not_used\n";
  for (const FlightPairStats& p : ties.pairs)
    o << photos.photos[p.a].name << "," << photos.photos[p.b].name << "," << p.tie_points << ","
      << Fmt("%.3f", p.epipolar_rms) << "," << CsvQuote(p.message) << "\n";
  io::WriteFileAtomically(path, o.str());
}

void WriteFlightOutputs(const FlightReportInput& in, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw IoError(Message(dir, ": cannot be created (", ec.message(), ")"));
  WritePairsCsv(*in.photos, *in.ties, dir + "/pairs.csv");
  if (in.result->summary.success) {
    WriteBlockOutputs(*in.result, in.frame, dir);
  } else {
    WriteFrame(in.frame, dir + "/crs.txt");
  }
  WriteFlightReport(in, dir + "/report.json", dir + "/report.md");
}

void WriteBlockOutputs(const FlightResult& block, const FlightFrame& frame,
                       const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw IoError(Message(dir, ": cannot be created (", ec.message(), ")"));
  WriteColmapModel(block, dir + "/sparse");
  WritePointsPly(block, dir + "/points.ply");
  WriteCamerasCsv(block, dir + "/cameras.csv");
  WriteFrame(frame, dir + "/crs.txt");
}

}  // namespace flight
}  // namespace slope_monitor
