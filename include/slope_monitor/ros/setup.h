// The parameter-failure rule of every nodelet's onInit (doc/style.md): the
// parameters are read and checked once, and the solver is built from them;
// a slope_monitor::Error there is the user's configuration (it names the key
// and the reason), so the nodelet logs it, does not advertise and stays
// loaded, never ROS_ASSERT or exit(). Anything else is a bug and propagates.
//
//   if (const auto error = ros_adapters::SetUpError([&] {
//         ReadParameters(pnh);
//         solver_ = std::make_unique<Solver>(options_);
//       })) {
//     NODELET_ERROR("my_node: %s; not advertising", error->c_str());
//     setup_failure_ = std::make_unique<SetUpFailureDiagnostics>(nh, pnh, "my_node", *error);
//     return;
//   }
//
// The nodelet logs itself: NODELET_ERROR names the nodelet's own logger.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

namespace slope_monitor {
namespace ros_adapters {

// Runs `set_up`; returns nothing when it succeeded, else the message of the
// slope_monitor::Error it threw.
std::optional<std::string> SetUpError(const std::function<void()>& set_up);

// A nodelet that cannot do its job says so until it is restarted with the
// cause fixed: ERROR "not running: <cause>" under `name` on /diagnostics
// every second (wall time, so also under a stopped sim clock). Held by the
// nodelet from its failed onInit:
//
//   setup_failure_ = std::make_unique<SetUpFailureDiagnostics>(nh, pnh, "my_node",
//                                                              "parameters rejected: " + *error);
//
// `values`: key-value pairs added to the status (e.g. the refused database).
class SetUpFailureDiagnostics {
 public:
  SetUpFailureDiagnostics(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
                          const std::string& name, const std::string& cause,
                          std::vector<std::pair<std::string, std::string>> values = {});

 private:
  std::string cause_;
  std::vector<std::pair<std::string, std::string>> values_;
  diagnostic_updater::Updater updater_;
  ros::WallTimer timer_;
};

// A one-shot node (camera_capture with a folder or video and `exit_at_end`:
// a recording script waits for it) that cannot do its job ends the process
// instead of staying up: EndProcess(1) records the status and requests the
// shutdown; the node shim (src/nodes/nodelet_node.cpp) returns
// ProcessExitStatus() from main, so roslaunch and the script see the failure.
// The highest status recorded wins; 0 until a failure is recorded.
void EndProcess(int status);
int ProcessExitStatus();

// The replay graph starts playing a bag only when every node of it is ready
// (replay_start): the launch sets `~graph_ready: false` for each node, and
// the nodelet's onInit holds a GraphReady whose destructor sets it true on
// every way out of onInit (set up, or refused with its error logged).
//
//   void onInit() override {
//     ros_adapters::GraphReady ready(getPrivateNodeHandle());
//     ...
//   }
class GraphReady {
 public:
  explicit GraphReady(const ros::NodeHandle& pnh) : pnh_(pnh) {}
  ~GraphReady();
  GraphReady(const GraphReady&) = delete;
  GraphReady& operator=(const GraphReady&) = delete;

 private:
  ros::NodeHandle pnh_;
};

// Time-outs (a silent camera, receiver or input no longer holds the others)
// are for live sensors. In a replay (/use_sim_time true) every input comes
// from the bag: completion is decided by the messages alone, as process_bag
// does, so the numbers do not depend on the CPU load or the replay rate (a
// wall-clock time-out would fire whenever an upstream node is slower than it
// under load). What is still held at the end of a replay is flushed by the
// nodelet's destructor where that can still reach its outputs (the
// deformation estimator) and is named in the log otherwise.
//
//   if (ros_adapters::LiveTimeouts()) Solve(collector_->Poll(Now()));
bool LiveTimeouts();

// The end of a replay, what the live time-outs were for: once the player has
// ended and the graph is idle, replay_end announces the end of the input on
// kEndOfInputTopic (std_msgs/UInt8, latched), one stage after another, each
// once the graph is idle again, so that what a stage flushes reaches the next
// (process_bag's Finish in the same order):
//   1 kEndOfMatching    the hex_matcher matches the photos still waiting
//   2 kEndOfAdjustment  the bundle adjuster solves the epoch still open (its
//                       log names what is missing); the radio solver releases
//                       the blocks held for a silent receiver
//   3 kEndOfFusion      the deformation estimator fuses what waits for a later
//                       stamp of another input
//   4 kEndOfSurfaces    the dense step measures the epochs it holds
// A node subscribes only in a replay (not LiveTimeouts()); `finish` runs once,
// on the node's callback queue, when its stage is announced.
inline constexpr const char* kEndOfInputTopic = "/replay/end_of_input";
enum EndOfInputStage { kEndOfMatching = 1, kEndOfAdjustment, kEndOfFusion, kEndOfSurfaces };
inline constexpr int kEndOfInputStages = kEndOfSurfaces;
// A null subscriber when live.
ros::Subscriber SubscribeEndOfInput(ros::NodeHandle& nh, EndOfInputStage stage,
                                    std::function<void()> finish);

}  // namespace ros_adapters
}  // namespace slope_monitor
