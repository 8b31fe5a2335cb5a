// The demo survey through the whole graph twice: replay.launch (rosbag play
// --clock at its default rate into the nodelet graph, the baseline) and
// process_bag (offline, bag-time order, no master). Prints the wall time of
// both, whether the two deformation summaries agree, and
//   ratio replay_launch_wall/process_bag_wall = X
// The demo bag is $SM_WS/demo/demo_site/demo_site.bag (scripts/demo makes
// it); a missing one is made here with make_survey_bag (not timed).
//   bench_replay_vs_process_bag [BAG]
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

namespace {

std::string ReadFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Wall seconds of `command` (through the shell); exits on failure.
double Timed(const std::string& command) {
  const auto start = std::chrono::steady_clock::now();
  const int rc = std::system(command.c_str());
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (rc != 0) {
    std::cerr << "bench_replay_vs_process_bag: failed (" << rc << "): " << command << "\n";
    std::exit(1);
  }
  return s;
}

// The deformation summary table of deformation_summary / process_bag.
std::string Summary(const std::string& text) {
  const size_t a = text.find("point ");
  const size_t b = text.find("\nReports in");
  return a == std::string::npos
             ? ""
             : text.substr(a, b == std::string::npos ? std::string::npos : b - a);
}

}  // namespace

int main(int argc, char** argv) {
  const char* ws = std::getenv("SM_WS");
  std::string bag =
      argc > 1 ? argv[1] : std::string(ws ? ws : ".") + "/demo/demo_site/demo_site.bag";
  const std::string stem = bag.substr(0, bag.size() - 4);
  if (!fs::exists(bag)) {
    std::cout << "making the demo survey " << bag << "\n";
    fs::create_directories(fs::path(bag).parent_path());
    Timed("rosrun slope_monitor make_survey_bag --config " SM_SOURCE_DIR
          "/config/sim/demo_site.yaml --out '" +
          bag + "' > /dev/null");
  }
  const fs::path dir =
      fs::temp_directory_path() / ("bench_replay_vs_process_bag_" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string site = fs::exists(stem + ".site.yaml") ? stem + ".site.yaml" : "";

  const std::string port = std::to_string(12000 + getpid() % 1000);
  const double replay_wall =
      Timed("ROS_MASTER_URI=http://127.0.0.1:" + port + " ROS_HOME='" + dir.string() +
            "/ros_home' roslaunch -p " + port + " slope_monitor replay.launch bag:='" + bag +
            "' database:='" + dir.string() + "/replay.db' report_dir:='" + dir.string() +
            "/replay_reports'" + (site.empty() ? "" : " site_config:='" + site + "'") + " > '" +
            dir.string() + "/replay.log' 2>&1");
  Timed("rosrun slope_monitor deformation_summary --database '" + dir.string() +
        "/replay.db' --truth '" + stem + ".truth.yaml' > '" + dir.string() +
        "/replay_summary.txt'");
  const double process_wall =
      Timed("rosrun slope_monitor process_bag --bag '" + bag + "' --database '" + dir.string() +
            "/process_bag.db' --report-dir '" + dir.string() + "/process_bag_reports'" +
            (site.empty() ? "" : " --site-config '" + site + "'") + " > '" + dir.string() +
            "/process_bag_summary.txt' 2> '" + dir.string() + "/process_bag.log'");

  const std::string a = Summary(ReadFile(dir / "replay_summary.txt"));
  const std::string b = Summary(ReadFile(dir / "process_bag_summary.txt"));
  std::cout << "replay.launch (rosbag play --clock, default rate): " << replay_wall << " s wall\n"
            << "process_bag: " << process_wall << " s wall\n"
            << "summaries " << (a == b && !a.empty() ? "identical" : "differ") << " ("
            << dir.string() << "/replay_summary.txt, process_bag_summary.txt)\n";
  if (a != b) std::cout << "--- replay.launch\n" << a << "--- process_bag\n" << b;
  std::printf("ratio replay_launch_wall/process_bag_wall = %.2f\n", replay_wall / process_wall);
  return 0;
}
