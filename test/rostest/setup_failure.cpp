// Test node of setup_failure.test: each node with a rejected parameter
// publishes ERROR "not running: parameters rejected: ..." naming the key or file, again
// and again (not once), and advertises none of its outputs.
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/master.h>

#include "test_node.h"

namespace slope_monitor {
namespace {

struct Seen {
  std::mutex mutex;
  std::map<std::string, std::vector<std::string>> errors;  // hardware id -> ERROR messages
};

TEST(SetUpFailure, RejectedParametersGiveRepeatedErrorDiagnosticsNamingTheKey) {
  ros::NodeHandle nh;
  Seen seen;
  ros::Subscriber sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 20, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
        std::lock_guard<std::mutex> lock(seen.mutex);
        for (const auto& st : m->status)
          if (st.level == diagnostic_msgs::DiagnosticStatus::ERROR)
            seen.errors[st.hardware_id].push_back(st.message);
      });
  auto count = [&](const std::string& id) {
    std::lock_guard<std::mutex> lock(seen.mutex);
    return seen.errors[id].size();
  };
  // Every second: at least three from each within 30 s.
  ASSERT_TRUE(rostest_node::WaitFor(
      [&] { return count("bundle_adjuster") >= 3 && count("hex_matcher") >= 3; }, 30.0))
      << "ERROR diagnostics: bundle_adjuster " << count("bundle_adjuster") << ", hex_matcher "
      << count("hex_matcher");
  std::lock_guard<std::mutex> lock(seen.mutex);
  const std::string& ba = seen.errors["bundle_adjuster"].back();
  EXPECT_NE(ba.find("not running: parameters rejected"), std::string::npos) << ba;
  EXPECT_NE(ba.find("/nonexistent/site.targets.yaml"), std::string::npos) << ba;
  const std::string& hm = seen.errors["hex_matcher"].back();
  EXPECT_NE(hm.find("not running: parameters rejected"), std::string::npos) << hm;
  EXPECT_NE(hm.find("mode"), std::string::npos) << hm;
  // Nothing advertised: no solution, no tie points.
  ros::master::V_TopicInfo topics;
  ASSERT_TRUE(ros::master::getTopics(topics));
  for (const auto& t : topics) {
    EXPECT_EQ(t.name.find("/solution"), std::string::npos) << t.name;
    EXPECT_EQ(t.name.find("/tie_points"), std::string::npos) << t.name;
  }
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "setup_failure_test");
}
