// Every file under config/ and launch/ loaded by what owns it (the idea of
// cartographer_ros's configuration_files_test): a node's yaml through that
// node's parameter reader (an unknown key, a value out of range or of the
// wrong type is an error naming it), a site file through io::LoadSiteFile,
// a simulator config through sim::SurveyConfig::CfLoad, a radio network through
// radio::NetworkConfig::CfLoad; every launch file through roslaunch's own
// loader (scripts/check_launch: XML, arguments, includes, rosparam files,
// node executables and nodelet plugins; nothing is started), and the private
// parameters each launch file gives a slope_monitor node through that node's
// reader. A file no test knows how to load fails the test.
//
// Defaults live in the Options structs: config/defaults/<node>.yaml must
// hold, for every key, the value the reader takes when the key is not set
// (ParamReader::Defaults), and every key the reader reads. An overlay
// (config/process_bag/, config/*.yaml adjuster / dense configurations) holds
// only values that differ from the defaults file, each with a comment.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <gtest/gtest.h>

#include "run_command.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/site_file.h"
#include "slope_monitor/core/radio/phase_solver.h"
#include "slope_monitor/core/sim/survey.h"
#include "slope_monitor/core/targets/options_reader.h"
#include "slope_monitor/ros/capture_parameters.h"
#include "slope_monitor/ros/dense_conversions.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/param_files.h"
#include "slope_monitor/ros/parameters.h"
#include "slope_monitor/ros/targetless_camera.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

namespace fs = std::filesystem;

const std::string kCfSource = SM_SOURCE_DIR;
const std::string kCfDemoSite = kCfSource + "/config/sites/demo.yaml";
const std::string kCfTargets = kCfSource + "/test/rostest/service_switches.targets.yaml";

using CfReader = std::function<void(ParamReader&)>;

// The parameter reader of each node, by the node's name (its defaults file's
// stem; a nodelet's class name in snake case).
const std::map<std::string, CfReader>& CfNodeReaders() {
  static const std::map<std::string, CfReader> readers = {
      {"bundle_adjuster", [](ParamReader& p) { ReadAdjusterParameters(p); }},
      {"camera_capture", [](ParamReader& p) { ReadCaptureParameters(p, "/fixed_cam_1/camera"); }},
      {"deformation_estimator", [](ParamReader& p) { ReadEstimatorParameters(p); }},
      {"dense_epoch", [](ParamReader& p) { ReadDenseEpochParameters(p); }},
      {"dense_matcher", [](ParamReader& p) { ReadDenseMatcherParameters(p); }},
      {"hex_matcher", [](ParamReader& p) { ReadHexMatcherParameters(p); }},
      {"radio_phase_solver", [](ParamReader& p) { ReadRadioParameters(p); }},
      {"target_centroider",
       [](ParamReader& p) {
         targets::ReadOptions(p).Check();
         targets::ReadNodeOptions(p);
         p.CheckNoUnknownKeys();
       }},
      {"targetless_camera", [](ParamReader& p) { ReadTargetlessParameters(p); }},
  };
  return readers;
}

// Keys a node cannot do without (a file to read), set for the test; the
// defaults files leave them empty.
XmlRpc::XmlRpcValue CfRequired(const std::string& node) {
  XmlRpc::XmlRpcValue r;
  r.begin();
  if (node == "targetless_camera") r["site_file"] = kCfDemoSite;
  if (node == "bundle_adjuster") r["target_list"] = kCfTargets;
  return r;
}

XmlRpc::XmlRpcValue CfLoad(const std::string& path) { return LoadParamFile(path); }

XmlRpc::XmlRpcValue CfMerged(XmlRpc::XmlRpcValue base, const XmlRpc::XmlRpcValue& over) {
  MergeParams(&base, over);
  return base;
}

// Reads `params` as node `node` does; returns what the reader asked for with
// its defaults. Fails the test (naming `what`) on a ConfigError.
std::map<std::string, XmlRpc::XmlRpcValue> CfReadAs(const std::string& node,
                                                    const XmlRpc::XmlRpcValue& params,
                                                    const std::string& what) {
  ParamReader p(params, "/" + node);
  try {
    CfNodeReaders().at(node)(p);
  } catch (const Error& e) {
    ADD_FAILURE() << what << " read as " << node << ": " << e.what();
  }
  return p.Defaults();
}

bool CfSameValue(XmlRpc::XmlRpcValue a, XmlRpc::XmlRpcValue b) {
  using V = XmlRpc::XmlRpcValue;
  const auto number = [](V& v, double* d) {
    if (v.getType() == V::TypeDouble)
      *d = static_cast<double>(v);
    else if (v.getType() == V::TypeInt)
      *d = static_cast<int>(v);
    else
      return false;
    return true;
  };
  double x, y;
  if (number(a, &x) && number(b, &y))
    return x == y || std::abs(x - y) <= 1e-12 * std::max(std::abs(x), std::abs(y));
  if (a.getType() != b.getType()) return false;
  if (a.getType() == V::TypeArray) {
    if (a.size() != b.size()) return false;
    for (int i = 0; i < a.size(); ++i)
      if (!CfSameValue(a[i], b[i])) return false;
    return true;
  }
  return a == b;
}

std::string CfText(XmlRpc::XmlRpcValue v) {
  std::ostringstream s;
  v.write(s);
  return s.str();
}

// A parameter file's keys as the parameter server names them
// ("schedule/interval"), with their values.
void CfFlatten(XmlRpc::XmlRpcValue& tree, const std::string& prefix,
               std::map<std::string, XmlRpc::XmlRpcValue>* out) {
  for (auto it = tree.begin(); it != tree.end(); ++it) {
    if (it->second.getType() == XmlRpc::XmlRpcValue::TypeStruct && it->second.size() > 0)
      CfFlatten(it->second, prefix + it->first + "/", out);
    else
      (*out)[prefix + it->first] = it->second;
  }
}

// A key whose default is computed (from the node's namespace, or the mode)
// is documented as a comment, "# <key>: ...".
bool CfDocumentedAsComment(const std::string& path, const std::string& key) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return ("\n" + s.str()).find("\n# " + key + ":") != std::string::npos;
}

std::vector<std::string> CfFilesUnder(const std::string& dir) {
  std::vector<std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (e.is_regular_file()) out.push_back(e.path().string());
  std::sort(out.begin(), out.end());
  return out;
}

// config/defaults/<node>.yaml: every key is read, every value is the reader's
// default (the Options struct's in-class value), every key read is in it.
TEST(ConfigFiles, DefaultsFilesHoldTheStructsDefaults) {
  std::set<std::string> nodes;
  for (const std::string& path : CfFilesUnder(kCfSource + "/config/defaults")) {
    const std::string node = fs::path(path).stem().string();
    nodes.insert(node);
    ASSERT_TRUE(CfNodeReaders().count(node))
        << path << ": no reader for node '" << node << "' in this test";
    const std::map<std::string, XmlRpc::XmlRpcValue> defaults =
        CfReadAs(node, CfRequired(node), "(nothing set)");
    XmlRpc::XmlRpcValue file = CfLoad(path);
    CfReadAs(node, CfMerged(file, CfRequired(node)), path);
    std::map<std::string, XmlRpc::XmlRpcValue> keys;
    CfFlatten(file, "", &keys);
    for (auto& [key, value] : keys) {
      const auto d = defaults.find(key);
      if (d == defaults.end())
        continue;  // a key read only in some modes: the read above checked it
      EXPECT_TRUE(CfSameValue(value, d->second))
          << path << ": " << key << " = " << CfText(value) << ", the reader's default is "
          << CfText(d->second);
    }
    for (const auto& [key, value] : defaults)
      EXPECT_TRUE(keys.count(key) || CfDocumentedAsComment(path, key))
          << path << ": key '" << key << "' (default " << CfText(value)
          << ") is read by the node but not documented in the file";
  }
  for (const auto& [node, reader] : CfNodeReaders())
    EXPECT_TRUE(nodes.count(node)) << "config/defaults/" << node << ".yaml is missing";
}

// Each key line of an overlay has a comment on it or on the line above.
void CfExpectEveryKeyCommented(const std::string& path) {
  std::ifstream in(path);
  std::string line, previous;
  while (std::getline(in, line)) {
    const bool key =
        !line.empty() && line[0] != ' ' && line[0] != '#' && line.find(':') != std::string::npos;
    if (key) {
      EXPECT_TRUE(line.find('#') != std::string::npos || previous.rfind("#", 0) == 0)
          << path << ": '" << line << "' says not why it differs from the defaults";
    }
    previous = line;
  }
}

// An overlay of node `node`: merged over its defaults file it reads, and
// every value in it differs from the defaults file's.
void CfCheckOverlay(const std::string& path, const std::string& node) {
  SCOPED_TRACE(path);
  const XmlRpc::XmlRpcValue defaults = CfLoad(kCfSource + "/config/defaults/" + node + ".yaml");
  XmlRpc::XmlRpcValue overlay = CfLoad(path);
  CfReadAs(node, CfMerged(CfMerged(defaults, overlay), CfRequired(node)), path);
  XmlRpc::XmlRpcValue& d = const_cast<XmlRpc::XmlRpcValue&>(defaults);
  for (auto it = overlay.begin(); it != overlay.end(); ++it) {
    if (d.hasMember(it->first)) {
      EXPECT_FALSE(CfSameValue(it->second, d[it->first]))
          << path << ": " << it->first << " = " << CfText(it->second)
          << " is the defaults file's value already";
    }
  }
  CfExpectEveryKeyCommented(path);
}

// Which owner loads a file under config/ ("" = none known: the test fails).
std::string CfOwnerOf(const std::string& path) {
  const std::string rel = fs::relative(path, kCfSource + "/config").string();
  const std::string dir = fs::path(rel).parent_path().string();
  const std::string stem = fs::path(rel).stem().string();
  if (dir == "defaults") return "defaults";
  if (dir == "process_bag") return "overlay:" + stem;
  if (dir == "sites") return "site";
  if (dir == "sim") return "sim";
  if (dir == "radio") return "radio";
  if (rel == "uav_self_calibration.yaml") return "overlay:bundle_adjuster";
  if (rel == "dense_cones.yaml") return "overlay:dense_matcher";
  return "";
}

TEST(ConfigFiles, EveryConfigFileLoadsThroughItsOwner) {
  int loaded = 0;
  for (const std::string& path : CfFilesUnder(kCfSource + "/config")) {
    SCOPED_TRACE(path);
    const std::string owner = CfOwnerOf(path);
    try {
      if (owner == "defaults") {
        continue;  // DefaultsFilesHoldTheStructsDefaults
      } else if (owner.rfind("overlay:", 0) == 0) {
        CfCheckOverlay(path, owner.substr(8));
      } else if (owner == "site") {
        io::LoadSiteFile(path);
      } else if (owner == "sim") {
        sim::SurveyConfig::Load(path);
      } else if (owner == "radio") {
        radio::NetworkConfig::Load(path);
      } else {
        ADD_FAILURE() << path
                      << ": no reader for this file in config_files_test (add it to CfOwnerOf)";
        continue;
      }
      ++loaded;
    } catch (const Error& e) {
      ADD_FAILURE() << e.what();
    }
  }
  EXPECT_GE(loaded, 14);
}

// A key's file that does not exist here (a launch argument's default built
// from the bag's name, say) is replaced by one that does, or left out.
void CfStubMissingFiles(XmlRpc::XmlRpcValue* params) {
  for (const char* key :
       {"target_list", "truth_file", "network_file", "site_file", "stable_polygons", "stable_mask",
        "report_dem", "camera_info_url", "folder", "video_file"}) {
    if (!params->hasMember(key) || (*params)[key].getType() != XmlRpc::XmlRpcValue::TypeString)
      continue;
    const std::string value = (*params)[key];
    if (value.empty() || fs::exists(value)) continue;
    if (std::string(key) == "target_list") {
      (*params)[key] = kCfTargets;
      continue;
    }
    XmlRpc::XmlRpcValue without;
    without.begin();
    for (auto it = params->begin(); it != params->end(); ++it)
      if (it->first != key) without[it->first] = it->second;
    *params = without;
  }
}

// The node name of a launch file's node type: slope_monitor/TargetCentroider
// and slope_monitor/target_centroider_node are both target_centroider.
std::string CfNodeOfType(const std::string& type) {
  std::string name = type.substr(type.find('/') + 1), out;
  for (char c : name) {
    if (std::isupper(static_cast<unsigned char>(c))) {
      if (!out.empty()) out += '_';
      out += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    } else {
      out += c;
    }
  }
  if (out.size() > 5 && out.compare(out.size() - 5, 5, "_node") == 0) out.resize(out.size() - 5);
  return out;
}

// Every launch file (with the arguments that exercise its branches) through
// roslaunch's loader, and each slope_monitor node's private parameters
// through its reader.
TEST(ConfigFiles, EveryLaunchFileLoadsAndItsNodesParametersRead) {
  const std::string bag = "/tmp/config_files_test.bag";
  const std::string site = "site:=" + kCfDemoSite;
  const std::map<std::string, std::vector<std::string>> runs = {
      {"bundle_adjuster.launch", {"target_list:=" + kCfTargets}},
      {"replay.launch", {"bag:=" + bag}},
      {"replay.launch ", {"bag:=" + bag, site, "uav_tie_points:=true"}},
      {"live.launch", {site}},                                       // its site file is required
      {"target_centroider.launch", {"camera:=north_ridge/camera"}},  // no default camera name
  };
  std::set<std::string> launch_files;
  for (const std::string& path : CfFilesUnder(kCfSource + "/launch"))
    if (fs::path(path).extension() == ".launch")
      launch_files.insert(fs::path(path).filename().string());
  std::string command = kCfSource + "/scripts/check_launch --dump ";
  const std::string dump = "/tmp/config_files_test_" + std::to_string(::getpid()) + ".json";
  command += dump;
  std::set<std::string> covered;
  for (const auto& [name, args] : runs) {
    covered.insert(name.substr(0, name.find(' ')));
    command += " " + kCfSource + "/launch/" + name.substr(0, name.find(' '));
    for (const std::string& a : args) command += " " + a;
    command += " --";
  }
  for (const std::string& name : launch_files)
    if (!covered.count(name)) command += " " + kCfSource + "/launch/" + name + " --";
  const run_command::CommandRun r = run_command::Run(command);
  ASSERT_EQ(r.status, 0) << command << "\n" << r.output;
  XmlRpc::XmlRpcValue loaded = CfLoad(dump);
  std::remove(dump.c_str());
  // Every file under launch/ (include/*.xml too) is reached from a launch file.
  std::set<std::string> reached;
  for (int i = 0; i < loaded["files"].size(); ++i) reached.insert(std::string(loaded["files"][i]));
  for (const std::string& path : CfFilesUnder(kCfSource + "/launch"))
    EXPECT_TRUE(reached.count(fs::canonical(path).string()))
        << path << " is loaded by no launch file the test runs";
  XmlRpc::XmlRpcValue& all = loaded["nodes"];
  int nodes_read = 0;
  for (auto file = all.begin(); file != all.end(); ++file) {
    for (int i = 0; i < file->second.size(); ++i) {
      XmlRpc::XmlRpcValue& n = file->second[i];
      const std::string node = CfNodeOfType(n["type"]);
      XmlRpc::XmlRpcValue params = n["params"];
      if (params.getType() != XmlRpc::XmlRpcValue::TypeStruct) params.begin();
      if (!CfNodeReaders().count(node)) {
        EXPECT_EQ(params.size(), 0) << file->first << ": node " << std::string(n["node"]) << " ("
                                    << node << ") has parameters and no reader in this test";
        continue;
      }
      CfStubMissingFiles(&params);
      CfReadAs(node, CfMerged(CfRequired(node), params),
               file->first + " " + std::string(n["node"]));
      ++nodes_read;
    }
  }
  EXPECT_GE(nodes_read, 18);  // replay x2, live x2 (6 + 7 + 6 + 6 nodes with readers) is more
}

// The checks fail on what they are for: an unknown key in a defaults file, a
// defaults file whose value is not the struct's, a broken launch file.
TEST(ConfigFiles, TheChecksFail) {
  XmlRpc::XmlRpcValue file = CfLoad(kCfSource + "/config/defaults/bundle_adjuster.yaml");
  SetParam(&file, "los_scale", 3.0);
  ParamReader p(file, "/bundle_adjuster");
  EXPECT_THROW(ReadAdjusterParameters(p), ConfigError);
  const auto defaults = CfReadAs("bundle_adjuster", CfRequired("bundle_adjuster"), "(nothing set)");
  EXPECT_FALSE(CfSameValue(XmlRpc::XmlRpcValue(4.0), defaults.at("loss_scale")));
  EXPECT_TRUE(CfSameValue(XmlRpc::XmlRpcValue(3), defaults.at("loss_scale")));
  const std::string bad = "/tmp/config_files_test_" + std::to_string(::getpid()) + ".launch";
  std::ofstream(bad)
      << "<launch><node pkg=\"slope_monitor\" type=\"no_such_node\" name=\"x\"/></launch>\n";
  const run_command::CommandRun r = run_command::Run(kCfSource + "/scripts/check_launch " + bad);
  std::remove(bad.c_str());
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("no_such_node"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
