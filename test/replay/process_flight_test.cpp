// process_flight (src/tools/process_flight.cpp) on real photos nobody here
// made: four GNSS-tagged photos of ../shared/data/uav_real_caliterra (two
// neighbouring strips flown in opposite directions), run as a crew runs it.
// Truth: the photos' own EXIF GNSS (a consumer receiver: metres) for the
// camera centres; the exported COLMAP model read back for its counts; bad
// input named with the documented exit status.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
// exiv2 0.27 still uses std::auto_ptr in its headers.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdeprecated-declarations"
#include <exiv2/exiv2.hpp>
#pragma GCC diagnostic pop
#include <opencv2/imgproc.hpp>

#include "replay_test_util.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/common/site_crs.h"
#include "slope_monitor/core/io/geotiff.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using replay_test::ReadFile;
using replay_test::Spawn;
using replay_test::Wait;

const fs::path kCaliterra =
    fs::path(SM_SOURCE_DIR) / ".." / "shared" / "data" / "uav_real_caliterra";
const fs::path kCopr =
    fs::path(SM_SOURCE_DIR) / ".." / "shared" / "data" / "uav_real_copr" / "images";
const std::string kTool = std::string(SM_TOOL_DIR) + "/process_flight";

fs::path Scratch(const std::string& name) {
  return replay_test::Scratch("process_flight_test", name);
}

int RunTool(const std::vector<std::string>& args, const fs::path& dir) {
  std::vector<std::string> argv{kTool};
  argv.insert(argv.end(), args.begin(), args.end());
  return Wait(Spawn(argv, dir));
}

std::vector<std::vector<std::string>> ReadCsv(const fs::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(p);
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> row;
    std::stringstream ss(line);
    for (std::string f; std::getline(ss, f, ',');) row.push_back(f);
    rows.push_back(row);
  }
  return rows;
}

// The dense stage (on by default): a DEM and an RGB orthophoto on its grid
// as GeoTIFFs in the run's EPSG CRS, placed where the photos' EXIF GNSS is
// (transformed to WGS 84 with PROJ; the photos look obliquely, so the ground
// lies up to ~100 m beside the cameras), heights that agree with the
// adjustment's own tie points (another method: sparse, least squares), and
// the cloud.
void ExpectDenseOutputs(const std::string& out, const fs::path& f1) {
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      out, m,
      std::regex(
          R"(flight 1: surface (\d+) of (\d+) cells at ([0-9.]+) m, (\d+) points from (\d+) of (\d+) pairs)")))
      << out;
  EXPECT_GT(std::stoi(m[1]), 1000);
  EXPECT_GE(std::stoi(m[5]), 2);
  const io::GeoRaster dem = io::ReadGeoTiff((f1 / "surface_e01.tif").string());
  const io::GeoRaster ortho = io::ReadGeoTiff((f1 / "ortho_e01.tif").string());
  EXPECT_EQ(dem.epsg, 32614);
  EXPECT_EQ(ortho.epsg, 32614);
  EXPECT_EQ(dem.band_names[0], "height");
  EXPECT_EQ(ortho.band_names, (std::vector<std::string>{"red", "green", "blue"}));
  EXPECT_DOUBLE_EQ(ortho.origin_x, dem.origin_x);
  EXPECT_DOUBLE_EQ(ortho.origin_y, dem.origin_y);
  EXPECT_NEAR(ortho.cell_size * 4, dem.cell_size, 1e-9);
  int filled = 0;
  for (float v : ortho.bands[1]) filled += !ortho.IsNoData(v);
  EXPECT_GT(filled, 1000 * 16);
  // The DEM's centre in WGS 84 against the mean EXIF position of the photos.
  SiteCrsOptions o;
  o.crs = "EPSG:32614";
  o.frame = SiteCrsOptions::Frame::kShiftedCrs;
  const SiteCrs crs(o);
  const Eigen::Vector3d centre =
      crs.Wgs84FromSite(Eigen::Vector3d(dem.origin_x + dem.width * dem.cell_size / 2,
                                        dem.origin_y - dem.height * dem.cell_size / 2, 0.0));
  double lon = 0, lat = 0;
  for (const char* n : {"IMG_9377.jpg", "IMG_9378.jpg", "IMG_9387.jpg", "IMG_9388.jpg"}) {
    const capture::ExifInfo e = capture::ReadExif((kCaliterra / n).string());
    lon += e.gps.longitude_deg / 4;
    lat += e.gps.latitude_deg / 4;
  }
  EXPECT_NEAR(centre.x(), lon, 0.0015);  // ~150 m
  EXPECT_NEAR(centre.y(), lat, 0.0015);
  // Tie points (points.ply, site frame; crs.txt: site = CRS - origin) against the DEM.
  std::stringstream crs_txt(ReadFile(f1 / "crs.txt"));
  double ox = 0, oy = 0;
  for (std::string line; std::getline(crs_txt, line);)
    if (line.rfind("origin:", 0) == 0) std::stringstream(line.substr(7)) >> ox >> oy;
  std::ifstream ply(f1 / "points.ply");
  std::string line;
  while (std::getline(ply, line) && line != "end_header") {
  }
  std::vector<double> dz;
  int inside = 0;
  for (double x, y, z; std::getline(ply, line) && std::stringstream(line) >> x >> y >> z;) {
    int r, c;
    if (!dem.CellOf(x + ox, y + oy, &r, &c)) continue;
    ++inside;
    const double h = dem.Interpolate(0, x + ox, y + oy);
    if (!std::isnan(h)) dz.push_back(h - z);
  }
  ASSERT_GT(inside, 1000);
  EXPECT_GT(dz.size(), inside / 2u);
  std::nth_element(dz.begin(), dz.begin() + dz.size() / 2, dz.end());
  EXPECT_LT(std::abs(dz[dz.size() / 2]), 0.2);  // 8 photos: -0.03 m, NMAD 0.41 m
  EXPECT_NE(ReadFile(f1 / "cloud.ply").find("format binary_little_endian 1.0"), std::string::npos);
  const auto surface = nlohmann::json::parse(ReadFile(f1 / "surface_report.json"));
  EXPECT_TRUE(surface.at("seconds").contains("decode")) << surface.dump();
}

// The folder a crew brings: four real photos, three photos of another
// flight (another camera, another height: copr), one photo of another size
// without EXIF (written by OpenCV) and a zero-byte file. The larger flight
// is oriented (4 of its 4 photos: more than half, though 4 of 9 files) and
// every other photo is named.
TEST(ProcessFlight, RealGnssFlightIsOrientedAndExportedAndBadPhotosAreNamed) {
  ASSERT_TRUE(fs::is_directory(kCaliterra))
      << kCaliterra << " (../shared/data beside the repository)";
  const fs::path dir = Scratch("caliterra");
  const fs::path photos = dir / "photos";
  fs::create_directories(photos);
  for (const char* n : {"IMG_9377.jpg", "IMG_9378.jpg", "IMG_9387.jpg", "IMG_9388.jpg"})
    fs::create_symlink(kCaliterra / n, photos / n);
  const std::vector<std::string> other = {"IMG_0022.jpg", "IMG_0025.jpg", "IMG_0028.jpg"};
  for (const std::string& n : other) fs::create_symlink(kCopr / n, photos / n);
  cv::Mat small;
  cv::resize(cv::imread((kCaliterra / "IMG_9379.jpg").string()), small, cv::Size(800, 600));
  cv::imwrite((photos / "IMG_small.jpg").string(), small);
  std::ofstream(photos / "IMG_empty.jpg").close();

  const int status = RunTool({"--photos", photos.string(), "--out", (dir / "out").string()}, dir);
  const std::string out = ReadFile(dir / "stdout"), err = ReadFile(dir / "stderr");
  EXPECT_EQ(status, 2) << err;  // oriented, but inputs were left out
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      out, m,
      std::regex(
          R"(flight 1: 4 of 9 photos oriented, (\d+) points, reprojection rms ([0-9.]+) px, [0-9.]+ s\n)")))
      << out << err;
  EXPECT_GT(std::stoi(m[1]), 1000);
  EXPECT_LT(std::stod(m[2]),
            1.0);  // COLMAP 3.8 on all eight: 0.87 px mean (doc/uav_real_flight.md)
  EXPECT_NE(err.find("IMG_empty.jpg: cannot be read as a photo"), std::string::npos) << err;
  EXPECT_NE(err.find("IMG_small.jpg: no focal length in its EXIF"), std::string::npos) << err;
  for (const std::string& n : other)
    EXPECT_NE(err.find(n + ": another camera or size (Canon Canon EOS DIGITAL REBEL XSi "
                           "4272x2848 f=30 mm) than the flight's 4 photos"),
              std::string::npos)
        << err;

  const fs::path f1 = dir / "out" / "flight_1";
  EXPECT_NE(ReadFile(f1 / "crs.txt").find("crs: EPSG:32614"),
            std::string::npos);  // UTM zone of the photos
  const std::string images = ReadFile(f1 / "sparse" / "images.txt");
  EXPECT_NE(images.find("# Number of images: 4"), std::string::npos);
  EXPECT_NE(ReadFile(f1 / "sparse" / "cameras.txt").find("1 FULL_OPENCV 4000 3000 "),
            std::string::npos);
  EXPECT_NE(
      ReadFile(f1 / "sparse" / "points3D.txt").find("# Number of points: " + std::string(m[1])),
      std::string::npos);
  EXPECT_NE(ReadFile(f1 / "report.json").find("\"datum\": \"GNSS of 4 photos\""),
            std::string::npos);
  // Camera centres against the photos' GNSS (same frame: crs.txt): the
  // adjustment weighs them at 3 m horizontally, so they stay within metres.
  const auto rows = ReadCsv(f1 / "cameras.csv");
  ASSERT_EQ(rows.size(), 5u);
  const std::string report = ReadFile(f1 / "report.md");
  EXPECT_NE(report.find("| photos oriented | 4 of 4 (5 skipped) |"), std::string::npos) << report;
  for (size_t r = 1; r < rows.size(); ++r) {
    ASSERT_EQ(rows[r].size(), 15u);
    for (int c = 7; c <= 9; ++c)
      EXPECT_GT(std::stod(rows[r][c]), 0.0) << rows[r][0];  // sigma from the covariance
    EXPECT_LT(std::stod(rows[r][7]), 5.0) << rows[r][0];
  }
  // Every pair of the flight's four photos, with its tie points or why not.
  const auto pairs = ReadCsv(f1 / "pairs.csv");
  ASSERT_EQ(pairs.size(), 7u);
  EXPECT_EQ(pairs[0], (std::vector<std::string>{"photo_a", "photo_b", "tie_points",
                                                "epipolar_rms_px", "why_not_used"}));
  int tied = 0;
  for (size_t r = 1; r < pairs.size(); ++r) {
    ASSERT_EQ(pairs[r].size(), 5u);
    const int n = std::stoi(pairs[r][2]);
    EXPECT_EQ(n >= 15, pairs[r][4] == "\"\"") << pairs[r][0] << " " << pairs[r][1];
    if (n < 15) continue;
    ++tied;
    EXPECT_LT(std::stod(pairs[r][3]), 1.0);
  }
  EXPECT_NE(ReadFile(f1 / "report.json").find("\"pairs_tied\": " + std::to_string(tied)),
            std::string::npos);
  ExpectDenseOutputs(out, f1);
  replay_test::ExpectStrictJson(dir / "out");

  // The same --out again: refused in one line naming the earlier results,
  // which stay as they were; --overwrite goes on (here to the photos).
  const std::string before = ReadFile(f1 / "report.json");
  EXPECT_EQ(RunTool({"--photos", photos.string(), "--out", (dir / "out").string()}, dir), 1);
  EXPECT_EQ(ReadFile(dir / "stderr"),
            "process_flight: --out " + (dir / "out").string() +
                " holds an earlier run's results (" + (f1 / "report.json").string() +
                "); give --overwrite to replace them, or another --out\n");
  EXPECT_EQ(ReadFile(f1 / "report.json"), before);
  EXPECT_EQ(
      RunTool({"--photos", (dir / "none").string(), "--overwrite", "--out", (dir / "out").string()},
              dir),
      1);
  EXPECT_EQ(ReadFile(dir / "stderr").find("earlier run"), std::string::npos)
      << ReadFile(dir / "stderr");
}

// The camera of a phone or a DJI drone: EXIF without the focal-plane
// resolution. The eight real photos with those tags removed start from the
// prior 1.2 x the larger side (4800 px, where the EXIF gives 2904 px: 65 %
// off) and self-calibrate; truth: the principal distance the untouched
// photos reach (3177 px; the prior's run: 3168 px).
double AdjustedFocalPx(const std::string& report) {
  std::smatch m;
  EXPECT_TRUE(std::regex_search(report, m, std::regex(R"("adjusted_px": ([0-9.]+))"))) << report;
  return m.empty() ? 0.0 : std::stod(m[1]);
}

// Removes these EXIF tags from the photo (Exiv2); how many were there.
int EraseExif(const fs::path& photo, const std::vector<std::string>& keys) {
  auto image = Exiv2::ImageFactory::open(photo.string());
  image->readMetadata();
  Exiv2::ExifData& exif = image->exifData();
  int erased = 0;
  for (const std::string& key : keys) {
    const auto it = exif.findKey(Exiv2::ExifKey(key));
    if (it == exif.end()) continue;
    exif.erase(it);
    ++erased;
  }
  image->writeMetadata();
  return erased;
}

TEST(ProcessFlight, PhotosWithoutAFocalPlaneResolutionStartFromAPriorAndSelfCalibrate) {
  const fs::path dir = Scratch("no_pixel_size");
  for (const char* sub : {"exif", "phone"}) fs::create_directories(dir / sub);
  for (const auto& e : fs::directory_iterator(kCaliterra)) {
    const std::string n = e.path().filename().string();
    fs::create_symlink(kCaliterra / n, dir / "exif" / n);
    fs::copy_file(kCaliterra / n, dir / "phone" / n);
    EraseExif(dir / "phone" / n,
              {"Exif.Photo.FocalPlaneXResolution", "Exif.Photo.FocalPlaneYResolution",
               "Exif.Photo.FocalPlaneResolutionUnit"});
  }
  ASSERT_EQ(RunTool({"--photos", (dir / "exif").string(), "--no-dense", "--out",
                     (dir / "out_exif").string()},
                    dir),
            0)
      << ReadFile(dir / "stderr");
  const double truth = AdjustedFocalPx(ReadFile(dir / "out_exif" / "flight_1" / "report.json"));
  ASSERT_EQ(RunTool({"--photos", (dir / "phone").string(), "--no-dense", "--out",
                     (dir / "out_phone").string()},
                    dir),
            0)
      << ReadFile(dir / "stderr");
  const std::string out = ReadFile(dir / "stdout"), err = ReadFile(dir / "stderr");
  EXPECT_NE(out.find("flight 1: 8 of 8 photos oriented"), std::string::npos) << out;
  // Progress, one plain line per stage at its start and end (not a terminal).
  for (const char* line :
       {"flight 1: features 8/8\n", "flight 1: pairs 1/28\n", "flight 1: pairs 28/28\n",
        "flight 1: oriented 2/8\n", "flight 1: oriented 8/8\n"})
    EXPECT_NE(err.find(std::string("process_flight: ") + line), std::string::npos) << line << err;
  EXPECT_EQ(err.find('\r'), std::string::npos);
  const std::string report = ReadFile(dir / "out_phone" / "flight_1" / "report.json");
  const auto focal = nlohmann::json::parse(report).at("focal");
  EXPECT_EQ(focal.at("source"), "prior: 1.2 x the larger image side") << report;
  EXPECT_EQ(focal.at("start_px"), 4800.0) << report;
  EXPECT_NEAR(AdjustedFocalPx(report), truth, 0.02 * truth) << report;
  EXPECT_NE(ReadFile(dir / "out_phone" / "flight_1" / "report.md").find("principal distance"),
            std::string::npos);
}

// Two photos of a GNSS flight without a position (tags removed with Exiv2):
// named, oriented from their tie points, and the datum comes from the others.
TEST(ProcessFlight, PhotosWithoutGnssInAGnssFlightAreNamedAndOriented) {
  const fs::path dir = Scratch("without_gnss");
  fs::create_directories(dir / "photos");
  const std::vector<std::string> names = {"IMG_9376.jpg", "IMG_9377.jpg", "IMG_9378.jpg",
                                          "IMG_9386.jpg", "IMG_9387.jpg", "IMG_9388.jpg"};
  for (const std::string& n : names) fs::copy_file(kCaliterra / n, dir / "photos" / n);
  for (const char* n : {"IMG_9377.jpg", "IMG_9387.jpg"})
    EXPECT_EQ(EraseExif(dir / "photos" / n,
                        {"Exif.GPSInfo.GPSLatitude", "Exif.GPSInfo.GPSLongitude",
                         "Exif.GPSInfo.GPSLatitudeRef", "Exif.GPSInfo.GPSLongitudeRef"}),
              4)
        << n;
  ASSERT_EQ(RunTool({"--photos", (dir / "photos").string(), "--no-dense", "--out",
                     (dir / "out").string()},
                    dir),
            0)
      << ReadFile(dir / "stderr");
  const std::string out = ReadFile(dir / "stdout"), err = ReadFile(dir / "stderr");
  EXPECT_NE(out.find("flight 1: 6 of 6 photos oriented"), std::string::npos) << out;
  for (const char* n : {"IMG_9377.jpg", "IMG_9387.jpg"})
    EXPECT_NE(err.find(std::string("process_flight: ") + n +
                       ": no GNSS position (oriented from its tie points only"),
              std::string::npos)
        << err;
  EXPECT_EQ(err.find("IMG_9376.jpg: no GNSS"), std::string::npos) << err;
  EXPECT_NE(
      ReadFile(dir / "out" / "flight_1" / "report.json").find("\"datum\": \"GNSS of 4 photos\""),
      std::string::npos);
}

TEST(ProcessFlight, BadInputIsNamedWithExitOne) {
  const fs::path dir = Scratch("bad");
  fs::create_directories(dir / "empty");
  EXPECT_EQ(RunTool({"--photos", (dir / "empty").string(), "--out", (dir / "out").string()}, dir),
            1);
  EXPECT_NE(ReadFile(dir / "stderr").find("empty: holds no photo"), std::string::npos)
      << ReadFile(dir / "stderr");
  EXPECT_EQ(RunTool({"--photos", (dir / "nowhere").string(), "--out", (dir / "out").string()}, dir),
            1);
  EXPECT_NE(ReadFile(dir / "stderr").find("nowhere: no such folder"), std::string::npos);
  EXPECT_EQ(RunTool({"--out", (dir / "out").string()}, dir), 1);
  EXPECT_NE(ReadFile(dir / "stderr").find("no --photos DIR given"), std::string::npos);
  EXPECT_EQ(RunTool({"--help"}, dir), 0);
  EXPECT_NE(ReadFile(dir / "stdout").find("usage: process_flight"), std::string::npos);

  // One real photo, a gcp list with a CRS PROJ does not know, then one that
  // names a photo not in the flight.
  fs::create_directories(dir / "one");
  fs::create_symlink(kCaliterra / "IMG_9377.jpg", dir / "one" / "IMG_9377.jpg");
  std::ofstream(dir / "bad_crs.txt") << "EPSG:999999\n1 2 3 4 5 IMG_9377.jpg p1\n";
  EXPECT_EQ(RunTool({"--photos", (dir / "one").string(), "--gcp", (dir / "bad_crs.txt").string(),
                     "--out", (dir / "out").string()},
                    dir),
            1);
  EXPECT_NE(ReadFile(dir / "stderr").find("EPSG:999999"), std::string::npos)
      << ReadFile(dir / "stderr");
  std::ofstream(dir / "gcp.txt") << "EPSG:32614\n500000 4000000 10 100 200 IMG_0001.jpg p1\n";
  EXPECT_EQ(RunTool({"--photos", (dir / "one").string(), "--gcp", (dir / "gcp.txt").string(),
                     "--out", (dir / "out").string()},
                    dir),
            1);  // one photo orients nothing
  const std::string err = ReadFile(dir / "stderr");
  EXPECT_NE(err.find("gcp.txt:2: photo 'IMG_0001.jpg' is not in this flight"), std::string::npos)
      << err;
  EXPECT_NE(ReadFile(dir / "stdout").find("flight 1: 0 of 1 photos oriented"), std::string::npos);
  EXPECT_NE(err.find("flight 1: no start pair"), std::string::npos) << err;

  // Fail early (issue 38): an --out that cannot be written is named before a photo is read.
  std::ofstream(dir / "file") << "x";
  const std::string out = (dir / "file" / "out").string();
  EXPECT_EQ(RunTool({"--photos", (dir / "one").string(), "--out", out}, dir), 1);
  EXPECT_NE(ReadFile(dir / "stderr")
                .find("process_flight: --out '" + out + "' cannot be created: Not a directory"),
            std::string::npos)
      << ReadFile(dir / "stderr");
  EXPECT_EQ(ReadFile(dir / "stdout").find("flight 1:"), std::string::npos)
      << "processed before failing";
}

}  // namespace
}  // namespace slope_monitor
