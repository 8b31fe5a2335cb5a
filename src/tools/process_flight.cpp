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
// with sigma, report.json / report.md, crs.txt).
//
// Frame: the CRS of the gcp list (its first line), else the site file's,
// else the UTM zone of the first photo with GNSS (EPSG:326NN / 327NN); the
// site frame is that CRS minus a rounded origin (crs.txt). Without control
// points or GNSS the block stays in a model frame (said in the report).
//
// Exit status: 0 every flight oriented at least half its photos and every
// input was used; 2 as 0 but some inputs were left out (photos skipped or
// not oriented, picks naming photos not in the flight; each named on
// stderr); 1 a flight oriented fewer than half its photos, nothing was
// produced, or the command line / a file is wrong (one line on stderr).
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/flight/flight_export.h"
#include "slope_monitor/core/flight/flight_orientation.h"
#include "slope_monitor/core/io/gcp_list.h"
#include "slope_monitor/core/io/site_file.h"

using namespace slope_monitor;

namespace {

// [m] sigma of the height of a control point whose list gives none.
constexpr double kNoHeightSigma = 10.0;

const char* kUsage =
    "usage: process_flight --photos DIR [--photos DIR2 ...] [--gcp FILE] [--check NAME[,NAME...]]\n"
    "                      [--site FILE] [--gcp-sigma M] [--gnss-sigma M] [--pixel-size MM] [--focal MM]\n"
    "                      [--no-leave-one-out] [--threads N] --out DIR\n"
    "  orients each folder of UAV photos (one flight each) and writes DIR/flight_<k>/\n";

struct Args {
  std::vector<std::string> folders;
  std::string gcp, site, out;
  std::set<std::string> check;
  double gcp_sigma = 0.05, gnss_sigma = 3.0;
  flight::FlightPhotoOptions photo;
  bool leave_one_out = true;
  int threads = 0;
};

double Number(const std::string& flag, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end || !std::isfinite(x) || x < 0.0)
    throw InvalidArgument(Message(flag, " '", v, "' is not a number >= 0"));
  return x;
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
    if (i + 1 >= argc) throw InvalidArgument(Message(f, " needs a value (or is unknown)"));
    const std::string v = argv[++i];
    if (f == "--photos") a->folders.push_back(v);
    else if (f == "--gcp") a->gcp = v;
    else if (f == "--site") a->site = v;
    else if (f == "--out") a->out = v;
    else if (f == "--gcp-sigma") a->gcp_sigma = Number(f, v);
    else if (f == "--gnss-sigma") a->gnss_sigma = Number(f, v);
    else if (f == "--pixel-size") a->photo.pixel_size_mm = Number(f, v);
    else if (f == "--focal") a->photo.focal_length_mm = Number(f, v);
    else if (f == "--threads") a->threads = static_cast<int>(Number(f, v));
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
                                 const flight::FlightPhotos& first, flight::FlightFrame* frame) {
  SiteCrsOptions o;
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  if (gcp) {
    o.crs = gcp->crs;
    const Eigen::Vector3d g = gcp->points.front().geo;
    o.origin = Eigen::Vector3d(std::round(g.x() / 100.0) * 100.0, std::round(g.y() / 100.0) * 100.0, 0.0);
  } else if (!args.site.empty()) {
    o = io::LoadSiteFile(args.site).crs;
  } else {
    const flight::FlightPhoto* p = nullptr;
    for (const auto& q : first.photos)
      if (!p && q.exif.has_gps) p = &q;
    if (!p) return std::nullopt;
    o.crs = UtmEpsg(p->exif.gps.longitude_deg, p->exif.gps.latitude_deg);
    SiteCrs probe(o);
    const Eigen::Vector3d u = probe.CrsFromSite(probe.SiteFromWgs84(
        Eigen::Vector3d(p->exif.gps.longitude_deg, p->exif.gps.latitude_deg, 0.0)));
    o.origin = Eigen::Vector3d(std::round(u.x() / 100.0) * 100.0, std::round(u.y() / 100.0) * 100.0, 0.0);
  }
  SiteCrs crs(o);  // throws naming the CRS when PROJ does not know it
  frame->crs = o.crs;
  frame->origin = o.origin;
  frame->wkt = crs.CrsWkt();
  return crs;
}

// false: every height of the list is 0 (a list without heights).
bool HasHeights(const io::GcpList& gcp) {
  for (const io::GcpPoint& p : gcp.points)
    if (p.geo.z() != 0.0) return true;
  return false;
}

// Control points of the gcp list in this flight's photos; picks naming a
// photo not in the flight are named on stderr (*skipped counts them).
std::vector<flight::FlightControlPoint> ControlPoints(const io::GcpList& gcp, const SiteCrs& crs,
                                                      const flight::FlightPhotos& photos, const Args& args,
                                                      int* skipped) {
  std::vector<flight::FlightControlPoint> out;
  const double s = args.gcp_sigma;
  const bool heights = HasHeights(gcp);
  for (const io::GcpPoint& p : gcp.points) {
    flight::FlightControlPoint cp;
    cp.name = p.name;
    cp.site = crs.SiteFromCrs(p.geo);
    const double sz = heights ? 2.0 * s : kNoHeightSigma;
    cp.covariance = Eigen::Vector3d(s * s, s * s, sz * sz).asDiagonal();
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

double PeakMemoryGb() {
  struct rusage u;
  getrusage(RUSAGE_SELF, &u);
  return u.ru_maxrss / 1024.0 / 1024.0;
}

struct FlightOutcome {
  bool ok = false;
  int skipped = 0;
};

FlightOutcome ProcessFlight(int k, const std::string& folder, const Args& args, const std::optional<io::GcpList>& gcp,
                            std::optional<SiteCrs>* crs, flight::FlightFrame* frame) {
  const auto t0 = std::chrono::steady_clock::now();
  FlightOutcome outcome;
  const std::vector<std::string> paths = flight::ListPhotoFolder(folder);
  const flight::FlightPhotos photos = flight::ReadFlightPhotos(paths, args.photo);
  for (const auto& s : photos.skipped) std::cerr << "process_flight: " << s.path << ": " << s.reason << "\n";
  outcome.skipped += static_cast<int>(photos.skipped.size());
  if (k == 1) *crs = MakeFrame(args, gcp, photos, frame);
  flight::FlightMatchingOptions mo;
  mo.threads = args.threads;
  const flight::FlightTies ties = flight::MatchFlight(photos, mo);
  for (const auto& u : ties.unreadable) std::cerr << "process_flight: " << u << "\n";
  flight::FlightInput input;
  input.photos = &photos;
  input.ties = &ties;
  if (*crs) {
    for (const auto& p : photos.photos) {
      if (!p.exif.has_gps) {
        input.gnss_in_site.emplace_back();
        continue;
      }
      const double h = p.exif.has_gps_altitude ? p.exif.gps.height_m : 0.0;
      input.gnss_in_site.emplace_back(
          (*crs)->SiteFromWgs84(Eigen::Vector3d(p.exif.gps.longitude_deg, p.exif.gps.latitude_deg, h)));
    }
    if (gcp) input.control = ControlPoints(*gcp, **crs, photos, args, &outcome.skipped);
  }
  flight::FlightOrientationOptions oo;
  oo.gnss_sigma_horizontal_m = args.gnss_sigma;
  oo.gnss_sigma_vertical_m = 2.0 * args.gnss_sigma;
  oo.leave_one_out = args.leave_one_out;
  const flight::FlightResult result = flight::OrientFlight(input, oo);
  const flight::FlightSummary& s = result.summary;
  for (const auto& n : s.not_oriented) std::cerr << "process_flight: not oriented: " << n << "\n";
  outcome.skipped += static_cast<int>(s.not_oriented.size());
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  flight::FlightReportInput rep{k, folder, &photos, &ties, &result, *frame, seconds, PeakMemoryGb()};
  flight::WriteFlightOutputs(rep, Message(args.out, "/flight_", k));
  std::printf("flight %d: %d of %zu photos oriented, %d points, reprojection rms %.3f px, %.1f s\n", k, s.oriented,
              paths.size(), s.points, s.rms_px, seconds);
  if (!input.control.empty())
    std::printf("flight %d: control rms %.3f m over %zu points, check rms %.3f m over %zu points\n", k,
                s.control_rms, s.control.size(), s.check_rms, s.check.size());
  std::fflush(stdout);
  if (!s.success) std::cerr << "process_flight: flight " << k << ": " << s.message << "\n";
  outcome.ok = s.success && 2 * s.oriented >= static_cast<int>(paths.size());
  if (s.success && !outcome.ok)
    std::cerr << "process_flight: flight " << k << ": only " << s.oriented << " of " << paths.size()
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
    std::optional<io::GcpList> gcp;
    if (!args.gcp.empty()) gcp = io::ReadGcpList(args.gcp);
    if (gcp && !HasHeights(*gcp))
      std::cerr << "process_flight: " << gcp->path << ": every height is 0: taken as not given (horizontal control;"
                << " heights held within " << kNoHeightSigma << " m of 0)\n";
    std::optional<SiteCrs> crs;
    flight::FlightFrame frame;
    for (size_t k = 0; k < args.folders.size(); ++k) {
      const FlightOutcome o = ProcessFlight(static_cast<int>(k + 1), args.folders[k], args, gcp, &crs, &frame);
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
