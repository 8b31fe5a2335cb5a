// replay.launch site:=config/sites/demo.yaml: a tf listener started `late`
// seconds after playback began sees `site` (latched /tf_static), and the
// deformation estimator, which reads the site file, is up. Also ROS's own
// command-line tools on the graph's interfaces (issue 38): `rostopic echo -n 1`
// of an output topic of each message package, `rosservice call` of every service.
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <ros/ros.h>
#include <ros/service.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "slope_monitor/AdjustmentSolution.h"

#include "../ros/run_command.h"
#include "test_node.h"

extern char** environ;

namespace slope_monitor {
namespace {

using rostest_node::Param;
using rostest_node::WaitFor;

bool Advertised(const std::string& topic) {
  ros::master::V_TopicInfo topics;
  ros::master::getTopics(topics);
  for (const ros::master::TopicInfo& t : topics)
    if (t.name == topic) return true;
  return false;
}

// Every solution of the bundle adjuster, from the start (latched: the latest
// also reaches a late subscriber).
std::vector<AdjustmentSolution> solutions;
std::vector<double> received;  // [s] bag clock when each came
std::mutex solutions_mutex;
ros::Subscriber solution_sub;
double clock_started = 0.0;  // [s] bag clock when the test first saw it run

void OnSolution(const AdjustmentSolutionConstPtr& m) {
  std::lock_guard<std::mutex> lock(solutions_mutex);
  solutions.push_back(*m);
  received.push_back(ros::Time::now().toSec());
}

// The master's system state: topic or service -> the nodes that publish,
// subscribe or provide it (index 0, 1, 2 of getSystemState).
std::map<std::string, std::set<std::string>> SystemState(int index) {
  XmlRpc::XmlRpcValue args, result, payload;
  args[0] = ros::this_node::getName();
  std::map<std::string, std::set<std::string>> out;
  if (!ros::master::execute("getSystemState", args, result, payload, false)) return out;
  XmlRpc::XmlRpcValue& list = payload[index];
  for (int i = 0; i < list.size(); ++i)
    for (int j = 0; j < list[i][1].size(); ++j)
      out[static_cast<std::string>(list[i][0])].insert(static_cast<std::string>(list[i][1][j]));
  return out;
}

// A node of the graph under test: not the player, rosout, this test node or a
// command-line tool it started.
bool GraphNode(const std::string& node) {
  return node != "/player" && node != "/rosout" && node != ros::this_node::getName() &&
         node.rfind("/rostopic_", 0) != 0 && node.rfind("/rosservice_", 0) != 0;
}

bool AnyGraphNode(const std::set<std::string>& nodes) {
  for (const std::string& n : nodes)
    if (GraphNode(n)) return true;
  return false;
}

struct Echo {
  std::string topic;
  bool message_expected = true;  // false: a type this survey sends nothing on (`listen`)
  pid_t pid = -1;
  std::string output_file;
};
std::vector<Echo> echoes;

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// `rostopic echo -n 1 --noarr <topic>` in the background, stdout and stderr to `output_file`.
pid_t StartEcho(const std::string& topic, const std::string& output_file) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, output_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                   0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  std::vector<std::string> argv = {"rostopic", "echo", "-n", "1", "--noarr", topic};
  std::vector<char*> args;
  for (std::string& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, "rostopic", &actions, nullptr, args.data(), environ) != 0) pid = -1;
  posix_spawn_file_actions_destroy(&actions);
  return pid;
}

TEST(SiteTfStatic, ALateListenerSeesTheSiteFrame) {
  ros::NodeHandle nh;
  solution_sub = nh.subscribe("/bundle_adjuster/solution", 10, &OnSolution);
  ros::NodeHandle pnh("~");
  const double late = Param(pnh, "late", 12.0);
  const double wait = Param(pnh, "wait", 5.0);
  // Playback has begun once the bag's clock runs.
  ASSERT_TRUE(WaitFor([] { return !ros::Time::now().isZero(); }, 60.0))
      << "no /clock from rosbag play";
  clock_started = ros::Time::now().toSec();
  ros::WallDuration(late).sleep();
  // Only now a listener starts, long after the bag's single /tf_static message was played.
  tf2_ros::Buffer buffer;
  tf2_ros::TransformListener listener(buffer);
  // rx1_antenna comes from the bag only (nothing in the graph publishes it).
  for (const char* frame : {"rx1_antenna", "rx5_antenna", "fixed_cam_1_optical"}) {
    EXPECT_TRUE(WaitFor([&] { return buffer.canTransform("site", frame, ros::Time(0)); }, wait))
        << "site -> " << frame << " not known to a listener started " << late
        << " s after playback began";
  }
  EXPECT_TRUE(buffer._frameExists("site")) << buffer.allFramesAsString();
  // The nodes read the site file: the estimator advertises its outputs only
  // when every parameter (site_file among them) was accepted.
  EXPECT_TRUE(WaitFor([] { return Advertised("/deformation_estimator/deformation"); }, wait));
}

// Issue 18: every node's parameters sit under its own name, once
// (/deformation_estimator/threshold_alarm, not
// /deformation_estimator/deformation_estimator/threshold_alarm), and its
// outputs and services beside them.
TEST(SiteTfStatic, ParametersSitUnderTheNodeNameOnce) {
  ASSERT_TRUE(WaitFor([] { return Advertised("/deformation_estimator/deformation"); }, 60.0));
  for (const char* key :
       {"/deformation_estimator/threshold_alarm", "/deformation_estimator/site_file",
        "/bundle_adjuster/epoch_wait", "/bundle_adjuster/site_file",
        "/radio/radio_phase_solver/site_file", "/dense/dense_matcher/report_dir"})
    EXPECT_TRUE(ros::param::has(key)) << key;
  for (const char* doubled :
       {"/deformation_estimator/deformation_estimator", "/bundle_adjuster/bundle_adjuster"})
    EXPECT_FALSE(ros::param::has(doubled)) << doubled;
  for (const char* service : {"/bundle_adjuster/run_adjustment", "/bundle_adjuster/resect_camera",
                              "/deformation_estimator/export_report"})
    EXPECT_TRUE(ros::service::waitForService(service, ros::Duration(10.0))) << service;
  EXPECT_TRUE(WaitFor([] { return Advertised("/bundle_adjuster/solution"); }, 10.0));
}

// Issue 18: the cameras come from the site file (demo.yaml lists fixed_cam_1,
// fixed_cam_2 and a uav): one centroider serves every camera with targets, and
// the bundle adjuster waits only for those the bag has (fixed_cam_1; the others
// never send): both epochs are solved, the first while the bag still plays.
TEST(SiteTfStatic, TheSiteFilesCamerasAreServedAndEveryEpochSolved) {
  for (const char* topic : {"/fixed_cam_1/targets", "/fixed_cam_2/targets", "/uav/targets"})
    EXPECT_TRUE(WaitFor([&] { return Advertised(topic); }, 10.0)) << topic;
  ASSERT_TRUE(WaitFor(
      [] {
        std::lock_guard<std::mutex> lock(solutions_mutex);
        return solutions.size() >= 2;
      },
      60.0))
      << "fewer than 2 adjustment solutions";
  std::lock_guard<std::mutex> lock(solutions_mutex);
  EXPECT_EQ(solutions.size(), 2u);
  EXPECT_NE(solutions[0].epoch, solutions[1].epoch);
  // The first epoch was not held for the absent cameras until the end of the
  // bag (the next epoch's markers come 60 s of bag time later).
  EXPECT_LT(received[0], clock_started + 30.0)
      << "epoch " << solutions[0].epoch << " solved " << received[0] - clock_started
      << " s of bag time after the replay began";
}

// Echoes one latched output topic of each message package the graph
// publishes (`echo`; the test fails when a package has none: a package's
// Python module loads all its types at once), and subscribes to `listen`
// (topics this survey sends nothing on, or not latched: the type loaded, no
// error). Starts them; StartEchoes' caller collects them with CheckEchoes.
void StartEchoes(const ros::NodeHandle& pnh) {
  std::vector<std::string> topics, listen;
  std::string tools_dir;
  ASSERT_TRUE(pnh.getParam("echo", topics) && pnh.getParam("listen", listen) &&
              pnh.getParam("tools_dir", tools_dir));
  const size_t with_message = topics.size();
  topics.insert(topics.end(), listen.begin(), listen.end());
  std::map<std::string, std::string> type_of;  // topic -> message type
  ros::master::V_TopicInfo infos;
  ros::master::getTopics(infos);
  for (const ros::master::TopicInfo& t : infos) type_of[t.name] = t.datatype;
  const auto package = [](const std::string& type) { return type.substr(0, type.find('/')); };
  std::set<std::string> echoed_packages;
  for (const std::string& t : topics) {
    EXPECT_TRUE(type_of.count(t)) << t << " (in the test's echo list) is not advertised";
    echoed_packages.insert(package(type_of[t]));
  }
  for (const auto& [topic, nodes] : SystemState(0)) {
    // rosout and the nodelet manager's bond are ROS's, not the graph's outputs
    if (topic == "/rosout" ||
        (topic.size() > 5 && topic.compare(topic.size() - 5, 5, "/bond") == 0) ||
        !AnyGraphNode(nodes))
      continue;
    EXPECT_TRUE(echoed_packages.count(package(type_of[topic])))
        << "the graph publishes " << topic << " [" << type_of[topic]
        << "], a message package no topic of the test's echo list has";
  }
  std::filesystem::create_directories(tools_dir);
  for (const std::string& t : topics) {
    Echo e{t, echoes.size() < with_message, -1,
           tools_dir + "/echo" + std::to_string(echoes.size()) + ".txt"};
    e.pid = StartEcho(t, e.output_file);
    ASSERT_GT(e.pid, 0) << "cannot start rostopic";
    echoes.push_back(e);
  }
}

// A `rostopic echo` node subscribes to `topic`.
bool EchoSubscribed(const std::string& topic) {
  const auto subs = SystemState(1);
  const auto it = subs.find(topic);
  if (it == subs.end()) return false;
  for (const std::string& n : it->second)
    if (n.rfind("/rostopic_", 0) == 0) return true;
  return false;
}

void CheckEchoes() {
  for (Echo& e : echoes) {
    int status = -1;
    bool ended = false, subscribed = false;
    if (e.message_expected)
      ended = WaitFor([&] { return waitpid(e.pid, &status, WNOHANG) == e.pid; }, 30.0);
    else
      subscribed = WaitFor([&] { return EchoSubscribed(e.topic); }, 30.0);
    if (!ended) {
      kill(e.pid, SIGKILL);
      waitpid(e.pid, &status, 0);
    }
    const std::string out = ReadText(e.output_file);
    const std::string what = "rostopic echo -n 1 " + e.topic + " printed:\n" + out;
    if (e.message_expected) {
      EXPECT_TRUE(ended && WIFEXITED(status) && WEXITSTATUS(status) == 0)
          << (ended ? "failed; " : "no message within 30 s; ") << what;
      EXPECT_NE(out.find("\n---"), std::string::npos) << what;
    } else {
      EXPECT_TRUE(subscribed) << "did not subscribe within 30 s; " << what;
      EXPECT_EQ(out.find("ERROR"), std::string::npos) << what;
    }
  }
}

// Runs last, after both epochs, while the graph is up: `rostopic echo -n 1` of
// an output topic of each message package prints it and ends with status 0;
// `rosservice call` of every service of the graph answers (issue 38).
TEST(SiteTfStatic, RosToolsEchoEveryOutputPackageAndCallEveryService) {
  ros::NodeHandle pnh("~");
  StartEchoes(pnh);  // they run while the services are called
  XmlRpc::XmlRpcValue calls;
  std::string report_dir;
  ASSERT_TRUE(pnh.getParam("services", calls) && pnh.getParam("report_dir", report_dir));
  std::set<std::string> listed;
  for (int i = 0; i < calls.size(); ++i) listed.insert(static_cast<std::string>(calls[i]["name"]));
  for (const auto& [service, nodes] : SystemState(2)) {
    const std::string leaf = service.substr(service.rfind('/') + 1);
    // roscpp's logger services and the nodelet manager's own are not the graph's interface
    if (!AnyGraphNode(nodes) || leaf == "get_loggers" || leaf == "set_logger_level" ||
        leaf == "load_nodelet" || leaf == "unload_nodelet" || leaf == "list")
      continue;
    EXPECT_TRUE(listed.count(service))
        << "the graph offers " << service << ", which the test's services list does not call";
  }
  for (int i = 0; i < calls.size(); ++i) {
    const std::string name = calls[i]["name"];
    const std::string args = calls[i]["args"];
    const run_command::CommandRun r =
        run_command::Run("rosservice call " + name + " '" + args + "'");
    EXPECT_EQ(r.status, 0) << "rosservice call " << name << " '" << args << "':\n" << r.output;
    // An entry without `success`: the answer depends on how far the replay
    // has come (the call itself, its types and a reply are what is checked).
    const std::string expected = !calls[i].hasMember("success")           ? "success: "
                                 : static_cast<bool>(calls[i]["success"]) ? "success: True"
                                                                          : "success: False";
    EXPECT_NE(r.output.find(expected), std::string::npos)
        << "rosservice call " << name << " '" << args << "':\n"
        << r.output;
  }
  // export_report wrote its CSV where it said
  EXPECT_TRUE(std::filesystem::exists(report_dir + "/ros_tools/deformation.csv"))
      << report_dir << "/ros_tools";
  CheckEchoes();
  rusage tools{};
  getrusage(RUSAGE_CHILDREN, &tools);
  std::cout << "ROS tools: " << echoes.size() << " rostopic echo, " << calls.size()
            << " rosservice call: " << tools.ru_utime.tv_sec + tools.ru_stime.tv_sec << " s CPU\n";
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  return slope_monitor::rostest_node::RunTests(argc, argv, "site_tf_static_test");
}
