// A crew's season: the full_graph_replay survey (four epochs 3 h
// apart, two fixed cameras, five radio transmitters) written as the three
// recordings a crew makes (before and the first event: epochs 0-1; after the
// second event: epoch 2; after the third: epoch 3; /tf_static in each), each
// processed with the README's command and no --database:
//   process_bag --bag recN.bag --site-config recN.site.yaml --report-dir reports
// Must hold: one history, ~/.ros/slope_monitor/full_graph_replay.db (the
// site's name that make_survey_bag wrote beside the bag); the final
// deformation.csv equal to the whole survey's (each displacement within
// 0.1 mm, the same alert per point); the second recording processed again
// adds no observation and says so; the third before the second gives the
// same final file; the last recording through replay.launch likewise; a
// recording of another site is refused naming both; a history without its
// reference is refused, the file untouched. And the first movement: every
// moving target's speed at epoch 1 within 3 sigma of the truth and its alert
// the one its true speed gives (alarm: 240 mm/day, confirmed by the others).
#include <sqlite3.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>

#include <iomanip>
#include <set>
#include <thread>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>
#include <opencv2/imgcodecs.hpp>

#include "process_bag_run.h"
#include "replay_test_util.h"
#include "slope_monitor/TargetObservationArray.h"
#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace {

namespace fs = std::filesystem;
using namespace process_bag_run;  // NOLINT: the test helpers

constexpr char kSurvey[] = "full_graph_replay";
constexpr double kT0 = 1700000000.0;
// The recordings' bounds [s after t0]: epochs at 0, 3, 6, 9 h, radio every 600 s.
const std::vector<double> kCuts = {16500.0, 27300.0};

// The survey cut into recordings rec1.bag ... in `dir`, each with /tf_static
// at its start and the files make_survey_bag writes beside a bag.
std::vector<std::string> WriteRecordings(const fs::path& dir) {
  rosbag::Bag whole(Survey(kSurvey, ".bag"), rosbag::bagmode::Read);
  std::vector<rosbag::MessageInstance> statics;
  rosbag::View tf(whole, rosbag::TopicQuery(std::vector<std::string>{"/tf_static"}));
  for (const rosbag::MessageInstance& m : tf) statics.push_back(m);
  std::vector<double> bounds = {0.0};
  bounds.insert(bounds.end(), kCuts.begin(), kCuts.end());
  bounds.push_back(1e9);
  std::vector<std::string> out;
  for (size_t k = 0; k + 1 < bounds.size(); ++k) {
    const std::string stem = (dir / ("rec" + std::to_string(k + 1))).string();
    rosbag::Bag rec(stem + ".bag", rosbag::bagmode::Write);
    rec.setCompression(rosbag::compression::LZ4);
    rosbag::View part(whole, ros::Time(kT0 + bounds[k]),
                      ros::Time(kT0 + bounds[k + 1]) - ros::Duration(0, 1));
    bool first = true;
    for (const rosbag::MessageInstance& m : part) {
      if (m.getTopic() == "/tf_static") continue;
      if (first)
        for (const rosbag::MessageInstance& s : statics) rec.write("/tf_static", m.getTime(), s);
      first = false;
      rec.write(m.getTopic(), m.getTime(), m, m.getConnectionHeader());
    }
    rec.close();
    for (const char* ext : {".truth.yaml", ".targets.yaml", ".site.yaml"})
      fs::copy_file(Survey(kSurvey, ext), stem + ext);
    out.push_back(stem);
  }
  return out;
}

// The README's command on one recording with HOME = `home` (no --database);
// stdout, stderr in `run`. The exit status.
int ProcessRecording(const std::string& stem, const fs::path& home, const fs::path& run) {
  fs::create_directories(run);
  const std::vector<std::string> args = {SM_PROCESS_BAG,
                                         "--bag",
                                         stem + ".bag",
                                         "--site-config",
                                         stem + ".site.yaml",
                                         "--report-dir",
                                         (home / "reports").string()};
  return replay_test::Wait(replay_test::Spawn(args, run, {"HOME=" + home.string()}));
}

struct Row {
  Eigen::Vector3d d = Eigen::Vector3d::Zero();  // [mm]
  std::string alert;
};

// deformation.csv by point id: displacement and alert.
std::map<std::string, Row> ReadReport(const fs::path& csv) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  std::stringstream hs(line);
  for (std::string c; std::getline(hs, c, ',');) header.push_back(c);
  auto column = [&](const std::string& name) {
    return static_cast<size_t>(std::find(header.begin(), header.end(), name) - header.begin());
  };
  std::map<std::string, Row> rows;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ls(line);
    for (std::string c; std::getline(ls, c, ',');) f.push_back(c);
    if (f.size() < header.size()) continue;
    Row r;
    r.d = Eigen::Vector3d(std::stod(f[column("dx_mm")]), std::stod(f[column("dy_mm")]),
                          std::stod(f[column("dz_mm")]));
    r.alert = f[column("alert")];
    std::string id = f[0];
    id.erase(std::remove(id.begin(), id.end(), '"'), id.end());
    rows[id] = r;
  }
  return rows;
}

void ExpectSameReport(const fs::path& a, const fs::path& b, const std::string& what) {
  const auto ra = ReadReport(a), rb = ReadReport(b);
  EXPECT_GE(ra.size(), 9u) << what;
  EXPECT_EQ(ra.size(), rb.size()) << what;
  double worst = 0.0;
  for (const auto& [id, r] : ra) {
    const auto it = rb.find(id);
    if (it == rb.end()) {
      ADD_FAILURE() << what << ": " << id << " missing";
      continue;
    }
    worst = std::max(worst, (r.d - it->second.d).cwiseAbs().maxCoeff());
    EXPECT_LE((r.d - it->second.d).cwiseAbs().maxCoeff(), 0.1) << what << ": " << id;
    EXPECT_EQ(r.alert, it->second.alert) << what << ": " << id;
  }
  std::cout << what << ": " << ra.size() << " points, largest displacement difference " << worst
            << " mm\n";
}

int64_t Count(const fs::path& db, const std::string& sql) {
  sqlite3* h = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK) << db;
  int64_t n = -1;
  sqlite3_exec(
      h, sql.c_str(),
      [](void* out, int, char** v, char**) {
        *static_cast<int64_t*>(out) = v[0] ? std::stoll(v[0]) : 0;
        return 0;
      },
      &n, nullptr);
  sqlite3_close(h);
  return n;
}

// The first line process_bag writes (which history, its reference).
std::string FirstLine(const fs::path& run) {
  std::istringstream err(replay_test::ReadFile(run / "stderr"));
  std::string line;
  while (std::getline(err, line))
    if (line.rfind("process_bag: history ", 0) == 0) return line;
  return "";
}

class Season : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(Scratch("season"));
    recordings_ = new std::vector<std::string>(WriteRecordings(*dir_));
    // The whole survey in one go: the numbers a season must reproduce.
    ASSERT_EQ(
        ProcessRecording(Survey(kSurvey, ".bag").substr(0, Survey(kSurvey, ".bag").size() - 4),
                         *dir_ / "whole", *dir_ / "whole_run"),
        0)
        << replay_test::ReadFile(*dir_ / "whole_run" / "stderr");
  }
  static fs::path History(const fs::path& home) {
    return home / ".ros" / "slope_monitor" / (std::string(kSurvey) + ".db");
  }
  static fs::path* dir_;
  static std::vector<std::string>* recordings_;
};
fs::path* Season::dir_ = nullptr;
std::vector<std::string>* Season::recordings_ = nullptr;

TEST_F(Season, RecordingsContinueTheSiteHistory) {
  const std::vector<std::string>& rec = *recordings_;
  EXPECT_NE(replay_test::ReadFile(rec[0] + ".site.yaml").find("site_name: full_graph_replay "),
            std::string::npos);
  const fs::path home = *dir_ / "season";
  for (size_t k = 0; k < rec.size(); ++k) {
    const fs::path run = *dir_ / ("season_run" + std::to_string(k + 1));
    ASSERT_EQ(ProcessRecording(rec[k], home, run), 0) << replay_test::ReadFile(run / "stderr");
    const std::string first = FirstLine(run);
    std::cout << first << "\n";
    EXPECT_NE(first.find(History(home).string()), std::string::npos) << first;
    EXPECT_NE(first.find("of site 'full_graph_replay'"), std::string::npos) << first;
    if (k == 0)
      EXPECT_NE(first.find("a new history"), std::string::npos) << first;
    else
      EXPECT_NE(first.find("continuing: reference epoch"), std::string::npos) << first;
    if (k > 0) EXPECT_NE(first.find("from rec1.bag"), std::string::npos) << first;
  }
  // One history for the site, none per recording.
  int histories = 0;
  for (const auto& f : fs::directory_iterator(home / ".ros" / "slope_monitor"))
    histories += f.path().extension() == ".db" ? 1 : 0;
  EXPECT_EQ(histories, 1);
  ExpectSameReport(*dir_ / "whole" / "reports" / "deformation.csv",
                   home / "reports" / "deformation.csv", "three recordings in order");

  // The second recording again: nothing added, said so.
  const int64_t observations = Count(History(home), "SELECT count(*) FROM observations");
  const fs::path again = *dir_ / "season_again";
  ASSERT_EQ(ProcessRecording(rec[1], home, again), 0);
  EXPECT_EQ(Count(History(home), "SELECT count(*) FROM observations"), observations);
  EXPECT_NE(replay_test::ReadFile(again / "stderr").find("rec2.bag: already in the history: "),
            std::string::npos)
      << replay_test::ReadFile(again / "stderr");
  ExpectSameReport(*dir_ / "whole" / "reports" / "deformation.csv",
                   home / "reports" / "deformation.csv", "the second recording again");
  // The levels the history ends at were announced by the runs that reached
  // them: a run that changes nothing announces no alert.
  EXPECT_EQ(replay_test::ReadFile(again / "stderr").find(": alert "), std::string::npos)
      << replay_test::ReadFile(again / "stderr");
}

TEST_F(Season, RecordingsOutOfOrderGiveTheInOrderNumbers) {
  const std::vector<std::string>& rec = *recordings_;
  const fs::path home = *dir_ / "order";
  for (size_t k : {0, 2, 1}) {
    const fs::path run = *dir_ / ("order_run" + std::to_string(k + 1));
    ASSERT_EQ(ProcessRecording(rec[k], home, run), 0) << replay_test::ReadFile(run / "stderr");
  }
  // The radio epochs of the third were tracked again after the second.
  EXPECT_NE(replay_test::ReadFile(*dir_ / "order_run2" / "stderr")
                .find("tracked again after it, in time order"),
            std::string::npos);
  ExpectSameReport(*dir_ / "whole" / "reports" / "deformation.csv",
                   home / "reports" / "deformation.csv", "recordings 1, 3, 2");
}

// The last recording through replay.launch (database auto) on the history
// the first two left: the same final numbers.
TEST_F(Season, LastRecordingThroughReplayLaunch) {
  const std::vector<std::string>& rec = *recordings_;
  const fs::path home = *dir_ / "launch";
  for (size_t k : {0, 1})
    ASSERT_EQ(ProcessRecording(rec[k], home, *dir_ / ("launch_run" + std::to_string(k + 1))), 0);
  const fs::path run = *dir_ / "launch_run3";
  fs::create_directories(run);
  const int port = replay_test::FreePort();
  const std::vector<std::string> argv = {"roslaunch",
                                         "-p",
                                         std::to_string(port),
                                         "slope_monitor",
                                         "replay.launch",
                                         "bag:=" + rec[2] + ".bag",
                                         "site_config:=" + rec[2] + ".site.yaml",
                                         "dense:=false"};
  const int status = replay_test::WaitAtMost(
      replay_test::Spawn(
          argv, run,
          {"HOME=" + home.string(), "ROS_MASTER_URI=http://127.0.0.1:" + std::to_string(port),
           "ROS_LOG_DIR=" + (run / "log").string(), "ROS_HOME=" + (run / "ros_home").string()}),
      std::chrono::seconds(180));
  ASSERT_EQ(status, 0) << replay_test::ReadFile(run / "stdout")
                       << replay_test::ReadFile(run / "stderr");
  // replay.launch's own report_dir default, ~/.ros/slope_monitor/reports.
  ExpectSameReport(*dir_ / "whole" / "reports" / "deformation.csv",
                   home / ".ros" / "slope_monitor" / "reports" / "deformation.csv",
                   "the last recording by replay.launch");
}

// Bad input: another site's recording, a history without its reference.
TEST_F(Season, AnotherSiteAndAMissingReferenceAreRefused) {
  const std::vector<std::string>& rec = *recordings_;
  const fs::path home = *dir_ / "bad";
  ASSERT_EQ(ProcessRecording(rec[0], home, *dir_ / "bad_run1"), 0);
  const int64_t observations = Count(History(home), "SELECT count(*) FROM observations");
  // The third recording's files renamed to another site, given the site's history.
  const std::string other = (*dir_ / "other").string();
  for (const char* ext : {".bag", ".truth.yaml", ".targets.yaml"})
    fs::copy_file(rec[2] + ext, other + ext);
  std::string overlay = replay_test::ReadFile(rec[2] + ".site.yaml");
  overlay.replace(overlay.find("site_name: full_graph_replay"),
                  std::string("site_name: full_graph_replay").size(), "site_name: south_gully");
  std::ofstream(other + ".site.yaml") << overlay;
  const fs::path run = *dir_ / "bad_other";
  fs::create_directories(run);
  const int status = replay_test::Wait(
      replay_test::Spawn({SM_PROCESS_BAG, "--bag", other + ".bag", "--site-config",
                          other + ".site.yaml", "--database", History(home).string()},
                         run, {"HOME=" + home.string()}));
  const std::string err = replay_test::ReadFile(run / "stderr");
  EXPECT_EQ(status, 1) << err;
  EXPECT_NE(err.find("is of site 'south_gully'"), std::string::npos) << err;
  EXPECT_NE(err.find("is of site 'full_graph_replay': refused, nothing written"), std::string::npos)
      << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_EQ(Count(History(home), "SELECT count(*) FROM observations"), observations);

  // The history's reference removed (edited by hand): refused, the file as it was.
  sqlite3* h = nullptr;
  ASSERT_EQ(sqlite3_open(History(home).c_str(), &h), SQLITE_OK);
  ASSERT_EQ(
      sqlite3_exec(h, "DELETE FROM meta WHERE key = 'datum_stamp'", nullptr, nullptr, nullptr),
      SQLITE_OK);
  sqlite3_close(h);
  const std::string before = replay_test::ReadFile(History(home));
  const fs::path missing = *dir_ / "bad_missing";
  EXPECT_EQ(ProcessRecording(rec[1], home, missing), 1);
  EXPECT_NE(replay_test::ReadFile(missing / "stderr").find("no reference epoch"), std::string::npos)
      << replay_test::ReadFile(missing / "stderr");
  EXPECT_TRUE(replay_test::ReadFile(History(home)) == before) << "the history was written";
}

// A new reference only on request: the third recording with --new-reference
// on the history of the first two measures from its own reference (the
// observations of the old one stay in the history, not fused).
TEST_F(Season, NewReferenceOnRequest) {
  const std::vector<std::string>& rec = *recordings_;
  const fs::path home = *dir_ / "new_reference";
  for (size_t k : {0, 1})
    ASSERT_EQ(ProcessRecording(rec[k], home, *dir_ / ("new_reference_run" + std::to_string(k + 1))),
              0);
  const int64_t before = Count(History(home), "SELECT count(*) FROM observations");
  const fs::path run = *dir_ / "new_reference_run3";
  fs::create_directories(run);
  const int status = replay_test::Wait(replay_test::Spawn(
      {SM_PROCESS_BAG, "--bag", rec[2] + ".bag", "--site-config", rec[2] + ".site.yaml",
       "--report-dir", (home / "reports").string(), "--new-reference"},
      run, {"HOME=" + home.string()}));
  ASSERT_EQ(status, 0) << replay_test::ReadFile(run / "stderr");
  EXPECT_NE(FirstLine(run).find("; a new reference from this recording (--new-reference)"),
            std::string::npos)
      << FirstLine(run);
  EXPECT_GT(Count(History(home), "SELECT count(*) FROM observations"), before);
  // Measured from a reference in the third recording: every displacement
  // smaller than the whole survey's, from its first reference.
  const auto whole = ReadReport(*dir_ / "whole" / "reports" / "deformation.csv");
  const auto fresh = ReadReport(home / "reports" / "deformation.csv");
  ASSERT_FALSE(fresh.empty());
  for (const auto& [id, r] : fresh) {
    ASSERT_TRUE(whole.count(id)) << id;
    EXPECT_LT(r.d.norm(), 0.7 * whole.at(id).d.norm()) << id;
  }
}

// The first movement: at epoch 1 (3 h after the reference) every moving
// target's fused speed is within 3 sigma of the simulator's true speed, and
// its alert is alarm (true speed 240 mm/day, 4.8 x the alarm threshold,
// confirmed by the other moving points): from the reference's zero, not one
// epoch later.
TEST_F(Season, FirstMovementIsMeasuredAndAlerted) {
  const fs::path db = History(*dir_ / "whole");
  const sim::SurveyTruth truth = sim::SurveyTruth::Load(Survey(kSurvey, ".truth.yaml"));
  const double t1 = truth.epochs.at(1).stamp;
  int checked = 0;
  for (const sim::TargetTruth& t : truth.targets) {
    if (t.role != io::TargetRole::kMonitoring) continue;
    const Eigen::Vector3d x = t.positions.at(0);
    const Eigen::Vector3d v_true =
        (truth.DisplacementAt(x, t1 + 1.0) - truth.DisplacementAt(x, t1 - 1.0)) / 2.0;
    if (v_true.norm() * 86400e3 < 50.0) continue;  // moving points only
    // The fused estimate right after the point's first target measurement at epoch 1.
    sqlite3* h = nullptr;
    ASSERT_EQ(sqlite3_open_v2(db.c_str(), &h, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
    const std::string sql =
        "SELECT e.vx, e.vy, e.vz, e.velocity_covariance, e.alert_level FROM estimates e WHERE "
        "e.point_id = ?1 AND e.stamp = (SELECT min(stamp) FROM observations WHERE point_id = ?1 "
        "AND source = 1 AND stamp > ?2)";
    sqlite3_stmt* s = nullptr;
    ASSERT_EQ(sqlite3_prepare_v2(h, sql.c_str(), -1, &s, nullptr), SQLITE_OK);
    sqlite3_bind_text(s, 1, t.key.c_str(), -1, SQLITE_TRANSIENT);
    sqlite3_bind_double(s, 2, t1 - 60.0);
    ASSERT_EQ(sqlite3_step(s), SQLITE_ROW) << t.key;
    const Eigen::Vector3d v(sqlite3_column_double(s, 0), sqlite3_column_double(s, 1),
                            sqlite3_column_double(s, 2));
    Eigen::Matrix3d P;
    std::memcpy(P.data(), sqlite3_column_blob(s, 3), sizeof(double) * 9);  // symmetric
    const int alert = sqlite3_column_int(s, 4);
    sqlite3_finalize(s);
    sqlite3_close(h);
    const Eigen::Vector3d u = v.normalized();
    const double sigma = std::sqrt(u.dot(P * u));
    const double error = v.norm() - v_true.norm();
    std::cout << t.key << ": speed " << v.norm() * 86400e3 << " +- " << sigma * 86400e3
              << " mm/day, truth " << v_true.norm() * 86400e3 << ", alert " << alert << "\n";
    EXPECT_LE(std::abs(error), 3.0 * sigma) << t.key;
    EXPECT_EQ(alert, 3) << t.key;  // alarm
    ++checked;
  }
  EXPECT_GE(checked, 6);
}

// Two fixed cameras recorded with camera_capture.launch's own example lines
// (ns:=north_ridge/camera, ns:=gully/camera, no camera_name) through
// record.launch, then process_bag: each camera keeps its frame (both were
// camera_optical), so the adjustment has both cameras' targets and two
// camera transforms. The photos: the survey's two fixed cameras, written as
// PNG files stamped (file time) with their capture times, and their
// CameraInfo as camera_calibration_parsers YAML.
TEST_F(Season, TwoCamerasCapturedWithTheLaunchExamplesKeepTheirFrames) {
  const fs::path dir = *dir_ / "two_cameras";
  const std::map<std::string, std::string> cameras = {{"fixed_cam_1", "north_ridge"},
                                                      {"fixed_cam_2", "gully"}};
  {
    rosbag::Bag whole(Survey(kSurvey, ".bag"), rosbag::bagmode::Read);
    for (const auto& [from, to] : cameras) {
      fs::create_directories(dir / to);
      int k = 0;
      rosbag::View images(whole, rosbag::TopicQuery("/" + from + "/camera/image_raw"));
      for (const rosbag::MessageInstance& m : images) {
        const auto im = m.instantiate<sensor_msgs::Image>();
        ASSERT_TRUE(im && im->encoding == "mono8");
        const cv::Mat pixels(static_cast<int>(im->height), static_cast<int>(im->width), CV_8UC1,
                             const_cast<uint8_t*>(im->data.data()), im->step);
        const fs::path file = dir / to / ("photo_" + std::to_string(k++) + ".png");
        ASSERT_TRUE(cv::imwrite(file.string(), pixels));
        const timespec t[2] = {{im->header.stamp.sec, static_cast<long>(im->header.stamp.nsec)},
                               {im->header.stamp.sec, static_cast<long>(im->header.stamp.nsec)}};
        ASSERT_EQ(utimensat(AT_FDCWD, file.c_str(), t, 0), 0);
      }
      EXPECT_EQ(k, 4) << from;
      rosbag::View infos(whole, rosbag::TopicQuery("/" + from + "/camera/camera_info"));
      const auto info = infos.begin()->instantiate<sensor_msgs::CameraInfo>();
      ASSERT_TRUE(info);
      std::ofstream cal(dir / (to + ".yaml"));
      auto list = [&cal](const auto& v) {
        for (size_t i = 0; i < v.size(); ++i)
          cal << (i ? ", " : "") << std::setprecision(17) << v[i];
      };
      cal << "image_width: " << info->width << "\nimage_height: " << info->height
          << "\ncamera_name: " << to << "\ncamera_matrix: {rows: 3, cols: 3, data: [";
      list(info->K);
      cal << "]}\ndistortion_model: " << info->distortion_model
          << "\ndistortion_coefficients: {rows: 1, cols: " << info->D.size() << ", data: [";
      list(info->D);
      cal << "]}\nrectification_matrix: {rows: 3, cols: 3, data: [";
      list(info->R);
      cal << "]}\nprojection_matrix: {rows: 3, cols: 4, data: [";
      list(info->P);
      cal << "]}\n";
    }
  }
  const fs::path site = dir / "two_cameras.yaml";
  std::ofstream(site) << "name: two_cameras\ncrs: EPSG:4979\norigin: [8.0, 46.5, 1200.0]\n"
                         "cameras:\n"
                         "  - {name: north_ridge, kind: fixed, pixel_size: 0.0048}\n"
                         "  - {name: gully, kind: fixed, pixel_size: 0.0048}\n"
                         "targets: {file: "
                      << Survey(kSurvey, ".targets.yaml") << "}\n";

  // record.launch first (it starts the run's master), then both captures at once.
  const int port = replay_test::FreePort();
  const std::vector<std::string> env = {"ROS_MASTER_URI=http://127.0.0.1:" + std::to_string(port),
                                        "ROS_LOG_DIR=" + (dir / "log").string(),
                                        "ROS_HOME=" + (dir / "ros_home").string()};
  for (const char* sub : {"bags", "record", "north_ridge_run", "gully_run"})
    fs::create_directories(dir / sub);
  const pid_t record =
      replay_test::Spawn({"roslaunch", "-p", std::to_string(port), "slope_monitor", "record.launch",
                          "site:=two_cameras", "dir:=" + (dir / "bags").string()},
                         dir / "record", env);
  ASSERT_GT(record, 0);
  std::this_thread::sleep_for(std::chrono::seconds(8));  // the master and the recorder up
  std::vector<pid_t> captures;
  for (const auto& [from, to] : cameras)
    captures.push_back(replay_test::Spawn(
        {"roslaunch", "slope_monitor", "camera_capture.launch", "ns:=" + to + "/camera",
         "source:=folder", "folder:=" + (dir / to).string(),
         "camera_info_url:=file://" + (dir / (to + ".yaml")).string(), "site:=" + site.string()},
        dir / (to + "_run"), env));
  for (const pid_t c : captures)
    EXPECT_EQ(replay_test::WaitAtMost(c, std::chrono::seconds(120)), 0);
  std::this_thread::sleep_for(std::chrono::seconds(2));  // the recorder writes what it queued
  kill(record, SIGINT);
  replay_test::WaitAtMost(record, std::chrono::seconds(60));

  std::vector<std::string> args = {SM_PROCESS_BAG, "--no-dense", "--site", site.string()};
  for (const auto& f : fs::directory_iterator(dir / "bags"))
    if (f.path().extension() == ".bag") {
      args.push_back("--bag");
      args.push_back(f.path().string());
    }
  ASSERT_GT(args.size(), 4u) << replay_test::ReadFile(dir / "record" / "stderr");
  for (const std::string& a :
       {std::string("--database"), (dir / "history.db").string(), std::string("--report-dir"),
        (dir / "reports").string(), std::string("--output-bag"), (dir / "out.bag").string()})
    args.push_back(a);
  const int status = replay_test::Wait(replay_test::Spawn(args, dir));
  ASSERT_EQ(status, 0) << replay_test::ReadFile(dir / "stderr");
  // Two camera transforms (one per frame) and both cameras' targets.
  std::set<std::string> frames;
  std::map<std::string, int> targets;
  rosbag::Bag out((dir / "out.bag").string(), rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(out)) {
    if (const auto tf = m.instantiate<tf2_msgs::TFMessage>())
      for (const auto& t : tf->transforms) frames.insert(t.child_frame_id);
    if (const auto t = m.instantiate<slope_monitor::TargetObservationArray>())
      targets[m.getTopic()] += static_cast<int>(t->observations.size());
  }
  EXPECT_TRUE(frames.count("north_ridge_optical")) << "no transform of north_ridge";
  EXPECT_TRUE(frames.count("gully_optical")) << "no transform of gully";
  EXPECT_FALSE(frames.count("camera_optical"));
  EXPECT_GT(targets["/north_ridge/targets"], 4 * 8);
  EXPECT_GT(targets["/gully/targets"], 4 * 8);
  EXPECT_EQ(replay_test::ReadFile(dir / "stderr").find("the frame of camera"), std::string::npos);
}

}  // namespace
}  // namespace slope_monitor
