// Every repository file, launch argument and topic that README.md names must
// exist:
//  * paths: words starting with a top-level directory of the repository
//    (config/, launch/, src/, ...) or naming a top-level file must exist
//    (words with a placeholder such as <site> or ... are skipped);
//  * launch arguments: every `name:=` must be declared (<arg name="name") in a
//    launch file under launch/, and every row of the table in the section
//    "The replay graph" must be an argument of launch/replay.launch;
//  * topics: a backticked `/ns/.../leaf` must name a namespace the launch files
//    declare (ns="ns" or name="ns"), and `leaf` must be a string literal in the
//    source of a nodelet running there (src/nodelets/<ns>_nodelet.cpp or the
//    nodelet a launch file loads in that namespace); a one-word topic
//    (`/diagnostics`) must be a string literal in src/ or named in a launch file.
// The checks themselves are tested on the README's former wrong claims.
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace fs = std::filesystem;

namespace {

const fs::path kRoot(SM_SOURCE_DIR);

std::string ReadFile(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// Concatenated text of every regular file under `dir` (recursively) whose
// name ends with one of `extensions`.
std::string TextUnder(const fs::path& dir, const std::vector<std::string>& extensions) {
  std::string all;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    const std::string ext = entry.path().extension().string();
    for (const std::string& e : extensions) {
      if (ext == e) all += ReadFile(entry.path()) + "\n";
    }
  }
  return all;
}

std::vector<std::string> MissingPaths(const std::string& text) {
  static const std::regex kPath(
      R"((^|[\s`(|,])((config|launch|src|include|test|doc|scripts|bench|rviz|msg|srv)/[A-Za-z0-9_./<>*-]*|CONTRIBUTING\.md|package\.xml|CMakeLists\.txt|nodelet_plugins\.xml))");
  std::vector<std::string> missing;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), kPath);
       it != std::sregex_iterator(); ++it) {
    std::string path = (*it)[2];
    if (path.find_first_of("<>*") != std::string::npos || path.find("...") != std::string::npos)
      continue;
    while (!path.empty() && (path.back() == '.' || path.back() == ',')) path.pop_back();
    if (!fs::exists(kRoot / path)) missing.push_back(path);
  }
  return missing;
}

std::set<std::string> DeclaredArgs(const std::string& launch_text) {
  static const std::regex kArg(R"re(<arg\s+name="([A-Za-z0-9_]+)"\s*(default=|/>|>))re");
  std::set<std::string> args;
  for (auto it = std::sregex_iterator(launch_text.begin(), launch_text.end(), kArg);
       it != std::sregex_iterator(); ++it) {
    args.insert((*it)[1]);
  }
  return args;
}

std::vector<std::string> UndeclaredLaunchArgs(const std::string& text) {
  const std::set<std::string> declared =
      DeclaredArgs(TextUnder(kRoot / "launch", {".launch", ".xml"}));
  static const std::regex kUse(R"(([A-Za-z0-9_]+):=)");
  std::vector<std::string> undeclared;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), kUse); it != std::sregex_iterator();
       ++it) {
    if (!declared.count((*it)[1])) undeclared.push_back((*it)[1]);
  }
  return undeclared;
}

// The first column of the argument table in the section "## The replay graph".
std::vector<std::string> ReplayTableArgs(const std::string& text) {
  const size_t start = text.find("## The replay graph");
  if (start == std::string::npos) return {};
  const size_t end = text.find("\n## ", start + 1);
  const std::string section =
      text.substr(start, end == std::string::npos ? std::string::npos : end - start);
  static const std::regex kRow(R"(\n\| `([A-Za-z0-9_]+)` \|)");
  std::vector<std::string> args;
  for (auto it = std::sregex_iterator(section.begin(), section.end(), kRow);
       it != std::sregex_iterator(); ++it) {
    args.push_back((*it)[1]);
  }
  return args;
}

std::string CamelToSnake(const std::string& camel) {
  std::string snake;
  for (char c : camel) {
    if (std::isupper(static_cast<unsigned char>(c))) {
      if (!snake.empty()) snake += '_';
      snake += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    } else {
      snake += c;
    }
  }
  return snake;
}

// Sources of the nodelets that run in namespace `ns` (empty when no launch
// file declares it).
std::vector<fs::path> NodeletsIn(const std::string& ns) {
  const std::string launch = TextUnder(kRoot / "launch", {".launch", ".xml"});
  std::vector<fs::path> sources;
  // A group or node of that name, or the default of a launch file's `ns`
  // argument (deformation_estimator.launch names its node after it).
  const std::regex kDecl("(ns|name)=\"" + ns + "\"|name=\"ns\" default=\"" + ns + "\"");
  static const std::regex kLoad(R"(load slope_monitor/([A-Za-z]+))");
  // A node of its own process: type "<x>_node" runs src/nodelets/<x>_nodelet.cpp.
  static const std::regex kNode(R"re(type="([a-z_]+)_node")re");
  bool declared = false;
  for (auto it = std::sregex_iterator(launch.begin(), launch.end(), kDecl);
       it != std::sregex_iterator(); ++it) {
    declared = true;
    // The nodelet loaded right there (within the group or node element).
    const std::string after = launch.substr(it->position(), 600);
    std::smatch load;
    const std::string element = after.substr(0, after.find("</group>"));
    if (std::regex_search(element, load, kLoad)) {
      sources.push_back(kRoot / "src/nodelets" / (CamelToSnake(load[1]) + "_nodelet.cpp"));
    } else if (std::regex_search(element, load, kNode)) {
      sources.push_back(kRoot / "src/nodelets" / (std::string(load[1]) + "_nodelet.cpp"));
    }
  }
  if (!declared) return {};
  sources.push_back(kRoot / "src/nodelets" / (ns + "_nodelet.cpp"));
  return sources;
}

std::vector<std::string> UnknownTopics(const std::string& text) {
  static const std::regex kTopic(R"(`((/[a-z][a-z0-9_]*)+)`)");
  const std::string src = TextUnder(kRoot / "src", {".cpp", ".h"});
  const std::string launch = TextUnder(kRoot / "launch", {".launch", ".xml"});
  std::vector<std::string> unknown;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), kTopic);
       it != std::sregex_iterator(); ++it) {
    const std::string topic = (*it)[1];
    const size_t leaf_at = topic.rfind('/');
    const std::string leaf = topic.substr(leaf_at + 1);
    bool found = false;
    if (leaf_at == 0) {
      found = src.find("\"" + topic + "\"") != std::string::npos ||
              src.find("\"" + leaf + "\"") != std::string::npos ||
              launch.find(topic) != std::string::npos;
    } else {
      const std::string ns = topic.substr(1, topic.find('/', 1) - 1);
      for (const fs::path& source : NodeletsIn(ns)) {
        if (fs::exists(source) && ReadFile(source).find("\"" + leaf + "\"") != std::string::npos)
          found = true;
        // Or one of that node's parameters (/deformation_estimator/threshold_alarm).
        std::string node = source.filename().string();
        node = node.substr(0, node.size() - std::string("_nodelet.cpp").size());
        const fs::path defaults = kRoot / "config/defaults" / (node + ".yaml");
        if (fs::exists(defaults) &&
            ("\n" + ReadFile(defaults)).find("\n" + leaf + ":") != std::string::npos)
          found = true;
      }
    }
    if (!found) unknown.push_back(topic);
  }
  return unknown;
}

std::string Join(const std::vector<std::string>& items) {
  std::string s;
  for (const std::string& i : items) s += (s.empty() ? "" : ", ") + i;
  return s;
}

class ReadmeClaims : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(fs::exists(kRoot / "README.md"));
    readme_ = ReadFile(kRoot / "README.md");
  }
  std::string readme_;
};

TEST_F(ReadmeClaims, EntryPointOfAtMost250Lines) {
  const auto lines = std::count(readme_.begin(), readme_.end(), '\n');
  EXPECT_LE(lines, 250) << "README.md has " << lines << " lines; details go to doc/";
}

TEST_F(ReadmeClaims, NamedFilesExist) {
  const std::vector<std::string> missing = MissingPaths(readme_);
  EXPECT_TRUE(missing.empty()) << "README.md names files that do not exist: " << Join(missing);
}

TEST_F(ReadmeClaims, LaunchArgumentsAreDeclared) {
  const std::vector<std::string> undeclared = UndeclaredLaunchArgs(readme_);
  EXPECT_TRUE(undeclared.empty()) << "README.md uses launch arguments no launch file declares: "
                                  << Join(undeclared);
  const std::vector<std::string> table = ReplayTableArgs(readme_);
  EXPECT_GE(table.size(), 10u) << "the argument table of 'The replay graph' was not found";
  const std::set<std::string> replay = DeclaredArgs(ReadFile(kRoot / "launch/replay.launch"));
  for (const std::string& arg : table) {
    EXPECT_TRUE(replay.count(arg)) << "README.md's replay table lists '" << arg
                                   << "', not an argument of launch/replay.launch";
  }
}

TEST_F(ReadmeClaims, TopicsExist) {
  const std::vector<std::string> unknown = UnknownTopics(readme_);
  EXPECT_TRUE(unknown.empty()) << "README.md names topics no nodelet publishes there: "
                               << Join(unknown);
}

// The checks catch the README's former wrong claims (issue 18).
TEST(ReadmeClaimChecks, CatchWrongClaims) {
  EXPECT_EQ(MissingPaths("see `config/sites/demo_targets.yaml` and DESIGN in `doc/DESIGN.md`"),
            (std::vector<std::string>{"config/sites/demo_targets.yaml", "doc/DESIGN.md"}));
  EXPECT_TRUE(MissingPaths("`launch/replay.launch`, `config/sites/<name>.yaml`").empty());
  EXPECT_EQ(UnknownTopics("`/radio_phase_solver/displacements` and `/radio/radio_displacements`"),
            (std::vector<std::string>{"/radio_phase_solver/displacements"}));
  EXPECT_EQ(UnknownTopics("`/deformation_estimator/alarms`"),
            (std::vector<std::string>{"/deformation_estimator/alarms"}));
  EXPECT_TRUE(UnknownTopics("`/deformation_estimator/threshold_alarm`").empty());
  EXPECT_EQ(UnknownTopics("`/deformation_estimator/threshold_alarms`"),
            (std::vector<std::string>{"/deformation_estimator/threshold_alarms"}));
  EXPECT_EQ(UndeclaredLaunchArgs("replay.launch bag:=x bagg:=demo.bag"),
            (std::vector<std::string>{"bagg"}));
  EXPECT_EQ(ReplayTableArgs("## The replay graph\n\n| arg |\n|---|\n| `bag` | x |\n| `rviz` | y "
                            "|\n\n## Next\n| `z` |"),
            (std::vector<std::string>{"bag", "rviz"}));
}

}  // namespace
