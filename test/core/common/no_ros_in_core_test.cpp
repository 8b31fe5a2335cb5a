// The core library must not depend on ROS (doc/design.md "Layers"): no file under
// include/slope_monitor/core or src/core may include a ROS, message, cv_bridge,
// rosbag, image_transport or tf2_ros header.
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace fs = std::filesystem;

namespace {

std::vector<std::string> RosIncludesUnder(const fs::path& dir) {
  static const std::regex kRosInclude(
      R"(^\s*#\s*include\s*[<"](ros/|[a-z_]*_msgs/|cv_bridge|rosbag|image_transport|tf2_ros|nodelet|pluginlib))");
  std::vector<std::string> found;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::ifstream in(entry.path());
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
      ++number;
      if (std::regex_search(line, kRosInclude)) {
        found.push_back(entry.path().string() + ":" + std::to_string(number) + ": " + line);
      }
    }
  }
  return found;
}

TEST(NoRosInCore, CoreFilesIncludeNoRosHeaders) {
  const fs::path root(SM_SOURCE_DIR);
  for (const char* sub : {"include/slope_monitor/core", "src/core"}) {
    ASSERT_TRUE(fs::is_directory(root / sub)) << (root / sub);
    const std::vector<std::string> found = RosIncludesUnder(root / sub);
    EXPECT_TRUE(found.empty()) << "ROS include in core: " << (found.empty() ? "" : found.front());
  }
}

TEST(NoRosInCore, DetectorFindsARosInclude) {
  // The check itself must be able to fail: a temporary file with a ROS include.
  const fs::path dir = fs::temp_directory_path() / "sm_no_ros_check";
  fs::create_directories(dir);
  std::ofstream(dir / "bad.h") << "#include <ros/ros.h>\n#include <sensor_msgs/Image.h>\n";
  EXPECT_EQ(RosIncludesUnder(dir).size(), 2u);
  fs::remove_all(dir);
}

}  // namespace
