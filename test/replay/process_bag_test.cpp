// process_bag on simulated surveys (rendered at build time from
// test/replay/<name>.sim.yaml and test/rostest/<name>.sim.yaml): the truth
// checks of the former full_graph_replay and estimator_no_radio rostests (the
// latter on the estimator_restart survey without its radio topics),
// without ROS transport;
// the same reports and history byte for byte with both cores busy; and a
// kill -9 in the middle followed by a second run on the same history giving
// the numbers of an uninterrupted run, with nothing fused twice.
#include <signal.h>
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>

#include "process_bag_run.h"
#include "replay_test_util.h"
#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/SlopeDeformation.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/evaluation/deformation_truth.h"
#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using namespace process_bag_run;  // NOLINT: the test helpers
using replay_test::DumpSqlite;

// (source, epoch, point) -> how many observations of it the history holds.
std::map<std::string, int> ObservationKeys(const fs::path& db) {
  sqlite3* h = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << db;
  std::map<std::string, int> keys;
  sqlite3_exec(
      h, "SELECT source, epoch, point_id FROM observations",
      [](void* out, int, char** v, char**) {
        ++(*static_cast<std::map<std::string, int>*>(
            out))[std::string(v[0]) + "/" + v[1] + "/" + v[2]];
        return 0;
      },
      &keys, nullptr);
  sqlite3_close(h);
  return keys;
}

// A command run as a crew runs it (outputs in `dir`): its exit status and
// what it printed.
std::pair<int, std::string> Tool(const std::vector<std::string>& argv, const fs::path& dir) {
  fs::create_directories(dir);
  const int status = Wait(Spawn(argv, dir));
  return {status, ReadFile(dir / "stdout") + ReadFile(dir / "stderr")};
}

// ------------------------------------------------ full_graph_replay's truth

// The checks the full_graph_replay rostest made (dropped: doc/testing.md),
// with its tolerances.
TEST(ProcessBag, FullGraphReplayMatchesTruth) {
  const std::string name = "full_graph_replay";
  const fs::path dir = Scratch(name);
  ASSERT_EQ(RunProcessBag(name, dir, true), 0);
  const sim::SurveyTruth truth = sim::SurveyTruth::Load(Survey(name, ".truth.yaml"));

  // Target observations of every fixed-camera image (the rostest's
  // CheckTargetObservations, max_id_px 1), from the output bag.
  rosbag::Bag out((dir / "out.bag").string(), rosbag::bagmode::Read);
  std::map<std::string, int> messages;
  int images = 0, checked = 0;
  for (const rosbag::MessageInstance& m : rosbag::View(out)) {
    ++messages[m.getTopic()];
    const auto t = m.instantiate<slope_monitor::TargetObservationArray>();
    if (!t) continue;
    const sim::CameraTruth* cam = nullptr;
    for (const sim::CameraTruth& c : truth.cameras)
      if (c.name == t->camera_name) cam = &c;
    ASSERT_NE(cam, nullptr) << t->camera_name;
    const sim::ImageTruth* im = nullptr;
    for (const sim::ImageTruth& i : cam->images)
      if (std::abs(i.stamp - t->header.stamp.toSec()) < 1e-3) im = &i;
    ASSERT_NE(im, nullptr) << cam->name << "@" << t->header.stamp;
    ++images;
    std::set<std::string> seen;
    for (const auto& o : t->observations) {
      ASSERT_GE(o.id, 0) << cam->name << "@" << im->stamp << ": unidentified target";
      const std::string key = o.family + "/" + std::to_string(o.id);
      seen.insert(key);
      const sim::TargetTruth* target = truth.FindTarget(key);
      ASSERT_NE(target, nullptr) << "false ID " << key;
      Eigen::Vector2d expect;
      ASSERT_TRUE(cam->model.Project(im->exterior, target->positions.at(im->epoch), &expect));
      EXPECT_LT((Eigen::Vector2d(o.x, o.y) - expect).norm(), 1.0)
          << cam->name << "@" << im->stamp << " " << key;
      ++checked;
    }
    for (const std::string& key : im->visible)
      EXPECT_TRUE(seen.count(key)) << key << " not observed";
  }
  int truth_images = 0;
  for (const sim::CameraTruth& c : truth.cameras)
    truth_images += c.kind == "fixed" ? c.images.size() : 0;
  EXPECT_EQ(images, truth_images);
  std::cout << images << " images, " << checked
            << " identified observations checked against the truth\n";
  // Every output topic is in the output bag (fixed cameras only: their poses
  // go to /tf_static; /tf carries UAV photos' poses, and this survey has none).
  for (const char* topic :
       {"/bundle_adjuster/solution", "/bundle_adjuster/points", "/bundle_adjuster/displacements",
        "/tf_static", "/radio/radio_displacements", "/radio/phase_observations",
        "/deformation_estimator/deformation", "/deformation_estimator/markers",
        "/deformation_estimator/points", "/deformation_estimator/alerts"})
    EXPECT_GT(messages[topic], 0) << topic;

  const evaluation::DeformationEvaluation e =
      evaluation::EvaluateHistory((dir / "history.db").string(), truth);
  std::cout << evaluation::FormatTable(e);
  int monitoring = 0, radio = 0;
  double sum2 = 0.0;
  for (const auto& p : e.points) {
    const bool moving = p.truth.norm() > 0.01;
    if (p.role == "monitoring") {
      ++monitoring;
      sum2 += p.Error().squaredNorm();
      EXPECT_LE(p.NormalisedError(), 3.0) << p.id;
    }
    if (p.role == "monitoring" || p.role == "radio") {
      if (moving) EXPECT_GE(p.alert_level, 1) << p.id << " moves " << p.truth.norm() * 1e3 << " mm";
      if (!moving) EXPECT_LE(p.alert_level, 0) << p.id << " is stable";
      if (p.forecast_valid && e.true_failure_time > 0.0)
        EXPECT_LE(std::abs(p.forecast_time - e.true_failure_time), 3.0 * p.forecast_sigma) << p.id;
    }
    if (p.role == "control" || p.role == "check") EXPECT_LE(p.alert_level, 0) << p.id;
    if (p.role == "radio") {
      ++radio;
      EXPECT_LE(p.Error().norm(), 0.005) << p.id;
    }
  }
  EXPECT_GE(radio, 2);
  EXPECT_GE(monitoring, 6);
  if (monitoring > 0) EXPECT_LE(std::sqrt(sum2 / monitoring), 0.005);
  // The summary scripts/demo prints, on stdout.
  EXPECT_NE(ReadFile(dir / "stdout").find(evaluation::FormatTable(e)), std::string::npos);

  // The reports as a crew's GIS tools see them (issue 18): GDAL's own
  // gdalinfo, gdalwarp -t_srs EPSG:4326 and ogrinfo on what the run wrote.
  const fs::path reports = dir / "reports";
  const auto [info_status, info] =
      Tool({"gdalinfo", (reports / "deformation.tif").string()}, dir / "gdalinfo");
  EXPECT_EQ(info_status, 0) << info;
  EXPECT_NE(info.find("PROJCRS"), std::string::npos)
      << info;  // a projected CRS, not ENGCRS["site"]
  EXPECT_EQ(info.find("ENGCRS"), std::string::npos) << info;
  const fs::path warped = dir / "deformation_wgs84.tif";
  const auto [warp_status, warp] = Tool(
      {"gdalwarp", "-t_srs", "EPSG:4326", (reports / "deformation.tif").string(), warped.string()},
      dir / "gdalwarp");
  EXPECT_EQ(warp_status, 0) << warp;
  // The warped raster's centre lies on the site: the survey's origin is
  // 46.5 N, 8.0 E and the site is 200 m x 150 m east and north of it.
  const auto [center_status, center] = Tool({"gdalinfo", warped.string()}, dir / "gdalinfo_wgs84");
  EXPECT_EQ(center_status, 0) << center;
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(center, m, std::regex(R"(Center\s*\(\s*([-0-9.]+),\s*([-0-9.]+)\))")))
      << center;
  EXPECT_NEAR(std::stod(m[1]), 8.0 + 0.0013, 0.0015) << center;   // lon: 0-200 m east
  EXPECT_NEAR(std::stod(m[2]), 46.5 + 0.0007, 0.0008) << center;  // lat: 0-150 m north
  const auto [ogr_status, ogr] =
      Tool({"ogrinfo", "-ro", "-so", (reports / "deformation.gpkg").string()}, dir / "ogrinfo");
  EXPECT_EQ(ogr_status, 0) << ogr;
  EXPECT_NE(ogr.find("points"), std::string::npos) << ogr;
  EXPECT_NE(ogr.find("latest_displacement"), std::string::npos) << ogr;
  // Issue 38: an EPSG CRS on every raster and vector output (this local_enu
  // site's origin, 46.5 N 8.0 E, is in UTM zone 32: EPSG:32632; was a custom
  // orthographic CRS named "unknown"), times as DateTime, the GeoJSON split by
  // geometry type, and each taken to EPSG:4326 by GDAL's tools.
  const auto [srs_status, srs] =
      Tool({"gdalsrsinfo", "-o", "epsg", (reports / "deformation.tif").string()}, dir / "srsinfo");
  EXPECT_EQ(srs_status, 0) << srs;
  EXPECT_NE(srs.find("EPSG:32632"), std::string::npos) << srs;
  const auto [json_status, json] =
      Tool({"gdalinfo", "-json", (reports / "deformation.tif").string()}, dir / "gdalinfo_json");
  EXPECT_EQ(json_status, 0) << json;
  EXPECT_NE(json.find(R"(ID[\"EPSG\",32632]])"), std::string::npos) << json;
  EXPECT_NE(json.find(R"("proj:epsg":32632)"), std::string::npos) << json;
  const auto [layer_status, layer] = Tool(
      {"ogrinfo", "-ro", "-so", (reports / "deformation.gpkg").string(), "latest_displacement"},
      dir / "ogrinfo_latest");
  EXPECT_EQ(layer_status, 0) << layer;
  EXPECT_NE(layer.find("time_utc: DateTime"), std::string::npos) << layer;
  EXPECT_NE(layer.find("forecast_failure_time_utc: DateTime"), std::string::npos) << layer;
  EXPECT_NE(layer.find(R"(ID["EPSG",32632]])"), std::string::npos) << layer;
  for (const char* gpkg_layer : {"points", "change_polygons"}) {
    const auto [status, out] =
        Tool({"ogrinfo", "-ro", "-so", (reports / "deformation.gpkg").string(), gpkg_layer},
             dir / (std::string("ogrinfo_") + gpkg_layer));
    EXPECT_EQ(status, 0) << out;
    EXPECT_NE(out.find(R"(ID["EPSG",32632]])"), std::string::npos) << gpkg_layer << ": " << out;
  }
  const auto [to_wgs84_status, to_wgs84] = Tool(
      {"ogr2ogr", "-f", "GeoJSON", "-t_srs", "EPSG:4326", (dir / "latest_wgs84.geojson").string(),
       (reports / "deformation.gpkg").string(), "latest_displacement"},
      dir / "ogr2ogr");
  EXPECT_EQ(to_wgs84_status, 0) << to_wgs84;
  const std::string latest_wgs84 = ReadFile(dir / "latest_wgs84.geojson");
  EXPECT_NE(latest_wgs84.find(R"("time_utc": ")"), std::string::npos) << latest_wgs84;
  // RFC 7946 GeoJSON, one geometry type per file, nothing but "type" and "features".
  for (const auto& [file, geometry, other] :
       std::vector<std::tuple<std::string, std::string, std::string>>{
           {"deformation.geojson", "(3D Point)", "Polygon"},
           {"deformation_areas.geojson", "", "Point"}}) {
    const std::string text = ReadFile(reports / file);
    EXPECT_EQ(text.find("crs_note"), std::string::npos) << file;
    EXPECT_EQ(text.find("\"summary\""), std::string::npos) << file;
    const auto [status, out] =
        Tool({"ogrinfo", "-ro", "-so", (reports / file).string()}, dir / ("ogrinfo_" + file));
    EXPECT_EQ(status, 0) << out;
    if (!geometry.empty()) EXPECT_NE(out.find(geometry), std::string::npos) << file << ": " << out;
    EXPECT_EQ(out.find(other), std::string::npos) << file << " mixes geometry types: " << out;
  }
}

// ----------------------------------------------- estimator_no_radio's truth

// The checks of the former estimator_no_radio rostest: a bag without the
// radio topics the site's network would send (the estimator_restart survey
// recorded without /radio/...: the same photos; rendering it a second time
// with the radio off cost a survey render in every build); only targets are
// fused, each monitoring target within 3 sigma.
TEST(ProcessBag, NoRadioSurveyMatchesTruth) {
  const std::string from = "estimator_restart", name = "estimator_no_radio";
  const fs::path dir = Scratch(name);
  const std::string stem = (dir / name).string();
  int dropped = 0;
  CopySurvey(from, dir, name, [&dropped](const rosbag::MessageInstance& m, rosbag::Bag* out) {
    if (m.getTopic().rfind("/radio/", 0) == 0)
      ++dropped;
    else
      out->write(m.getTopic(), m.getTime(), m, m.getConnectionHeader());
  });
  ASSERT_GT(dropped, 0) << "the estimator_restart survey has no radio topics to leave out";
  ASSERT_TRUE(fs::exists(stem + ".site.yaml"));
  ASSERT_EQ(Wait(Spawn({SM_PROCESS_BAG, "--bag", stem + ".bag", "--database",
                        (dir / "history.db").string(), "--report-dir", (dir / "reports").string(),
                        "--site-config", stem + ".site.yaml"},
                       dir)),
            0)
      << ReadFile(dir / "stderr");
  const sim::SurveyTruth truth = sim::SurveyTruth::Load(stem + ".truth.yaml");
  const evaluation::DeformationEvaluation e =
      evaluation::EvaluateHistory((dir / "history.db").string(), truth);
  std::cout << evaluation::FormatTable(e);
  int monitoring = 0;
  for (const auto& p : e.points) {
    EXPECT_NE(p.role, "radio") << p.id;
    for (const auto& [source, count] : p.measurements)
      EXPECT_EQ(evaluation::SourceName(source), "target")
          << p.id << ": " << count << " measurement(s)";
    if (p.role == "monitoring") {
      ++monitoring;
      EXPECT_LE(p.NormalisedError(), 3.0) << p.id;
    }
  }
  EXPECT_GE(monitoring, 6);
}

// ------------------------------------------------------------- determinism

// One uninterrupted run on an idle machine of the survey the determinism and
// kill tests use (made once, shared by both).
const fs::path& QuietRun() {
  static const fs::path dir = [] {
    const fs::path d = Scratch("quiet");
    EXPECT_EQ(RunProcessBag("estimator_restart", d), 0);
    return d;
  }();
  return dir;
}

// Keeps both cores busy while it lives.
// Two busy loops at the lowest priority (nice 19): on idle cores they take
// every cycle process_bag leaves, so its threads are preempted and
// rescheduled all the time; among other work (a CI run) they yield to it
// instead of taking two cores from the other tests.
class CpuLoad {
 public:
  CpuLoad() {
    for (int i = 0; i < 2; ++i)
      pids_.push_back(
          Spawn({"/usr/bin/nice", "-n", "19", "/bin/sh", "-c", "while :; do :; done"}, "/tmp"));
  }
  ~CpuLoad() {
    for (pid_t p : pids_) {
      kill(p, SIGKILL);
      Wait(p);
    }
  }

 private:
  std::vector<pid_t> pids_;
};

// The same bag twice, the second time with both cores busy: every report
// file and the history byte for byte the same (less the wall-clock fields
// named below).
TEST(ProcessBag, SameResultsUnderCpuLoad) {
  const std::string name = "estimator_restart";
  const fs::path& quiet = QuietRun();
  const fs::path loaded = Scratch("loaded");
  {
    CpuLoad load;
    ASSERT_EQ(RunProcessBag(name, loaded), 0);
  }
  // Every report file and the history, less the wall-clock fields
  // (replay_test::WallClockFields, doc/testing.md).
  replay_test::ExpectSameResults(quiet, loaded, "idle vs loaded");
}

// ------------------------------------------------------------------ kill -9

// The last "N epochs solved" of the progress line in `stderr_file`.
int EpochsSolved(const fs::path& stderr_file) {
  const std::string text = ReadFile(stderr_file);
  const size_t at = text.rfind(" epochs solved");
  if (at == std::string::npos) return 0;
  const size_t start = text.rfind(' ', at - 1) + 1;
  return std::stoi(text.substr(start, at - start));
}

// kill -9 half-way, then a second run on the same history: the final
// numbers of an uninterrupted run (difference 0), the same observation
// counts, every (source, epoch, point) once.
TEST(ProcessBag, KillAndRerunGivesUninterruptedNumbers) {
  const std::string name = "estimator_restart";
  const fs::path& whole = QuietRun();
  const fs::path killed = Scratch("killed");
  const int total = EpochsSolved(whole / "stderr");
  ASSERT_GT(total, 4);

  const pid_t pid = Spawn(ProcessBagArgs(name, killed), killed);
  ASSERT_GT(pid, 0);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
  while (EpochsSolved(killed / "stderr") < total / 2 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  kill(pid, SIGKILL);
  EXPECT_EQ(Wait(pid), -1) << "process_bag ended before it was killed";
  const int at_kill = EpochsSolved(killed / "stderr");
  std::cout << "killed after " << at_kill << " of " << total << " epochs\n";
  EXPECT_GT(at_kill, 0);
  EXPECT_LT(at_kill, total);
  fs::rename(killed / "stderr", killed / "stderr.killed");
  ASSERT_EQ(Wait(Spawn(ProcessBagArgs(name, killed), killed)), 0) << ReadFile(killed / "stderr");

  const sim::SurveyTruth truth = sim::SurveyTruth::Load(Survey(name, ".truth.yaml"));
  const auto a = evaluation::EvaluateHistory((whole / "history.db").string(), truth);
  const auto b = evaluation::EvaluateHistory((killed / "history.db").string(), truth);
  ASSERT_EQ(a.points.size(), b.points.size());
  ASSERT_FALSE(a.points.empty());
  for (size_t i = 0; i < a.points.size(); ++i) {
    const auto& p = a.points[i];
    const auto& q = b.points[i];
    ASSERT_EQ(p.id, q.id);
    EXPECT_EQ(p.stamp, q.stamp) << p.id;
    EXPECT_EQ((p.estimate - q.estimate).norm(), 0.0) << p.id;
    EXPECT_EQ((p.covariance - q.covariance).norm(), 0.0) << p.id;
    EXPECT_EQ((p.velocity - q.velocity).norm(), 0.0) << p.id;
    EXPECT_EQ(p.alert_level, q.alert_level) << p.id;
    EXPECT_EQ(p.forecast_time, q.forecast_time) << p.id;
    EXPECT_EQ(p.measurements, q.measurements) << p.id;
  }
  EXPECT_EQ(a.fused_rms, b.fused_rms);
  const auto keys_a = ObservationKeys(whole / "history.db");
  const auto keys_b = ObservationKeys(killed / "history.db");
  EXPECT_EQ(keys_a, keys_b);
  for (const auto& [key, n] : keys_b) EXPECT_EQ(n, 1) << key << " fused " << n << " times";
}

// ------------------------------------------------------------ bad input

TEST(ProcessBag, BadInputIsNamed) {
  const fs::path dir = Scratch("bad_input");
  std::ofstream(dir / "not_a_bag.bag") << "this is not a bag\n";
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{SM_PROCESS_BAG, "--bag", (dir / "missing.bag").string()}, "missing.bag' not found"},
      {{SM_PROCESS_BAG, "--bag", (dir / "not_a_bag.bag").string()}, "not_a_bag.bag"},
      {{SM_PROCESS_BAG, "--bag", Survey("full_graph_replay", ".bag"), "--frobnicate"},
       "unknown argument '--frobnicate'"},
      {{SM_PROCESS_BAG}, "--bag FILE is required"},
      {{SM_PROCESS_BAG, "--bag", Survey("full_graph_replay", ".bag"), "--target-list",
        (dir / "none.yaml").string()},
       "none.yaml' not found"}};
  for (const auto& [args, expected] : cases) {
    EXPECT_EQ(Wait(Spawn(args, dir)), 1) << args.back();
    EXPECT_NE(ReadFile(dir / "stderr").find(expected), std::string::npos)
        << "expected '" << expected << "' in: " << ReadFile(dir / "stderr");
  }
}

// Fail early (issue 38): a report folder that cannot be written is named
// before a message is processed, exit status 1 (it was found at the end).
TEST(ProcessBag, UnwritableReportFolderIsNamedBeforeProcessing) {
  const fs::path dir = Scratch("unwritable_reports");
  std::ofstream(dir / "file") << "x";
  const std::string reports = (dir / "file" / "reports").string();
  const std::vector<std::string> args = {SM_PROCESS_BAG,
                                         "--bag",
                                         Survey("full_graph_replay", ".bag"),
                                         "--database",
                                         (dir / "history.db").string(),
                                         "--report-dir",
                                         reports};
  ASSERT_EQ(Wait(Spawn(args, dir)), 1) << ReadFile(dir / "stderr");
  const std::string err = ReadFile(dir / "stderr");
  EXPECT_NE(
      err.find("process_bag: --report-dir '" + reports + "' cannot be created: Not a directory"),
      std::string::npos)
      << err;
  EXPECT_EQ(err.find("messages of 1 bag(s)"), std::string::npos) << "processed before failing:\n"
                                                                 << err;
  EXPECT_FALSE(fs::exists(dir / "history.db")) << "the history was written before failing";
}

// A bag cut in the middle (no index): reindexed in a temporary copy, said
// with the file's name, processed up to the break; the break named at the
// end and exit status 2 (issue 38).
TEST(ProcessBag, TruncatedBagIsProcessedUpToTheBreak) {
  const fs::path dir = Scratch("truncated");
  const fs::path cut = dir / "cut.bag";
  fs::copy_file(Survey("full_graph_replay", ".bag"), cut);
  fs::resize_file(cut, fs::file_size(cut) * 6 / 10);
  // The target list and truth (radio network) beside it, as the simulator writes them.
  fs::copy_file(Survey("full_graph_replay", ".targets.yaml"), dir / "cut.targets.yaml");
  fs::copy_file(Survey("full_graph_replay", ".truth.yaml"), dir / "cut.truth.yaml");
  const std::vector<std::string> args = {SM_PROCESS_BAG,
                                         "--bag",
                                         cut.string(),
                                         "--database",
                                         (dir / "history.db").string(),
                                         "--report-dir",
                                         (dir / "reports").string()};
  // Processed up to the break, the break named, exit status 2 (input ended early; issue 38).
  ASSERT_EQ(Wait(Spawn(args, dir)), 2) << ReadFile(dir / "stderr");
  const std::string err = ReadFile(dir / "stderr");
  EXPECT_NE(err.find("'" + cut.string() + "' is not indexed"), std::string::npos) << err;
  EXPECT_NE(err.find("reindexing a temporary copy"), std::string::npos) << err;
  EXPECT_NE(err.find("process_bag: input ended early: bag '" + cut.string() +
                     "' breaks off at byte " + std::to_string(fs::file_size(cut))),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("messages read up to the break, its last readable message at bag time "),
            std::string::npos)
      << err;
  // The epoch the break cut short, accepted at the end of input, is said once more at the end.
  EXPECT_NE(err.find("process_bag: accepted at the end of input without all its inputs: epoch 1: "
                     "fixed_cam_2: no end marker"),
            std::string::npos)
      << err;
  EXPECT_GT(ObservationKeys(dir / "history.db").size(), 0u) << "nothing processed before the break";
  EXPECT_TRUE(fs::exists(dir / "reports" / "deformation.csv")) << "no report of what was processed";
}

// Bounded memory on bag messages (issue 38): the full_graph_replay survey
// rewritten by the test with its photos replaced by forged image messages (a
// header claiming 20000 x 20000 px over 64 bytes, a header whose step x
// height is not the data's size, a record larger than an image within
// --max-megapixels can be). Each is skipped before conversion, named with
// topic, bag time and size; the rest (the radio receivers, markers, tf) is
// processed; exit status 2 (inputs skipped). Cheap: no photo is measured.
TEST(ProcessBag, ForgedImageMessagesAreSkippedAndNamed) {
  const fs::path dir = Scratch("forged_images");
  const fs::path forged = dir / "forged.bag";
  std::vector<std::string> expected;
  {
    rosbag::Bag in(Survey("full_graph_replay", ".bag"), rosbag::bagmode::Read);
    rosbag::Bag out(forged.string(), rosbag::bagmode::Write);
    int n = 0;
    for (const rosbag::MessageInstance& m : rosbag::View(in)) {
      const auto image = m.instantiate<sensor_msgs::Image>();
      if (!image) {
        out.write(m.getTopic(), m.getTime(), m, m.getConnectionHeader());
        continue;
      }
      sensor_msgs::Image f;
      f.header = image->header;
      f.encoding = "mono8";
      char at[32];
      std::snprintf(at, sizeof at, "%.3f", m.getTime().toSec());
      const std::string where = "image message on " + m.getTopic() + " at " + at + " s: ";
      switch (n++ % 3) {
        case 0:  // 400 MP claimed over 64 bytes
          f.width = f.height = f.step = 20000;
          f.data.assign(64, 0);
          expected.push_back(where +
                             "image 20000 x 20000 px (400.0 MP), more than max_megapixels 1");
          break;
        case 1:  // 0.3 MP, a third of its rows
          f.width = f.step = 640;
          f.height = 480;
          f.data.assign(640 * 160, 0);
          expected.push_back(where +
                             "image 640 x 480 px: step 640 x height 480 = 307200 bytes, but the "
                             "message holds 102400");
          break;
        default:  // 12 MB: more than an image of 1 MP can be (9 MB with the 1 MiB margin)
          f.width = f.step = 4000;
          f.height = 3000;
          f.data.assign(4000 * 3000, 0);
          expected.push_back(where + "a record of ");
          break;
      }
      out.write(m.getTopic(), m.getTime(), f);
    }
    EXPECT_EQ(n, 8);  // 4 photos of each of the 2 fixed cameras
  }
  fs::copy_file(Survey("full_graph_replay", ".targets.yaml"), dir / "forged.targets.yaml");
  fs::copy_file(Survey("full_graph_replay", ".truth.yaml"), dir / "forged.truth.yaml");
  const int status = Wait(Spawn(
      {SM_PROCESS_BAG, "--bag", forged.string(), "--max-megapixels", "1", "--no-dense",
       "--database", (dir / "history.db").string(), "--report-dir", (dir / "reports").string()},
      dir));
  const std::string err = ReadFile(dir / "stderr");
  EXPECT_EQ(status, 2) << err;
  for (const std::string& line : expected)
    EXPECT_NE(err.find("process_bag: skipped " + line), std::string::npos) << line << "\n" << err;
  EXPECT_NE(err.find("process_bag: 8 message(s) skipped:"), std::string::npos) << err;
  EXPECT_NE(err.find("bytes, more than an image of max_megapixels 1 can hold (9048576 bytes); not "
                     "read"),
            std::string::npos)
      << err;
  // The rest processed: the radio receivers' epochs solved and in the history.
  EXPECT_GT(ObservationKeys(dir / "history.db").size(), 0u) << err;
  EXPECT_TRUE(fs::exists(dir / "reports" / "deformation.csv")) << err;
}

}  // namespace
}  // namespace slope_monitor
