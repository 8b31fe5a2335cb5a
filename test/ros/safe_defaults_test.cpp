// Safe and unsurprising defaults (issue 38 item 6), each checked where it is
// decided, without running the graph:
//   * a history per bag: replay.launch's default `database` is the one
//     process_bag takes (ros/replay_defaults.h), and two bags get two;
//   * the services that change data are off in live.launch unless
//     services:=true, on in replay.launch (the tests call them there);
//   * a surveyors' CSV works as a target_list (the graph, process_bag);
//   * a usage error is exit status 1 in every tool (doc/security.md).
// The launch files go through roslaunch's own loader (scripts/check_launch,
// about 1 s of Python per run).
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "run_command.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/param_files.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/replay_defaults.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

const std::string kSdSource = SM_SOURCE_DIR;

// "<launch file name> <node>" -> private parameters of each slope_monitor
// node the launch files load, each file with its arguments (one
// scripts/check_launch --dump run; each launch file at most once).
using SdParams = std::map<std::string, XmlRpc::XmlRpcValue>;
SdParams SdLaunchParams(const std::vector<std::pair<std::string, std::string>>& launches) {
  const std::string dump = "/tmp/safe_defaults_test_" + std::to_string(::getpid()) + ".json";
  std::string command = kSdSource + "/scripts/check_launch --dump " + dump;
  for (const auto& [launch, args] : launches)
    command += " " + kSdSource + "/launch/" + launch + " " + args + " --";
  const run_command::CommandRun r = run_command::Run(command);
  EXPECT_EQ(r.status, 0) << command << "\n" << r.output;
  SdParams out;
  if (r.status != 0) return out;
  XmlRpc::XmlRpcValue all = LoadParamFile(dump);
  std::remove(dump.c_str());
  XmlRpc::XmlRpcValue& nodes = all["nodes"];
  for (auto file = nodes.begin(); file != nodes.end(); ++file)
    for (int i = 0; i < file->second.size(); ++i)
      out[std::filesystem::path(file->first).filename().string() + " " +
          std::string(file->second[i]["node"])] = file->second[i]["params"];
  return out;
}

// A parameter's value as text ("on" / "off" for a boolean), "(not set)" if absent.
std::string SdValue(SdParams& params, const std::string& node, const std::string& key) {
  if (!params.count(node) || !params[node].hasMember(key)) return "(not set)";
  XmlRpc::XmlRpcValue& v = params[node][key];
  if (v.getType() == XmlRpc::XmlRpcValue::TypeBoolean) return bool(v) ? "on" : "off";
  return std::string(v);
}

// Two check_launch runs: replay.launch of two bags, live.launch with its
// defaults and with services:=true.
TEST(SafeDefaults, OneHistoryPerSiteAndNoDataChangingServicesOnALiveSite) {
  const std::string home = std::getenv("HOME");
  const std::string site = "site:=" + kSdSource + "/config/sites/demo.yaml";
  const std::string bag_a = "/data/north/site_a.bag", bag_b = "/data/south/site_b.bag";
  // Without anything naming the site: the recording's name.
  EXPECT_EQ(DefaultHistory({"", "", "", bag_a}, home), home + "/.ros/slope_monitor/site_a.db");
  EXPECT_EQ(DefaultHistory({"", "", "", "site_b.bag"}, home),
            home + "/.ros/slope_monitor/site_b.db");
  // The site file's name wins over the recording's: every recording of a site, one history.
  EXPECT_EQ(DefaultHistory({kSdSource + "/config/sites/demo.yaml", "", "", bag_a}, home),
            home + "/.ros/slope_monitor/demo.db");
  EXPECT_EQ(ResolveDatabase("/data/x.db", {"", "", "", bag_a}), "/data/x.db");
  EXPECT_EQ(ResolveDatabase("", {"", "", "", bag_a}), "");
  EXPECT_THROW(DefaultHistory({}, home), ConfigError);
  SdParams first = SdLaunchParams({{"replay.launch", "bag:=" + bag_a}, {"live.launch", site}});
  SdParams second = SdLaunchParams(
      {{"replay.launch", "bag:=" + bag_b}, {"live.launch", site + " services:=true"}});
  // The history: "auto" in replay.launch and live.launch, for every node
  // that keeps a reference, resolved by the same rule as process_bag's.
  for (const char* node :
       {" /deformation_estimator", " /bundle_adjuster", " /radio/radio_phase_solver"}) {
    EXPECT_EQ(SdValue(first, std::string("replay.launch") + node, "database"), "auto") << node;
    EXPECT_EQ(SdValue(first, std::string("live.launch") + node, "database"), "auto") << node;
  }
  EXPECT_EQ(SdValue(first, "replay.launch /deformation_estimator", "recording"), bag_a);
  EXPECT_EQ(SdValue(second, "replay.launch /bundle_adjuster", "recording"), bag_b);
  // The services that change data: off in live.launch unless services:=true;
  // otherwise as config/defaults says (on), in replay.launch too.
  const std::vector<std::pair<std::string, std::string>> switches = {
      {" /bundle_adjuster", "enable_run_adjustment"},
      {" /bundle_adjuster", "enable_set_reference_epoch"},
      {" /deformation_estimator", "enable_export_report"},
      {" /deformation_estimator", "enable_set_reference_epoch"}};
  for (const auto& [node, key] : switches) {
    EXPECT_EQ(SdValue(first, "live.launch" + node, key), "off") << "live.launch" << node << key;
    EXPECT_EQ(SdValue(second, "live.launch" + node, key), "on")
        << "live.launch services:=true" << node << " " << key;
    EXPECT_EQ(SdValue(first, "replay.launch" + node, key), "on")
        << "replay.launch" << node << " " << key;
  }
}

// Two cameras recorded with camera_capture.launch's own example lines
// (ns:=north_ridge/camera, ns:=drone/camera, no camera_name) keep their own
// optical frames (both were camera_optical, and the adjuster
// publishes one transform per frame); camera_name:= still names it.
TEST(SafeDefaults, EachCapturedCameraItsOwnFrame) {
  SdParams north = SdLaunchParams(
      {{"camera_capture.launch", "ns:=north_ridge/camera source:=folder folder:=/data/n"}});
  SdParams drone = SdLaunchParams(
      {{"camera_capture.launch", "ns:=/drone/camera source:=folder folder:=/data/d"}});
  SdParams named = SdLaunchParams(
      {{"camera_capture.launch", "ns:=cam camera_name:=gully source:=folder folder:=/data/g"}});
  EXPECT_EQ(SdValue(north, "camera_capture.launch /north_ridge/camera/camera_capture", "frame_id"),
            "north_ridge_optical");
  EXPECT_EQ(
      SdValue(north, "camera_capture.launch /north_ridge/camera/camera_capture", "camera_name"),
      "north_ridge");
  EXPECT_EQ(SdValue(drone, "camera_capture.launch /drone/camera/camera_capture", "frame_id"),
            "drone_optical");
  EXPECT_EQ(SdValue(named, "camera_capture.launch /cam/camera_capture", "frame_id"),
            "gully_optical");
}

// A target_list in the surveyors' CSV of doc/your_own_site.md, read as the
// bundle adjuster (and process_bag's --target-list) reads it.
AdjusterParameters SdReadAdjuster(const std::string& target_list, const std::string& site = "") {
  XmlRpc::XmlRpcValue p = LoadParamFile(kSdSource + "/config/defaults/bundle_adjuster.yaml");
  SetParam(&p, "target_list", target_list);
  if (!site.empty()) SetParam(&p, "site_file", site);
  ParamReader r(p, "/bundle_adjuster");
  return ReadAdjusterParameters(r);
}

TEST(SafeDefaults, ASurveyorsCsvIsATargetList) {
  const std::string stem = "/tmp/safe_defaults_test_" + std::to_string(::getpid());
  std::ofstream(stem + "_site.csv") << "# crs: site\n"
                                       "id,role,x,y,z,sigma_h,sigma_v\n"
                                       "tag36h11/0,control,10.0,20.0,3.0,0.010,0.020\n"
                                       "tag36h11/1,monitoring,-5.0,7.5,1.0,0.30,0.50\n"
                                       "circle/3,check,0,0,0,0.010,0.020\n";
  const AdjusterParameters a = SdReadAdjuster(stem + "_site.csv");
  ASSERT_EQ(a.targets.targets().size(), 3u);
  const io::TargetSpec* t0 = a.targets.Find("tag36h11", 0);
  ASSERT_NE(t0, nullptr);
  EXPECT_EQ(t0->role, io::TargetRole::kControl);
  ASSERT_TRUE(t0->position.has_value());
  EXPECT_EQ(*t0->position, Eigen::Vector3d(10.0, 20.0, 3.0));
  EXPECT_EQ(t0->sigma, Eigen::Vector2d(0.010, 0.020));
  ASSERT_NE(a.targets.Find("circle", 3), nullptr);
  EXPECT_EQ(a.targets.Find("circle", 3)->role, io::TargetRole::kCheck);

  // In WGS 84, placed by the site file's CRS: the site's origin is (0, 0, 0).
  std::ofstream(stem + "_site.yaml") << "name: csv_test\ncrs: EPSG:4979\n"
                                        "origin: [8.0, 46.5, 1200.0]\n";
  std::ofstream(stem + "_wgs84.csv") << "# crs: WGS 84\n"
                                        "id,role,x,y,z,sigma_h,sigma_v\n"
                                        "tag36h11/5,control,8.0,46.5,1200.0,0.010,0.020\n";
  const AdjusterParameters b = SdReadAdjuster(stem + "_wgs84.csv", stem + "_site.yaml");
  ASSERT_NE(b.targets.Find("tag36h11", 5), nullptr);
  EXPECT_LT(b.targets.Find("tag36h11", 5)->position->norm(), 1e-6);
  // Without a site file nothing says where WGS 84 is in the site frame: named.
  try {
    SdReadAdjuster(stem + "_wgs84.csv");
    ADD_FAILURE() << "a WGS 84 CSV without a site file was taken";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("target list '" + stem + "_wgs84.csv'"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("no site file"), std::string::npos) << e.what();
  }
  for (const char* f : {"_site.csv", "_site.yaml", "_wgs84.csv"}) std::remove((stem + f).c_str());
}

TEST(SafeDefaults, AUsageErrorIsExitStatusOneInEveryTool) {
  // The tools that said 2 on a usage error before issue 38 (the others said
  // 1 already: ToolErrors.*, ProcessBag.*): an unknown flag, then no argument.
  for (const std::string tool : {"bag_check", "deformation_summary", "make_survey_bag"}) {
    const run_command::CommandRun r =
        run_command::Run(std::string(SM_TOOL_DIR) + "/" + tool + " --no-such-flag");
    EXPECT_EQ(r.status, 1) << tool << " --no-such-flag:\n" << r.output;
    EXPECT_NE(r.output.find("'--no-such-flag'"), std::string::npos) << tool << ":\n" << r.output;
  }
  for (const std::string tool :
       {"bag_check", "deformation_summary", "make_survey_bag", "solve_bal"}) {
    const run_command::CommandRun r = run_command::Run(std::string(SM_TOOL_DIR) + "/" + tool);
    EXPECT_EQ(r.status, 1) << tool << " without arguments:\n" << r.output;
    EXPECT_NE(r.output.find("usage"), std::string::npos) << tool << ":\n" << r.output;
  }
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
