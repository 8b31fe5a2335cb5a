// replay_player: plays a bag into replay.launch's graph and loses nothing.
//
//   <node pkg="slope_monitor" type="replay_player" name="player"
//         args="--pause --rate 400 --delay 1 $(arg bag)"/>
//
// Why not `rosbag play`: it calls ros::shutdown() as soon as it has handed
// the bag's last message to its publishers, and the messages they have not
// written to their subscribers' sockets yet are dropped. With full-size
// photos that is most of a flight (measured: 8 photos of 36 MB at rate 400,
// 0 of 8 reached a plain subscriber; 1 of 8 at rate 40; 7 of 8 at rate 4).
// Its --keep-alive keeps the process but runs the bag clock on after the end
// of the bag and, in librosbag 1.15 (Debian 12), loops on a CPU (63-73 % of
// a core measured) until it is killed.
//
// replay_player publishes every message of the bag on its own topic, with the
// bag's type and latching, at `rate` times the bag's pace, and /clock
// (rosgraph_msgs/Clock, `clock_hz` per wall second, never past the next
// message not yet published). Its publishers keep every message until each
// subscriber has been sent it (queue without limit: nothing is dropped,
// whatever the message size and the rate). After the last message it
// publishes /clock at the bag's end time once and `~finished`
// (std_msgs/Bool true, latched), then sleeps (no clock, no CPU) until it is
// stopped: replay_end waits for `~finished` and for this process and the
// graph to be idle (what the publishers still send keeps it busy), and then
// ends the launch.
//
// Services: `~pause_playback` (std_srvs/SetBool, true = pause, false = play;
// success when the state changed), which replay_start calls.
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <rosgraph_msgs/Clock.h>
#include <std_msgs/Bool.h>
#include <std_srvs/SetBool.h>

namespace {

using Clock = std::chrono::steady_clock;

struct PlayerOptions {
  std::string bag;         // the bag file
  double rate = 1.0;       // [x bag pace] > 0
  double delay = 0.2;      // [s wall] after advertising, before the first message (>= 0)
  bool pause = false;      // start paused (resumed through ~pause_playback)
  double clock_hz = 100;   // [1/s wall] /clock while playing or paused (> 0)
  double status_hz = 1.0;  // [1/s wall] progress lines on stdout (> 0)
};

// The usage, after `why` (none for --help, which goes to stdout).
int Usage(const std::string& why, std::ostream& out = std::cerr) {
  const PlayerOptions d;
  if (!why.empty()) out << "replay_player: " << why << "\n";
  out << "usage: replay_player [--pause] [--rate R] [--delay S] [--clock-hz F] file.bag\n"
         "  --pause       start paused; ~pause_playback (std_srvs/SetBool, false) plays\n"
         "  --rate R      playback rate [x bag time] (default "
      << d.rate << ")\n"
      << "  --delay S     wall seconds between advertising and playing (default " << d.delay
      << ")\n"
      << "  --clock-hz F  /clock messages per wall second (default " << d.clock_hz << ")\n"
      << "Started by launch/replay.launch as node `player`. Publishes every message of the\n"
         "bag (nothing dropped whatever its size and the rate) and /clock; after the last\n"
         "message it publishes ~finished (std_msgs/Bool, latched) and sleeps until it is\n"
         "stopped (replay_end ends the launch once the graph has taken everything).\n"
         "Exit status 0 when stopped, 1 on a usage error or an unreadable bag.\n";
  return 1;
}

bool ParseNumber(const std::string& text, double* out) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0') return false;
  *out = v;
  return true;
}

// The bag clock: bag time runs at `rate` times the wall clock while playing
// and stands still while paused.
class BagClock {
 public:
  BagClock(ros::Time start, double rate, bool paused)
      : start_(start), rate_(rate), paused_(paused), resumed_(Clock::now()) {}

  // Pauses (true) or plays (false); false when it already was so.
  bool Set(bool pause) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (pause == paused_) return false;
    const Clock::time_point now = Clock::now();
    if (pause) played_ += now - resumed_;
    resumed_ = now;
    paused_ = pause;
    changed_.notify_all();
    return true;
  }

  bool Paused() {
    std::lock_guard<std::mutex> lock(mutex_);
    return paused_;
  }

  ros::Time Now() {
    std::lock_guard<std::mutex> lock(mutex_);
    return NowLocked(Clock::now());
  }

  // Sleeps until `until` (wall) or a pause change, whichever first.
  void SleepUntil(Clock::time_point until) {
    std::unique_lock<std::mutex> lock(mutex_);
    const bool was = paused_;
    changed_.wait_until(lock, until, [&] { return paused_ != was; });
  }

  // The wall time at which the bag clock reaches `t` if it keeps playing.
  Clock::time_point WallAt(const ros::Time& t) {
    std::lock_guard<std::mutex> lock(mutex_);
    const Clock::time_point now = Clock::now();
    const double ahead = (t - NowLocked(now)).toSec() / rate_;
    return now + std::chrono::duration_cast<Clock::duration>(
                     std::chrono::duration<double>(std::clamp(ahead, 0.0, 3600.0)));
  }

 private:
  ros::Time NowLocked(Clock::time_point now) const {
    const Clock::duration played = paused_ ? played_ : played_ + (now - resumed_);
    return start_ + ros::Duration(std::chrono::duration<double>(played).count() * rate_);
  }

  const ros::Time start_;
  const double rate_;
  std::mutex mutex_;
  std::condition_variable changed_;
  bool paused_;
  Clock::duration played_{0};  // wall time played before the last resume
  Clock::time_point resumed_;
};

}  // namespace

int main(int argc, char** argv) {
  // --help: the usage, before ros::init (no master contacted, nothing changed).
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "-h" || std::string(argv[i]) == "--help") {
      Usage("", std::cout);
      return 0;
    }
  ros::init(argc, argv, "player");
  // Line by line also into a file (roslaunch's log): the end of the bag is
  // seen when it happens, not when the process exits.
  std::setvbuf(stdout, nullptr, _IOLBF, 0);
  PlayerOptions o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--pause") {
      o.pause = true;
    } else if (a == "--rate" || a == "--delay" || a == "--clock-hz") {
      if (i + 1 >= argc) return Usage(a + " needs a value");
      double* v = a == "--rate" ? &o.rate : a == "--delay" ? &o.delay : &o.clock_hz;
      if (!ParseNumber(argv[++i], v)) return Usage(a + " value '" + argv[i] + "' is not a number");
    } else if (!a.empty() && a[0] == '-') {
      return Usage("unknown option '" + a + "'");
    } else if (o.bag.empty()) {
      o.bag = a;
    } else {
      return Usage("one bag only ('" + o.bag + "' and '" + a + "')");
    }
  }
  if (o.bag.empty()) return Usage("no bag file given");
  if (!(o.rate > 0.0) || !(o.delay >= 0.0) || !(o.clock_hz > 0.0))
    return Usage("--rate and --clock-hz must be > 0 and --delay >= 0");

  rosbag::Bag bag;
  try {
    bag.open(o.bag, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    std::cerr << "replay_player: " << o.bag << ": " << e.what() << "\n";
    return 1;
  }
  rosbag::View view(bag);
  ros::NodeHandle nh, pnh("~");
  // One publisher per topic, with the bag's type and latching; queue 0: no
  // limit, a publisher never drops a message a subscriber has not been sent.
  std::map<std::string, ros::Publisher> publishers;
  std::map<std::string, std::string> md5sums;
  for (const rosbag::ConnectionInfo* c : view.getConnections()) {
    const auto known = md5sums.find(c->topic);
    if (known != md5sums.end()) {
      if (known->second != c->md5sum) {
        std::cerr << "replay_player: " << o.bag << ": topic '" << c->topic
                  << "' holds two message types (" << c->datatype << " and another)\n";
        return 1;
      }
      continue;
    }
    ros::AdvertiseOptions a(c->topic, 0, c->md5sum, c->datatype, c->msg_def);
    const auto latching = c->header ? c->header->find("latching") : ros::M_string::const_iterator();
    a.latch = c->header && latching != c->header->end() && latching->second == "1";
    publishers[c->topic] = nh.advertise(a);
    md5sums[c->topic] = c->md5sum;
  }
  ros::Publisher clock_pub = nh.advertise<rosgraph_msgs::Clock>("/clock", 1);
  ros::Publisher finished_pub = pnh.advertise<std_msgs::Bool>("finished", 1, true);

  const ros::Time begin = view.size() > 0 ? view.getBeginTime() : ros::Time(0);
  const ros::Time end = view.size() > 0 ? view.getEndTime() : ros::Time(0);
  BagClock bag_clock(begin, o.rate, true);
  ros::ServiceServer pause_service =
      pnh.advertiseService<std_srvs::SetBool::Request, std_srvs::SetBool::Response>(
          "pause_playback", [&](std_srvs::SetBool::Request& req, std_srvs::SetBool::Response& res) {
            res.success = bag_clock.Set(req.data);
            res.message = std::string(res.success ? "playback is now " : "playback is already ") +
                          (req.data ? "paused" : "playing");
            ROS_INFO("replay_player: %s", res.message.c_str());
            return true;
          });
  ros::AsyncSpinner spinner(1);
  spinner.start();
  ROS_INFO("replay_player: %s: %u messages on %zu topics, %.1f s of bag time, rate %g%s",
           o.bag.c_str(), view.size(), publishers.size(), (end - begin).toSec(), o.rate,
           o.pause ? ", paused" : "");

  const auto wall_step =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.clock_hz));
  const auto status_step =
      std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.status_hz));
  std::this_thread::sleep_for(std::chrono::duration<double>(o.delay));
  // Paused from the start: a pause_playback call during the delay is kept.
  if (!o.pause) bag_clock.Set(false);
  const Clock::time_point started = Clock::now();
  Clock::time_point next_tick = started, next_status = started;
  rosgraph_msgs::Clock tick;
  const auto publish_clock = [&](const ros::Time& t) {
    tick.clock = t;
    clock_pub.publish(tick);
  };
  const auto status = [&](const ros::Time& t, bool paused) {
    std::printf("\r replay_player: bag time %.3f, %.1f of %.1f s played%s   ", t.toSec(),
                (t - begin).toSec(), (end - begin).toSec(), paused ? " (paused)" : "");
    std::fflush(stdout);
  };
  uint64_t published = 0;
  for (const rosbag::MessageInstance& m : view) {
    const ros::Time t = m.getTime();
    // Wait until the bag clock reaches the message; /clock meanwhile, never
    // past it (a node's clock is never ahead of a message still to come).
    while (ros::ok()) {
      const bool paused = bag_clock.Paused();
      const ros::Time now = std::min(bag_clock.Now(), t);
      const Clock::time_point wall = Clock::now();
      if (wall >= next_tick) {
        publish_clock(now);
        next_tick = wall + wall_step;
      }
      if (wall >= next_status) {
        status(now, paused);
        next_status = wall + status_step;
      }
      if (!paused && now >= t) break;
      bag_clock.SleepUntil(paused ? next_tick : std::min(next_tick, bag_clock.WallAt(t)));
    }
    if (!ros::ok()) break;
    publishers[m.getTopic()].publish(m);
    ++published;
  }
  if (ros::ok()) {
    publish_clock(end);
    status(end, false);
    std::printf("\n");
    std_msgs::Bool done;
    done.data = true;
    finished_pub.publish(done);
    ROS_INFO(
        "replay_player: published the %lu messages of %s in %.1f s; idle until the launch ends",
        static_cast<unsigned long>(published), o.bag.c_str(),
        std::chrono::duration<double>(Clock::now() - started).count());
    // One thread left, for the pause service (no effect any more) and the
    // subscribers' connections, until roslaunch stops the node.
    spinner.stop();
    ros::spin();
  }
  return 0;
}
