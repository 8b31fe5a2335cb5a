// process_bag on the simulated UAV surveys (test/replay/uav_*.sim.yaml,
// rendered at build time): the truth checks and tolerances of the former
// uav_graph_replay and uav_block_replay rostests (uav_replay_checks.h),
// without ROS transport (dropped from the suite: doc/testing.md).
//   * uav_graph_replay: the demo site's two fixed cameras and a UAV strip,
//     three epochs, targets only;
//   * uav_block_replay: the UAV alone, two parallel strips, two epochs, tie
//     points from the sequence matcher (--uav-tie-points, the graph's
//     hex_matcher in mode sequence) and the camera self-calibrated
//     (config/uav_self_calibration.yaml). Run on a copy of the bag whose
//     UAV topics are /drone/...: a site file names the camera `drone` with
//     kind uav, and every UAV step (priors, tie points, self-calibration)
//     must follow the kind, not the name `uav` (issue 18).
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "replay_test_util.h"
#include "slope_monitor/EpochMarker.h"
#include "uav_replay_checks.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using replay_test::CopySurvey;
using replay_test::ReadFile;
using replay_test::Survey;

fs::path OutputDir(const std::string& name) {
  return fs::temp_directory_path() / ("process_bag_uav_test_" + std::to_string(getpid())) / name;
}

// A copy of `name`'s survey in `dir` whose topics under /uav/ are under
// /<camera>/ and whose epoch markers name <camera> (stamps, the other
// messages and latching kept).
std::string RenamedSurvey(const std::string& name, const fs::path& dir, const std::string& camera) {
  return CopySurvey(name, dir, name, [&camera](const rosbag::MessageInstance& m, rosbag::Bag* out) {
    std::string topic = m.getTopic();
    if (topic.rfind("/uav/", 0) == 0) topic = "/" + camera + topic.substr(4);
    // The epoch markers name their camera (EpochMarker.source), as a
    // driver of camera `drone` writes them.
    if (const auto marker = m.instantiate<slope_monitor::EpochMarker>()) {
      slope_monitor::EpochMarker renamed = *marker;
      if (renamed.source == "uav") renamed.source = camera;
      out->write(topic, m.getTime(), renamed, m.getConnectionHeader());
    } else {
      out->write(topic, m.getTime(), m, m.getConnectionHeader());
    }
  });
}

// process_bag on `name`'s survey (or on `bag`) with `extra` arguments;
// outputs in a fresh directory (history.db, reports/, out.bag, stdout,
// stderr). Returns it.
fs::path RunProcessBag(const std::string& name, const std::vector<std::string>& extra,
                       std::string bag = "") {
  if (bag.empty()) bag = Survey(name, ".bag");
  const fs::path dir = OutputDir(name);
  fs::remove_all(dir / "out.bag");
  fs::remove_all(dir / "history.db");
  fs::remove_all(dir / "reports");
  fs::create_directories(dir);
  std::string command = std::string("'") + SM_PROCESS_BAG + "' --bag '" + bag + "' --database '" +
                        (dir / "history.db").string() + "' --report-dir '" +
                        (dir / "reports").string() + "' --output-bag '" +
                        (dir / "out.bag").string() + "'";
  if (fs::exists(Survey(name, ".site.yaml")))
    command += " --site-config '" + Survey(name, ".site.yaml") + "'";
  for (const std::string& a : extra) command += " '" + a + "'";
  command += " > '" + (dir / "stdout").string() + "' 2> '" + (dir / "stderr").string() + "'";
  const auto start = std::chrono::steady_clock::now();
  const int status = std::system(command.c_str());
  std::cout << "process_bag on " << name << ": "
            << std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count()
            << " s\n";
  EXPECT_EQ(status, 0) << ReadFile(dir / "stderr");
  return dir;
}

TEST(ProcessBagUav, GraphReplaySurveyMatchesTruth) {
  const std::string name = "uav_graph_replay";
  // The adjustment's truth only: the dense step's is process_bag_dense_test's.
  const fs::path dir = RunProcessBag(name, {"--no-dense"});
  uav_replay::Tolerances tol;  // those of uav_graph_replay.test.in
  tol.min_uav_photos = 5;      // kept per epoch, of 9
  tol.max_uav_position_error = 0.15;
  tol.max_uav_attitude_error = 0.005;
  tol.min_fraction_within_3_sigma = 0.99;
  tol.max_uav_displacement_rms = 0.02;
  uav_replay::CheckUavReplay(uav_replay::ReadOutputs((dir / "out.bag").string()),
                             Survey(name, ".truth.yaml"), tol);
}

TEST(ProcessBagUav, BlockSurveyWithTiePointsMatchesTruth) {
  const std::string name = "uav_block_replay";
  // The UAV is `drone` by the site file's kind field (the survey calls it uav).
  const fs::path survey = OutputDir(name) / "drone";
  const std::string bag = RenamedSurvey(name, survey, "drone");
  const std::string site = (survey / "drone.site.yaml").string();
  std::ofstream(site) << "name: drone_block\n"
                         "crs: EPSG:4979\n"
                         "origin: [8.0, 46.5, 1200.0]\n"
                         "cameras:\n"
                         "  - {name: drone, kind: uav, pixel_size: 0.0048}\n";
  const fs::path dir =
      RunProcessBag(name,
                    {"--uav-tie-points", "--no-dense", "--site", site, "--adjuster-config",
                     std::string(SM_SOURCE_DIR) + "/config/uav_self_calibration.yaml"},
                    bag);
  const uav_replay::Outputs outputs =
      uav_replay::ReadOutputs((dir / "out.bag").string(), "/drone/tie_points");
  std::cout << outputs.tie_point_messages << " tie-point messages, " << outputs.tie_points
            << " tie points\n";
  // Every photo but the first of each epoch pairs (2 epochs x 20 photos).
  EXPECT_GE(outputs.tie_point_messages, 40);
  EXPECT_GT(outputs.tie_points, 38 * 100);
  uav_replay::Tolerances tol;  // those of uav_block_replay.test.in
  tol.min_uav_photos = 16;     // kept per epoch, of 20
  tol.max_uav_position_error = 0.10;
  tol.max_uav_attitude_error = 0.004;
  tol.min_fraction_within_3_sigma = 0.99;
  tol.max_uav_displacement_rms = 0.02;  // issue #5: UAV at 60 m; the graph measured 14.6 mm
  tol.check_interior = true;
  tol.max_c_error = 0.008;               // [mm] nominal is 0.020 off
  tol.max_principal_point_error = 0.03;  // [mm] 6 px; nominal is 0.008-0.012 off
  tol.max_k1_error = 2e-5;               // [mm^-2] nominal is 2e-4 off
  tol.uav_camera = "drone";
  uav_replay::CheckUavReplay(outputs, Survey(name, ".truth.yaml"), tol);
}

}  // namespace
}  // namespace slope_monitor
