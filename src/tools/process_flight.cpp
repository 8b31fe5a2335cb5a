// process_flight: a crew's UAV flight, from its photo folder to an oriented,
// georeferenced block (core/flight: the same matching and adjustment code as
// the graph's UAV path), in one command:
//
//   rosrun slope_monitor process_flight --photos DIR [--photos DIR2 ...] [--gcp FILE]
//       [--check NAME[,NAME...]] [--site FILE] --out DIR
//
// Each --photos is one flight (one epoch; the first is the reference). Per
// flight it prints exactly one line
//   flight <k>: <n> of <m> photos oriented, <p> points, reprojection rms <r> px, <t> s
// and, with control points,
//   flight <k>: control rms <x> m over <a> points, check rms <y> m over <b> points
// and writes DIR/flight_<k>/ (flight_export.h: COLMAP text model, PLY, poses
// with sigma, the pairs tried, report.json / report.md, crs.txt).
//
// --geo FILE: the photos' positions in ODM's geo.txt format (io/geo_list.h),
// used instead of their EXIF GNSS (same sigma, --gnss-sigma).
//
// An --out folder holding an earlier run's results (flight_<k>/report.json)
// is refused in one line unless --overwrite is given.
//
// Frame: the CRS of the gcp list (its first line), else the site file's (a local_enu
// site's: the UTM zone of its origin),
// else the geo list's, else the UTM zone of the first photo with GNSS (EPSG:326NN / 327NN); the
// site frame is that CRS minus a rounded origin (crs.txt). Without control
// points or GNSS the block stays in a model frame (said in the report).
//
// Dense stage (on unless --no-dense; core/flight/flight_surface.h): per
// flight, at a working resolution of --working-size px, the dense cloud
// (cloud.ply), the DEM surface_e<kk>.tif and the RGB orthophoto
// ortho_e<kk>.tif in the run's CRS, surface_report.json / .md, and the line
//   flight <k>: surface <filled> of <cells> cells at <c> m, <p> points, <t> s (decode .., matching
//   .., ortho ..), peak <g> GB
// The reference surface is --reference DIR's flight_1/surface_e01.tif (an
// earlier process_flight run in the same CRS), else this run's flight 1;
// every later flight is measured on its grid, co-registered to it on stable
// ground (the site file's areas.stable, else outside areas.outline, else
// everywhere) and its DoD written as change_e<kk>.tif (bands change, lod,
// class), with the line
//   flight <k>: change: shift (x +- sx, y +- sy) m, vertical v m, stable median dz m, NMAD n m,
//   flagged f % ...
// A dense stage or change that fails is named and counts as a left-out input.
//
// Exit status: 0 every flight oriented at least half its photos (those of its
// camera: another camera's photos in the folder are skipped) and every
// input was used; 2 as 0 but some inputs were left out (photos skipped or
// not oriented, picks naming photos not in the flight; each named on
// stderr); 1 a flight oriented fewer than half its photos, nothing was
// produced, or the command line / a file is wrong (one line on stderr).

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/peak_memory.h"
#include "slope_monitor/core/common/progress_line.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/flight/flight_export.h"
#include "slope_monitor/core/flight/flight_orientation.h"
#include "slope_monitor/core/flight/flight_surface.h"
#include "slope_monitor/core/io/gcp_list.h"
#include "slope_monitor/core/io/geo_list.h"
#include "slope_monitor/core/io/safe_file.h"
#include "slope_monitor/core/io/site_file.h"

using namespace slope_monitor;

namespace {

const char* kUsage =
    "usage: process_flight --photos DIR [--photos DIR2 ...] [--gcp FILE] [--geo FILE] [--check "
    "NAME[,NAME...]]\n"
    "                      [--site FILE] [--gcp-sigma M] [--gnss-sigma M] [--pixel-size MM] "
    "[--focal MM]\n"
    "                      [--no-leave-one-out] [--threads N] [--no-dense] [--working-size PX] "
    "[--cell M]\n"
    "                      [--reference DIR] [--overwrite] --out DIR\n"
    "  orients each folder of UAV photos (one flight each) and writes DIR/flight_<k>/\n";

struct Args {
  std::vector<std::string> folders;
  std::string gcp, site, out, geo;
  std::set<std::string> check;
  double gcp_sigma = io::kDefaultGcpSigma, gnss_sigma = capture::kExifGnssSigmaHorizontal;
  flight::FlightPhotoOptions photo;
  bool leave_one_out = true;
  int threads = 0;
  bool dense = true;
  bool overwrite = false;  // replace an earlier run's results in --out
  std::string reference;   // an earlier run's --out folder
  flight::FlightSurfaceOptions surface;
};

// The dense stage's state across the run's flights.
struct SurfaceState {
  std::optional<io::GeoRaster> reference;  // site frame of this run
  std::string reference_name;
  std::vector<dense::Polygon> stable, moving;  // site frame of this run
  bool areas_loaded = false;
};

double Number(const std::string& flag, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end || !std::isfinite(x) || x < 0.0)
    throw InvalidArgument(Message(flag, " '", v, "' is not a number >= 0"));
  return x;
}

// An --out folder that holds an earlier run's results is not written over
// without --overwrite (a crew's earlier flight would be lost without a word).
void RefuseEarlierResults(const Args& args) {
  namespace fs = std::filesystem;
  if (args.overwrite || !fs::is_directory(args.out)) return;
  std::vector<std::string> reports;
  for (const auto& e : fs::directory_iterator(args.out))
    if (e.path().filename().string().rfind("flight_", 0) == 0 &&
        fs::exists(e.path() / "report.json"))
      reports.push_back((e.path() / "report.json").string());
  if (reports.empty()) return;
  std::sort(reports.begin(), reports.end());
  throw InvalidArgument(Message("--out ", args.out, " holds an earlier run's results (", reports[0],
                                "); give --overwrite to replace them, or another --out"));
}

std::string ReferencePath(const std::string& dir) {
  return Message(dir, "/flight_1/", dense::EpochSurfaceFileName(1));
}

// Returns false for --help (printed).
bool ParseArgs(int argc, char** argv, Args* a) {
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    if (f == "-h" || f == "--help") {
      std::cout << kUsage;
      return false;
    }
    if (f == "--no-leave-one-out") {
      a->leave_one_out = false;
      continue;
    }
    if (f == "--no-dense") {
      a->dense = false;
      continue;
    }
    if (f == "--overwrite") {
      a->overwrite = true;
      continue;
    }
    if (i + 1 >= argc) throw InvalidArgument(Message(f, " needs a value (or is unknown)"));
    const std::string v = argv[++i];
    if (f == "--photos")
      a->folders.push_back(v);
    else if (f == "--gcp")
      a->gcp = v;
    else if (f == "--site")
      a->site = v;
    else if (f == "--geo")
      a->geo = v;
    else if (f == "--out")
      a->out = v;
    else if (f == "--gcp-sigma")
      a->gcp_sigma = Number(f, v);
    else if (f == "--gnss-sigma")
      a->gnss_sigma = Number(f, v);
    else if (f == "--pixel-size")
      a->photo.pixel_size_mm = Number(f, v);
    else if (f == "--focal")
      a->photo.focal_length_mm = Number(f, v);
    else if (f == "--threads")
      a->threads = static_cast<int>(Number(f, v));
    else if (f == "--working-size")
      a->surface.working_size = static_cast<int>(Number(f, v));
    else if (f == "--cell")
      a->surface.cell_size = Number(f, v);
    else if (f == "--reference")
      a->reference = v;
    else if (f == "--check") {
      std::stringstream ss(v);
      for (std::string n; std::getline(ss, n, ',');)
        if (!n.empty()) a->check.insert(n);
    } else {
      throw InvalidArgument(Message("unknown argument '", f, "'"));
    }
  }
  if (a->folders.empty()) throw InvalidArgument("no --photos DIR given");
  if (a->out.empty()) throw InvalidArgument("no --out DIR given");
  if (!(a->gcp_sigma > 0.0) || !(a->gnss_sigma > 0.0))
    throw InvalidArgument("--gcp-sigma and --gnss-sigma must be > 0");
  a->surface.Check();
  if (!a->reference.empty() && !a->dense)
    throw InvalidArgument("--reference needs the dense stage (no --no-dense)");
  if (!a->reference.empty() && !std::filesystem::is_regular_file(ReferencePath(a->reference)))
    throw InvalidArgument(
        Message("--reference ", a->reference, ": no ", ReferencePath(a->reference),
                " (the --out folder of an earlier process_flight run with its dense stage)"));
  return true;
}

// UTM zone (WGS 84) of a longitude / latitude.
std::string UtmEpsg(double lon, double lat) {
  const int zone = std::clamp(static_cast<int>(std::floor((lon + 180.0) / 6.0)) + 1, 1, 60);
  return io::WgsUtmEpsg(zone, lat < 0.0);
}

// The site frame of the run: from the gcp list, the site file or the first
// GNSS photo (nullopt: model frame).
std::optional<SiteCrs> MakeFrame(const Args& args, const std::optional<io::GcpList>& gcp,
                                 const std::optional<io::GeoList>& geo,
                                 const flight::FlightPhotos& first, flight::FlightFrame* frame) {
  SiteCrsOptions o;
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  if (gcp) {
    o.crs = gcp->crs;
    const Eigen::Vector3d g = gcp->points.front().geo;
    o.origin =
        Eigen::Vector3d(std::round(g.x() / 100.0) * 100.0, std::round(g.y() / 100.0) * 100.0, 0.0);
  } else if (!args.site.empty()) {
    o = io::LoadSiteFile(args.site).crs;
    if (o.frame == SiteCrsOptions::Frame::kLocalEnu) {
      // A local_enu site: the run's frame is the UTM zone of its origin
      // (SiteCrs::MapCrs), so the GeoTIFFs carry that EPSG code.
      const SiteCrs site(o);
      const Eigen::Vector3d u = site.MapFromSite(Eigen::Vector3d::Zero());
      o.crs = site.MapCrs();
      o.frame = SiteCrsOptions::Frame::kShiftedCrs;
      o.origin = Eigen::Vector3d(std::round(u.x() / 100.0) * 100.0,
                                 std::round(u.y() / 100.0) * 100.0, 0.0);
    }
  } else if (geo && !geo->entries.empty()) {
    o.crs = geo->crs;
    const Eigen::Vector3d g = geo->entries.front().geo;
    o.origin =
        Eigen::Vector3d(std::round(g.x() / 100.0) * 100.0, std::round(g.y() / 100.0) * 100.0, 0.0);
  } else {
    const flight::FlightPhoto* p = nullptr;
    for (const auto& q : first.photos)
      if (!p && q.exif.has_gps) p = &q;
    if (!p) return std::nullopt;
    o.crs = UtmEpsg(p->exif.gps.longitude_deg, p->exif.gps.latitude_deg);
    SiteCrs probe(o);
    const Eigen::Vector3d u = probe.CrsFromSite(probe.SiteFromWgs84(
        Eigen::Vector3d(p->exif.gps.longitude_deg, p->exif.gps.latitude_deg, 0.0)));
    o.origin =
        Eigen::Vector3d(std::round(u.x() / 100.0) * 100.0, std::round(u.y() / 100.0) * 100.0, 0.0);
  }
  SiteCrs crs(o);  // throws naming the CRS when PROJ does not know it
  frame->crs = o.crs;
  frame->origin = o.origin;
  frame->wkt = crs.CrsWkt();
  return crs;
}

// Control points of the gcp list in this flight's photos; picks naming a
// photo not in the flight are named on stderr (*skipped counts them).
std::vector<flight::FlightControlPoint> ControlPoints(const io::GcpList& gcp, const SiteCrs& crs,
                                                      const flight::FlightPhotos& photos,
                                                      const Args& args, int* skipped) {
  std::vector<flight::FlightControlPoint> out;
  const Eigen::Vector2d sigma = io::GcpSigma(gcp, args.gcp_sigma);  // horizontal, vertical
  const bool heights = io::HasHeights(gcp);
  for (const io::GcpPoint& p : gcp.points) {
    flight::FlightControlPoint cp;
    cp.name = p.name;
    cp.site = crs.SiteFromCrs(p.geo);
    cp.covariance = Eigen::Vector3d(sigma.x(), sigma.x(), sigma.y()).cwiseAbs2().asDiagonal();
    cp.has_height = heights;
    cp.check = args.check.count(p.name) > 0;
    for (const io::GcpPick& k : p.picks) {
      int index = -1;
      for (size_t i = 0; i < photos.photos.size(); ++i)
        if (photos.photos[i].name == k.image) index = static_cast<int>(i);
      if (index < 0) {
        std::cerr << "process_flight: " << gcp.path << ":" << k.line << ": photo '" << k.image
                  << "' is not in this flight (pick of " << p.name << " left out)\n";
        ++*skipped;
        continue;
      }
      cp.picks.emplace_back(index, k.pixel);
    }
    if (!cp.picks.empty()) out.push_back(cp);
  }
  return out;
}

// The site file's areas in this run's site frame (through WGS 84 when the
// run's frame is not the site file's).
void LoadAreas(const Args& args, const std::optional<SiteCrs>& crs, SurfaceState* st) {
  st->areas_loaded = true;
  if (args.site.empty()) return;
  const io::SiteFile site = io::LoadSiteFile(args.site);
  if (!crs)
    throw InvalidArgument(
        Message(args.site, ": areas need a georeferenced block (this one is in a model frame)"));
  const SiteCrs from(site.crs);
  auto convert = [&](const std::vector<Eigen::Vector2d>& poly) {
    dense::Polygon out;
    for (const Eigen::Vector2d& v : poly) {
      const Eigen::Vector3d p =
          crs->SiteFromWgs84(from.Wgs84FromSite(Eigen::Vector3d(v.x(), v.y(), 0.0)));
      out.emplace_back(p.x(), p.y());
    }
    return out;
  };
  if (site.outline.size() >= 3) st->moving.push_back(convert(site.outline));
  for (const auto& p : site.stable_areas) st->stable.push_back(convert(p));
}

std::string Seconds(const std::map<std::string, double>& s) {
  std::string out;
  for (const auto& [k, v] : s)
    out += Message(out.empty() ? "" : ", ", k, " ", std::round(v * 10) / 10, " s");
  return out;
}

// The DoD of flight k against the reference (written beside its surface).
// Returns false (named on stderr) when the flights cannot be compared.
bool FlightChangeStage(int k, const io::GeoRaster& dem, const flight::FlightFrame& frame,
                       const std::string& dir, const SurfaceState& st,
                       flight::FlightChangeSummary* summary) {
  flight::FlightChangeInput in;
  in.reference = &*st.reference;
  in.after = &dem;
  in.stable = st.stable;
  in.moving = st.moving;
  in.stable_name = st.stable.empty() ? "the ground outside areas.outline" : "areas.stable";
  try {
    const flight::FlightChange c = flight::CompareFlights(in);
    io::WriteGeoTiff(Message(dir, "/", dense::EpochChangeFileName(k)),
                     flight::InCrs(c.result.change, frame));
    *summary = c.summary;
  } catch (const InvalidArgument& e) {
    std::cerr << "process_flight: flight " << k << ": change against " << st.reference_name << ": "
              << e.what() << "\n";
    return false;
  }
  const dense::Coregistration& c = summary->dem.coregistration;
  std::printf(
      "flight %d: change against %s: shift (%.3f +- %.3f, %.3f +- %.3f) m, vertical %.3f +- %.3f "
      "m, stable "
      "median dz %.4f m, NMAD %.3f m, flagged %.2f %% of stable and %.2f %% of %d common cells, "
      "held-out stable cells flagged %.2f %% of %d (LoD by slope x roughness, %d bins), gain "
      "%.1f +- "
      "%.1f m3, loss %.1f +- %.1f m3\n",
      k, st.reference_name.c_str(), c.shift.x(), c.shift_sigma.x(), c.shift.y(), c.shift_sigma.y(),
      c.vertical, c.level_sigma, summary->stable_median, summary->stable_nmad,
      100 * summary->stable_flagged, 100 * summary->flagged, summary->common_cells,
      100 * summary->dem.holdout_flagged, summary->dem.holdout_cells,
      static_cast<int>(summary->dem.error_model.bins.size()), summary->dem.volume_fill,
      summary->dem.sigma_fill, summary->dem.volume_cut, summary->dem.sigma_cut);
  return true;
}

// Surface, orthophoto and cloud of an oriented flight, and its change against
// the reference. Returns false (named on stderr) when a part failed.
bool DenseStage(int k, const flight::FlightPhotos& photos, const flight::FlightResult& result,
                const Args& args, const std::optional<SiteCrs>& crs,
                const flight::FlightFrame& frame, SurfaceState* st) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::string dir = Message(args.out, "/flight_", k);
  try {
    if (!st->areas_loaded) LoadAreas(args, crs, st);
    if (!st->reference && !args.reference.empty()) {
      st->reference_name = ReferencePath(args.reference);
      st->reference =
          flight::InSite(io::ReadGeoTiff(st->reference_name), frame, st->reference_name);
    }
    const Eigen::Vector4d region =
        st->reference ? dense::RegionOf(*st->reference) : Eigen::Vector4d::Zero();
    flight::FlightSurfaceOptions o = args.surface;
    if (st->reference) o.cell_size = st->reference->cell_size;
    flight::FlightSurface s = flight::MeasureFlightSurface(photos, result, o, region);
    io::WriteGeoTiff(Message(dir, "/", dense::EpochSurfaceFileName(k)),
                     flight::InCrs(s.dem, frame));
    io::WriteGeoTiff(Message(dir, "/", dense::EpochOrthoFileName(k)),
                     flight::InCrs(s.ortho, frame));
    flight::WriteCloudPly(s.cloud, dir + "/cloud.ply");
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    s.summary.seconds["total"] = seconds;
    std::printf(
        "flight %d: surface %d of %d cells at %.2f m, %d points from %d of %d pairs, %.1f s (%s), "
        "peak %.2f GB\n",
        k, s.summary.dense.filled_cells, s.summary.dense.cells, s.summary.cell_size,
        s.summary.dense.points, s.summary.dense.pairs_measured, s.summary.dense.candidate_pairs,
        seconds, Seconds(s.summary.seconds).c_str(), PeakResidentGb());
    std::fflush(stdout);
    bool ok = true;
    flight::FlightChangeSummary change;
    const bool compare = static_cast<bool>(st->reference);
    if (compare) ok = FlightChangeStage(k, s.dem, frame, dir, *st, &change);
    flight::WriteSurfaceReport(s.summary, compare && ok ? &change : nullptr, st->reference_name,
                               dir + "/surface_report.json", dir + "/surface_report.md");
    if (!st->reference) {
      st->reference = std::move(s.dem);
      st->reference_name = Message("flight_", k, "/", dense::EpochSurfaceFileName(k));
    }
    return ok;
  } catch (const InvalidArgument& e) {
    std::cerr << "process_flight: flight " << k << ": dense stage: " << e.what() << "\n";
    return false;
  }
}

struct FlightOutcome {
  bool ok = false;
  int skipped = 0;
};

// Site positions of the photos from the geo list (nullopt where it has none).
std::vector<std::optional<Eigen::Vector3d>> GeoPositions(const io::GeoList& geo, const SiteCrs& crs,
                                                         const flight::FlightPhotos& photos) {
  SiteCrsOptions o;
  o.crs = geo.crs;
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteCrs from(o);  // site = the geo list's CRS
  const bool same = geo.crs == crs.options().crs;
  std::vector<std::optional<Eigen::Vector3d>> out(photos.photos.size());
  for (const io::GeoEntry& e : geo.entries)
    for (size_t i = 0; i < photos.photos.size(); ++i)
      if (photos.photos[i].name == e.image)
        out[i] = same ? crs.SiteFromCrs(e.geo) : crs.SiteFromWgs84(from.Wgs84FromSite(e.geo));
  return out;
}

// A flight with GNSS where some photos have none: each named (it is oriented
// from its tie points only, without a position prior).
void NameWithoutPosition(const flight::FlightPhotos& photos,
                         const std::vector<std::optional<Eigen::Vector3d>>& gnss) {
  const auto with = std::count_if(gnss.begin(), gnss.end(), [](const auto& g) { return g; });
  if (with == 0) return;
  for (size_t i = 0; i < gnss.size() && i < photos.photos.size(); ++i)
    if (!gnss[i])
      std::cerr << "process_flight: " << photos.photos[i].name
                << ": no GNSS position (oriented from its tie points only, no position prior)\n";
}

FlightOutcome ProcessFlight(int k, const std::string& folder, const Args& args,
                            const std::optional<io::GcpList>& gcp,
                            const std::optional<io::GeoList>& geo, std::optional<SiteCrs>* crs,
                            flight::FlightFrame* frame, SurfaceState* surface) {
  const auto t0 = std::chrono::steady_clock::now();
  FlightOutcome outcome;
  const std::vector<std::string> paths = flight::ListPhotoFolder(folder);
  const flight::FlightPhotos photos = flight::ReadFlightPhotos(paths, args.photo);
  for (const auto& s : photos.skipped)
    std::cerr << "process_flight: " << s.path << ": " << s.reason << "\n";
  outcome.skipped += static_cast<int>(photos.skipped.size());
  if (k == 1) *crs = MakeFrame(args, gcp, geo, photos, frame);
  // One progress line per stage (features k/n, pairs k/n, oriented k/n):
  // redrawn on a terminal, else a plain line at its start, its end and
  // every half minute between.
  ProgressLine line(stderr);
  std::set<std::string> started;
  const flight::StageProgress progress = [&](const char* stage, int done, int total) {
    const bool first = started.insert(stage).second;
    if (!line.Due(first || done == total)) return;
    line.Show(Message("process_flight: flight ", k, ": ", stage, " ", done, "/", total));
  };
  flight::FlightMatchingOptions mo;
  mo.threads = args.threads;
  const flight::FlightTies ties = flight::MatchFlight(photos, mo, progress);
  line.End();
  for (const auto& u : ties.unreadable) std::cerr << "process_flight: " << u << "\n";
  flight::FlightInput input;
  input.photos = &photos;
  input.ties = &ties;
  if (*crs && geo) {
    input.gnss_in_site = GeoPositions(*geo, **crs, photos);
  } else if (*crs) {
    for (const auto& p : photos.photos) {
      if (!p.exif.has_gps) {
        input.gnss_in_site.emplace_back();
        continue;
      }
      const double h = p.exif.has_gps_altitude ? p.exif.gps.height_m : 0.0;
      input.gnss_in_site.emplace_back((*crs)->SiteFromWgs84(
          Eigen::Vector3d(p.exif.gps.longitude_deg, p.exif.gps.latitude_deg, h)));
    }
  }
  NameWithoutPosition(photos, input.gnss_in_site);
  if (*crs) {
    if (gcp) input.control = ControlPoints(*gcp, **crs, photos, args, &outcome.skipped);
  }
  flight::FlightOrientationOptions oo;
  oo.gnss_sigma_horizontal_m = args.gnss_sigma;
  oo.gnss_sigma_vertical_m =
      args.gnss_sigma * capture::kExifGnssSigmaVertical / capture::kExifGnssSigmaHorizontal;
  oo.leave_one_out = args.leave_one_out;
  const flight::FlightResult result = flight::OrientFlight(input, oo, progress);
  line.End();
  const flight::FlightSummary& s = result.summary;
  for (const auto& n : s.not_oriented) std::cerr << "process_flight: not oriented: " << n << "\n";
  outcome.skipped += static_cast<int>(s.not_oriented.size());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  flight::FlightReportInput rep{k,       folder, &photos, &ties,
                                &result, *frame, seconds, PeakResidentGb()};
  flight::WriteFlightOutputs(rep, Message(args.out, "/flight_", k));
  std::printf("flight %d: %d of %zu photos oriented, %d points, reprojection rms %.3f px, %.1f s\n",
              k, s.oriented, paths.size(), s.points, s.rms_px, seconds);
  if (!input.control.empty())
    std::printf("flight %d: control rms %.3f m over %zu points, check rms %.3f m over %zu points\n",
                k, s.control_rms, s.control.size(), s.check_rms, s.check.size());
  std::fflush(stdout);
  if (!s.success) std::cerr << "process_flight: flight " << k << ": " << s.message << "\n";
  if (s.success && args.dense && !DenseStage(k, photos, result, args, *crs, *frame, surface))
    ++outcome.skipped;
  // Half of the flight's own photos: another camera's photos in the folder
  // (a second flight) and unreadable files are named as skipped above.
  const size_t own = photos.photos.size();
  outcome.ok = s.success && 2 * s.oriented >= static_cast<int>(own);
  if (s.success && !outcome.ok)
    std::cerr << "process_flight: flight " << k << ": only " << s.oriented << " of " << own
              << " photos oriented (fewer than half)\n";
  return outcome;
}

}  // namespace

int main(int argc, char** argv) {
  KeepFreedMemoryForReuse();
  Args args;
  try {
    if (!ParseArgs(argc, argv, &args)) return 0;
  } catch (const Error& e) {
    std::cerr << "process_flight: " << e.what() << "\n" << kUsage;
    return 1;
  }
  int failed = 0, skipped = 0;
  try {
    io::CheckFolderWritable(args.out, "--out");  // fail early: before any photo is read
    RefuseEarlierResults(args);
    std::optional<io::GcpList> gcp;
    if (!args.gcp.empty()) gcp = io::ReadGcpList(args.gcp);
    if (gcp && !io::HasHeights(*gcp))
      std::cerr << "process_flight: " << gcp->path
                << ": every height is 0: taken as not given (horizontal control;"
                << " heights held within " << io::kNoHeightSigma << " m of 0)\n";
    std::optional<io::GeoList> geo;
    if (!args.geo.empty()) geo = io::ReadGeoList(args.geo);
    std::optional<SiteCrs> crs;
    flight::FlightFrame frame;
    SurfaceState surface;
    for (size_t k = 0; k < args.folders.size(); ++k) {
      const FlightOutcome o = ProcessFlight(static_cast<int>(k + 1), args.folders[k], args, gcp,
                                            geo, &crs, &frame, &surface);
      failed += !o.ok;
      skipped += o.skipped;
    }
  } catch (const std::exception& e) {
    std::cerr << "process_flight: " << e.what() << "\n";
    return 1;
  }
  if (failed) return 1;
  return skipped ? 2 : 0;
}
