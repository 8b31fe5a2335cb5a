// process_bag: a recorded (or simulated) survey through the whole processing
// graph, offline, at CPU speed:
//
//   rosrun slope_monitor process_bag --bag FILE [--bag FILE2 ...] [--site-config FILE]
//       [--target-list FILE] [--radio-network FILE] [--adjuster-config FILE]
//       [--uav-tie-points] [--database FILE] [--report-dir DIR] [--output-bag FILE]
//       [--no-dense] [--verbose]
//
// The bags are read with rosbag::View in bag-time order (several bags, e.g.
// the split files of one recording, merged by time) and every message goes,
// in that order, to the same core components and ROS adapters the nodelets of
// launch/replay.launch use: a target centroider per camera, the bundle
// adjuster's EpochCollector and epoch solver, the radio phase solver with its
// epoch assembler, the deformation estimator with its SQLite history and
// reports. One process, no ROS master, no sleeps; completion of an epoch is
// decided by the messages only, so the result does not depend on the CPU load.
// Parameters: config/defaults/<node>.yaml, then config/process_bag/<node>.yaml
// (what the launch files add), then the command line and overlays, as
// replay.launch loads them. Defaults of the options: those of replay.launch
// (target list and truth beside the bag, reports under ~/.ros/slope_monitor,
// the history ~/.ros/slope_monitor/<first bag's name>.db: one per bag,
// ros/replay_defaults.h). See doc/process_bag.md.
//
// One writer per history: while another process_bag (or an estimator node)
// writes the --database, this run ends at once, before processing anything,
// with exit status 1 and the one line
//   process_bag: history database '<file>' is in use by process <pid> (<name>), which holds its
//   writer lock '<file>.lock'; one writer per history: wait for it to end or use another database
// (deformation/history.h).
//
// Exit status (the tools' convention, doc/security.md): 0 every bag read to
// its end and something solved; 2 input ended early (a cut bag, processed up
// to its break, the break named at the end with the epochs then accepted
// incomplete) or messages skipped (an image message above --max-megapixels,
// default 100, or whose header does not describe its data: named with its
// topic, bag time and size when met and again at the end; the rest
// processed); 1 nothing solved (said why in one line), a usage error, an
// unreadable input or another writer on the history.
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <ros/package.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/input_order.h"
#include "slope_monitor/core/common/progress_line.h"
#include "slope_monitor/core/deformation/alert_hook.h"
#include "slope_monitor/core/deformation/alert_log.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/deformation/plot_report.h"
#include "slope_monitor/core/deformation/report.h"
#include "slope_monitor/core/evaluation/deformation_truth.h"
#include "slope_monitor/core/io/safe_file.h"
#include "slope_monitor/core/io/target_file.h"
#include "slope_monitor/ros/adjuster_step.h"
#include "slope_monitor/ros/adjustment_conversions.h"
#include "slope_monitor/ros/change_area_conversions.h"
#include "slope_monitor/ros/conversions.h"
#include "slope_monitor/ros/deformation_conversions.h"
#include "slope_monitor/ros/epoch_solver.h"
#include "slope_monitor/ros/estimator_step.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"
#include "slope_monitor/ros/image_limits.h"
#include "slope_monitor/ros/node_parameters.h"
#include "slope_monitor/ros/offline_dense.h"
#include "slope_monitor/ros/param_files.h"
#include "slope_monitor/ros/radio_step.h"
#include "slope_monitor/ros/replay_defaults.h"
#include "slope_monitor/ros/sequence_conversions.h"
#include "slope_monitor/ros/sequence_step.h"
#include "slope_monitor/ros/target_centroider_step.h"
#include "slope_monitor/ros/targetless_camera.h"
#include "slope_monitor/ros/uav_topics.h"
#include "slope_monitor/ros/validation.h"
#include "slope_monitor/ros/view_markers.h"

namespace fs = std::filesystem;

namespace slope_monitor {
namespace {

constexpr char kUsage[] =
    "usage: process_bag --bag FILE [--bag FILE2 ...] [--site FILE] [--site-config FILE] "
    "[--target-list FILE]\n"
    "                   [--radio-network FILE] [--adjuster-config FILE] [--uav-tie-points]\n"
    "                   [--database FILE] [--report-dir DIR] [--output-bag FILE] [--no-dense] "
    "[--verbose]\n"
    "                   [--max-megapixels MP]\n";

// Topics of the replay graph (launch/include/processing_graph.xml).
constexpr char kAdjusterDisplacements[] = "/bundle_adjuster/displacements";
constexpr char kRadioDisplacements[] = "/radio/radio_displacements";
constexpr char kTargetlessDisplacements[] = "/targetless_camera/displacements";

struct Args {
  std::vector<std::string> bags;
  std::string site, site_config, target_list, radio_network, adjuster_config;
  bool uav_tie_points = false;
  // No target list (a --site without targets and no <bag>.targets.yaml): no
  // target stage; set by ResolveTargets.
  bool no_targets = false;
  bool dense = true;     // the dense epoch step (replay.launch dense:=true)
  bool verbose = false;  // the bundle adjuster's INFO lines too
  std::string database, report_dir, output_bag;
  bool default_database = false;  // --database not given: the bag's own history
  // Image messages above this many pixels, or whose header does not describe
  // their data, are skipped before conversion, named (ros/image_limits.h).
  ros_adapters::ImageMessageLimits image_limits;
};

// Throws InvalidArgument naming the flag.
Args ParseArgs(int argc, char** argv) {
  Args a;
  const std::map<std::string, std::string*> with_value = {{"--site", &a.site},
                                                          {"--site-config", &a.site_config},
                                                          {"--target-list", &a.target_list},
                                                          {"--radio-network", &a.radio_network},
                                                          {"--adjuster-config", &a.adjuster_config},
                                                          {"--database", &a.database},
                                                          {"--report-dir", &a.report_dir},
                                                          {"--output-bag", &a.output_bag}};
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "-h" || flag == "--help") {
      std::cout << kUsage;
      std::exit(0);
    }
    if (flag == "--uav-tie-points") {
      a.uav_tie_points = true;
      continue;
    }
    if (flag == "--no-dense") {
      a.dense = false;
      continue;
    }
    if (flag == "--verbose") {
      a.verbose = true;
      continue;
    }
    if (flag == "--max-megapixels") {
      const std::string v = i + 1 < argc ? argv[++i] : "";
      char* end = nullptr;
      a.image_limits.max_megapixels = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !(a.image_limits.max_megapixels > 0))
        throw InvalidArgument("--max-megapixels '" + v + "' is not a number > 0");
      continue;
    }
    const bool is_bag = flag == "--bag";
    const auto it = with_value.find(flag);
    if (!is_bag && it == with_value.end()) throw InvalidArgument("unknown argument '" + flag + "'");
    if (i + 1 >= argc || std::string(argv[i + 1]).rfind("--", 0) == 0)
      throw InvalidArgument(flag + " needs a value");
    if (is_bag)
      a.bags.push_back(argv[++i]);
    else
      *it->second = argv[++i];
  }
  if (a.bags.empty()) throw InvalidArgument("--bag FILE is required");
  for (const std::string& bag : a.bags)
    if (!fs::is_regular_file(bag)) throw InvalidArgument("bag '" + bag + "' not found");
  // The defaults of replay.launch: a history per bag (ros/replay_defaults.h).
  const char* home = std::getenv("HOME");
  const std::string ros_dir = std::string(home ? home : ".") + "/.ros/slope_monitor";
  a.default_database = a.database.empty();
  if (a.default_database)
    a.database = ros_adapters::DefaultHistoryOfBag(a.bags.front(), home ? home : ".");
  if (a.report_dir.empty()) a.report_dir = ros_dir + "/reports";
  return a;
}

// The other input files (after the bags: a bag that is not one is named first).
void CheckInputFiles(const Args& a) {
  for (const std::string* f :
       {&a.site, &a.site_config, &a.target_list, &a.radio_network, &a.adjuster_config})
    if (!f->empty() && !fs::is_regular_file(*f))
      throw InvalidArgument("file '" + *f + "' not found");
  // Fail early (issue 38): the outputs' folders are written before a message is processed.
  io::CheckFolderWritable(a.report_dir, "--report-dir");
  const fs::path database_folder = fs::path(a.database).parent_path();
  io::CheckFolderWritable(database_folder.empty() ? "." : database_folder.string(),
                          "folder of --database");
}

// The targets, as replay.launch finds them: the site file's when it lists
// them, else --target-list, else <first bag>.targets.yaml (the simulator's).
// A --site without targets and no such file: a site without targets (a UAV
// flight oriented by its tie points), no target stage; its UAV cameras are
// tied by the sequence matcher without --uav-tie-points. Without --site a
// target list is required (InvalidArgument naming the file looked for).
void ResolveTargets(Args* a, const std::function<void(const std::string&)>& log) {
  const std::optional<io::SiteFile> site =
      a->site.empty() ? std::nullopt : std::optional<io::SiteFile>(io::LoadSiteFile(a->site));
  if (site && site->targets) return;
  if (!a->target_list.empty()) return;
  const std::string beside =
      a->bags.front().substr(0, a->bags.front().size() - 4) + ".targets.yaml";
  if (fs::is_regular_file(beside)) {
    a->target_list = beside;
    return;
  }
  if (!site)
    throw InvalidArgument(
        "no target list: file '" + beside +
        "' not found (give --target-list FILE, or --site FILE naming the targets)");
  a->no_targets = true;
  std::string uav;
  for (const io::SiteCamera& c : site->cameras)
    if (c.kind == io::CameraKind::kUav) uav += (uav.empty() ? "" : ", ") + c.name;
  if (!uav.empty() && !a->uav_tie_points) {
    a->uav_tie_points = true;
    log("site '" + site->name + "' lists no targets: no target stage; UAV camera(s) " + uav +
        " tied by their tie points (as --uav-tie-points)");
  } else {
    log("site '" + site->name + "' lists no targets: no target stage");
  }
}

// ------------------------------------------------------------------ bags

// A bag read only up to its break (cut while recording or copying): named at
// the end of the run, which then exits 2 (issue 38).
struct BagBreak {
  std::string path;
  uintmax_t bytes = 0;                    // size of the cut file
  const rosbag::Bag* readable = nullptr;  // its reindexed copy
};

// Opens `path`; an unindexed or truncated bag is reindexed in a temporary
// copy (rosbag reindex), said on stderr, read up to its break and added to
// `breaks`.
std::unique_ptr<rosbag::Bag> OpenBag(const std::string& path, std::vector<fs::path>* temporaries,
                                     std::vector<BagBreak>* breaks) {
  if (!fs::is_regular_file(path)) throw InvalidArgument("bag '" + path + "' not found");
  auto bag = std::make_unique<rosbag::Bag>();
  try {
    bag->open(path, rosbag::bagmode::Read);
    return bag;
  } catch (const rosbag::BagException& e) {
    // A bag 2.0 header but no usable index (cut while recording or copying):
    // reindex. Anything else is not a bag.
    char magic[13] = {};
    std::ifstream(path, std::ios::binary).read(magic, sizeof(magic));
    if (std::string(magic, sizeof(magic)) != "#ROSBAG V2.0\n")
      throw InvalidArgument("'" + path + "' is not a bag (" + e.what() + ")");
  }
  char pattern[] = "/tmp/process_bag_XXXXXX";
  if (!mkdtemp(pattern))
    throw IoError("cannot make a temporary directory for reindexing '" + path + "'");
  const fs::path dir = pattern;
  temporaries->push_back(dir);
  const fs::path copy = dir / fs::path(path).filename();
  fs::copy_file(path, copy);
  std::cerr << "process_bag: bag '" << path << "' is not indexed (truncated or not closed): "
            << "reindexing a temporary copy " << copy.string() << "; it is read up to its break\n";
  const std::string command = "rosbag reindex --quiet --output-dir '" + dir.string() + "/out' '" +
                              copy.string() + "' > '" + dir.string() + "/reindex.log' 2>&1";
  fs::create_directories(dir / "out");
  if (std::system(command.c_str()) != 0 || !fs::exists(dir / "out" / copy.filename()))
    throw IoError("cannot reindex bag '" + path + "' (see " + (dir / "reindex.log").string() + ")");
  bag = std::make_unique<rosbag::Bag>();  // the failed one stays "open"
  try {
    bag->open((dir / "out" / copy.filename()).string(), rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw IoError("bag '" + path + "' reindexed but still unreadable: " + e.what());
  }
  breaks->push_back({path, fs::file_size(path), bag.get()});
  return bag;
}

// What a run whose input ended early says at its end: each break, and the
// epochs accepted at the end of input without all their inputs.
void SayBreaks(const std::vector<BagBreak>& breaks, const std::vector<std::string>& incomplete) {
  for (const BagBreak& b : breaks) {
    rosbag::View part(*b.readable);
    char when[160] = "no message before it";
    if (part.size() > 0)
      std::snprintf(when, sizeof(when),
                    "its last readable message at bag time %.3f s (%.1f s after its start)",
                    part.getEndTime().toSec(), (part.getEndTime() - part.getBeginTime()).toSec());
    std::cerr << "process_bag: input ended early: bag '" << b.path << "' breaks off at byte "
              << b.bytes << " (cut while recording or copying): " << part.size()
              << " messages read up to the break, " << when
              << "; what was recorded after it is not in the file\n";
  }
  for (const std::string& line : incomplete)
    std::cerr << "process_bag: accepted at the end of input without all its inputs: " << line
              << "\n";
}

// Cameras of the survey: every /<name>/camera/image_raw topic of the bags.
std::vector<std::string> CamerasOf(rosbag::View& view) {
  std::set<std::string> names;
  for (const rosbag::ConnectionInfo* c : view.getConnections()) {
    const std::string& t = c->topic;
    const std::string suffix = "/camera/image_raw";
    if (t.size() > suffix.size() + 1 && t[0] == '/' &&
        t.compare(t.size() - suffix.size(), suffix.size(), suffix) == 0)
      names.insert(t.substr(1, t.size() - suffix.size() - 1));
  }
  return {names.begin(), names.end()};
}

bool HasTopic(rosbag::View& view, const std::string& topic) {
  for (const rosbag::ConnectionInfo* c : view.getConnections())
    if (c->topic == topic) return true;
  return false;
}

// ------------------------------------------------------------ parameters

std::string ConfigDir() {
  const std::string pkg = ros::package::getPath("slope_monitor");
  if (pkg.empty())
    throw ConfigError("package 'slope_monitor' not found (source the workspace's setup.bash)");
  return pkg + "/config";
}

// config/defaults/<node>.yaml, then config/process_bag/<node>.yaml if any.
XmlRpc::XmlRpcValue NodeParams(const std::string& node) {
  const std::string config = ConfigDir();
  XmlRpc::XmlRpcValue p = ros_adapters::LoadParamFile(config + "/defaults/" + node + ".yaml");
  const std::string extra = config + "/process_bag/" + node + ".yaml";
  if (fs::exists(extra)) ros_adapters::MergeParams(&p, ros_adapters::LoadParamFile(extra));
  return p;
}

XmlRpc::XmlRpcValue StringList(const std::vector<std::string>& v) {
  XmlRpc::XmlRpcValue list;
  list.setSize(static_cast<int>(v.size()));
  for (size_t i = 0; i < v.size(); ++i) list[static_cast<int>(i)] = v[i];
  return list;
}

// ------------------------------------------------------------------ graph

// f() with its wall time added to *seconds; returns what f returns.
template <typename F>
auto Timed(double* seconds, F&& f) {
  struct Add {
    double* seconds;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    ~Add() {
      *seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
  } add{seconds};
  return f();
}

// The process's peak resident memory so far (VmHWM) [MB]; 0 where /proc has none.
double PeakMemoryMb() {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;  // kB
  return 0.0;
}

struct Centroider {
  std::unique_ptr<ros_adapters::TargetCentroiderStep> step;      // the node's, shared
  std::map<ros::Time, sensor_msgs::Image::ConstPtr> images;      // waiting for their camera_info
  std::map<ros::Time, sensor_msgs::CameraInfo::ConstPtr> infos;  // waiting for their image
  // The latest centroided photo (its image kept: `mono` may share its pixels),
  // written as /<camera>/debug_image at the end of the input.
  sensor_msgs::Image::ConstPtr last_image;
  std::optional<ros_adapters::CentroidedImage> last;
};

class OfflineGraph {
 public:
  // `log`: a line for the user (stderr, with the progress line redrawn).
  OfflineGraph(const Args& args, const std::vector<std::string>& cameras, rosbag::Bag* output,
               std::function<void(const std::string&)> log)
      : log_(std::move(log)), args_(args), output_(output) {
    SetUpTargetless();
    std::vector<std::string> with_targets;
    for (const std::string& cam : cameras)
      if (!targetless_ || !targetless_->Handles(cam)) with_targets.push_back(cam);
    if (!args.site.empty()) site_ = io::LoadSiteFile(args.site);
    for (const std::string& cam : with_targets) SetUpCentroider(cam);
    SetUpAdjuster(with_targets);
    SetUpRadio();
    SetUpEstimator();
    if (args.dense) SetUpDense();
  }

  void OnMessage(const rosbag::MessageInstance& m) {
    const std::string& topic = m.getTopic();
    if (UavMatcher* uav = UavMatcherOf(topic, &ros_adapters::UavTopics::prior)) {
      // The sequence matcher's work for this prior (features and pairs of
      // the photo that waited for it) runs while the photo's targets are
      // still being centroided (Pair); both are taken in bag order after.
      if (const auto prior = m.instantiate<geometry_msgs::PoseWithCovarianceStamped>()) {
        const std::optional<ros_adapters::SequenceOutput> step = MatchUavPrior(uav, *prior);
        TakeCentroided();
        now_ = m.getTime();
        adjuster_->AddPrior(*prior);
        if (step) OnSequenceStep(*uav, *step);
        return;
      }
    }
    // A message the graph takes no input from (e.g. /uav/gnss/fix) leaves a
    // photo being centroided running.
    if (!Handled(m.getDataType())) return;
    // An image is read once, and only when its record and its header are
    // within the pixel budget (issue 38); else it is skipped, named.
    sensor_msgs::Image::ConstPtr image;
    if (m.getDataType() == ros::message_traits::datatype<sensor_msgs::Image>()) {
      image = CheckedImage(m);
      if (!image) return;
    }
    TakeCentroided();
    now_ = m.getTime();
    if (topic == "/tf" || topic == "/tf_static") {
      if (const auto tf = m.instantiate<tf2_msgs::TFMessage>()) OnTf(*tf, topic == "/tf_static");
    } else if (OnTargetlessMessage(m, image)) {
    } else if (image) {
      if (UavMatcher* uav = UavMatcherOf(topic, &ros_adapters::UavTopics::image))
        OnUavImage(uav, image);
      if (Centroider* c = CameraOf(topic, "/camera/image_raw")) {
        c->images[image->header.stamp] = image;
        if (dense_)
          Timed(&stages_.dense, [&] { dense_->OnImage(c->step->camera(), *image, now_.toSec()); });
        Pair(c, image->header.stamp);
      }
    } else if (const auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
      if (Centroider* c = CameraOf(topic, "/camera/camera_info")) {
        OnCameraInfo(c->step->camera(), *info);
        if (dense_) dense_->OnCameraInfo(c->step->camera(), *info);
        c->infos[info->header.stamp] = info;
        Pair(c, info->header.stamp);
      }
    } else if (const auto marker = m.instantiate<slope_monitor::EpochMarker>()) {
      if (marker->end) OnEpochEnd(*marker);
    } else if (const auto prior = m.instantiate<geometry_msgs::PoseWithCovarianceStamped>()) {
      if (IsPriorTopic(topic)) adjuster_->AddPrior(*prior);
    } else if (const auto block = m.instantiate<slope_monitor::RadioSampleBlock>()) {
      OnRadioBlock(*block, topic);
    }
  }

  // End of the bags: an epoch still open is solved with what it has (the
  // live graph's time-out), then the reports are written.
  void Finish() {
    TakeCentroided();
    // The centroider's debug_image of each camera's latest photo (rviz's
    // photo panel), once: every photo would multiply the output bag's size.
    for (auto& [camera, c] : centroiders_)
      if (c.last)
        Write("/" + camera + "/debug_image",
              ros_adapters::ToDebugImage(*c.last, c.last_image->header));
    for (UavMatcher& uav : uav_matchers_)
      OnSequenceStep(uav, Timed(&stages_.matching, [&] { return uav.step->Finish(); }));
    if (const std::optional<ros_adapters::SolvedEpoch> e = adjuster_->Finish()) Solve(*e);
    // The inputs have ended: what waits for a later stamp of another input is fused.
    Publish(Timed(&stages_.estimator, [&] { return estimator_->Flush(); }));
    if (dense_) {
      dense_->Finish();
      char line[120];
      std::snprintf(line, sizeof line, "dense step: %d surface(s) in %.1f s (%.1f s CPU)",
                    dense_->epochs_measured(), dense_->seconds(), dense_->cpu_seconds());
      Log(line);
    }
    Log("end of input: " + std::to_string(adjuster_->accepted()) +
        " adjustment epoch(s) accepted, " + std::to_string(radio_epochs()) +
        " radio epoch(s) solved");
    if (estimator_->GetSnapshot().points.empty()) {
      Log("no point was ever measured: no reports written to " +
          estimator_->parameters().report_dir);
      return;
    }
    WriteReportFiles();
  }

  // --uav-tie-points: the graph's hex matcher (mode sequence) for every
  // camera of kind uav (the site file's, else io::DefaultCameras()'s `uav`)
  // on /<camera>/camera/image_raw and position_prior; its tie points go to
  // the collector as /<camera>/tie_points. has_topic: whether the bag has a
  // topic; with priors in the bag an image waits for its own, else every
  // image is matched when it comes.
  void SetUpUavTiePoints(const std::function<bool(const std::string&)>& has_topic) {
    for (const std::string& camera : adjuster_->parameters().collector.uav_cameras) {
      XmlRpc::XmlRpcValue p = NodeParams("hex_matcher");
      ros_adapters::SetParam(&p, "mode", std::string("sequence"));
      ros_adapters::SetParam(&p, "camera", camera);
      ros_adapters::ParamReader r(p, "/" + camera + "/hex_matcher");
      UavMatcher uav;
      uav.step = std::make_unique<ros_adapters::SequenceMatcherStep>(
          ros_adapters::ReadHexMatcherParameters(r));
      uav.topics = ros_adapters::UavCameraTopics(camera);
      uav.step->matcher().SetPriorsExpected(has_topic(uav.topics.prior));
      uav_matchers_.push_back(std::move(uav));
    }
  }

  int epochs_solved() const { return adjuster_->accepted() + static_cast<int>(radio_epochs()); }
  unsigned int radio_epochs() const { return radio_ ? radio_->epochs() : 0; }
  // Why no epoch was solved, in one line (epochs_solved() == 0).
  std::string WhyNothingSolved() const {
    if (!last_failure_.empty()) return last_failure_;
    if (centroiders_.empty() && !radio_)
      return "the bags hold no camera images (/<camera>/camera/image_raw) and no radio network "
             "runs";
    return "no adjustment epoch was completed (no epoch end marker of the cameras; see the "
           "warnings above)";
  }
  bool has_points() const { return !estimator_->GetSnapshot().points.empty(); }
  // The messages skipped (CheckedImage), one line each.
  const std::vector<std::string>& skipped() const { return skipped_; }

 private:
  void Log(const std::string& line) const { log_(line); }

  // ---- set-up: the parameters replay.launch gives every node.
  void SetUpCentroider(const std::string& cam) {
    XmlRpc::XmlRpcValue p = NodeParams("target_centroider");
    ros_adapters::SetParam(&p, "target_list", args_.target_list);
    ros_adapters::SetParam(&p, "camera_name", cam);
    ros_adapters::ParamReader r(p, "/" + cam + "/target_centroider");
    const ros_adapters::TargetCentroiderParameters params =
        ros_adapters::ReadTargetCentroiderParameters(r);
    const io::SiteFile* site = site_ ? &*site_ : nullptr;
    // A site without targets: nothing to look for (each photo gets an empty
    // target list, what a centroider would find).
    std::optional<io::TargetList> targets;
    if (!args_.no_targets) targets = ros_adapters::CentroiderTargets(params.node, site);
    centroiders_[cam].step = std::make_unique<ros_adapters::TargetCentroiderStep>(
        cam, ros_adapters::CameraPixelSize(params.node, site ? site->FindCamera(cam) : nullptr),
        params, targets, "/" + cam + "/camera/image_raw");
  }

  void SetUpAdjuster(const std::vector<std::string>& cameras) {
    XmlRpc::XmlRpcValue p = NodeParams("bundle_adjuster");
    if (!args_.target_list.empty()) ros_adapters::SetParam(&p, "target_list", args_.target_list);
    ros_adapters::SetParam(&p, "cameras", StringList(cameras));
    if (!args_.site.empty()) ros_adapters::SetParam(&p, "site_file", args_.site);
    if (!args_.adjuster_config.empty())
      ros_adapters::MergeParams(&p, ros_adapters::LoadParamFile(args_.adjuster_config));
    if (args_.uav_tie_points) ros_adapters::SetParam(&p, "uav_tie_points", true);
    ros_adapters::ParamReader r(p, "/bundle_adjuster");
    adjuster_ = std::make_unique<ros_adapters::AdjusterStep>(
        ros_adapters::ReadAdjusterParameters(r), "/bundle_adjuster");
    // The site's cameras that this bag has (a UAV that did not fly is not
    // waited for), as the replay graph decides it.
    std::vector<ros_adapters::LogLine> log;
    adjuster_->KeepCameras(ros_adapters::ReplayCameras(
        adjuster_->parameters(),
        [&](const std::string& c) {
          return std::find(cameras.begin(), cameras.end(), c) != cameras.end();
        },
        &log));
    for (const ros_adapters::LogLine& line : log) Log("bundle_adjuster: " + line.text);
    adjuster_->SetTiePointsExpected(args_.uav_tie_points);
  }

  void SetUpRadio() {
    XmlRpc::XmlRpcValue p = NodeParams("radio_phase_solver");
    const std::string stem = args_.bags.front().substr(0, args_.bags.front().size() - 4);
    // The simulator's truth beside the bag when there is one (replay.launch's
    // truth_file); a recorded bag has none, and a site without radio_network
    // has no radio: the solver does not run.
    if (args_.radio_network.empty()) {
      if (fs::is_regular_file(stem + ".truth.yaml"))
        ros_adapters::SetParam(&p, "truth_file", stem + ".truth.yaml");
    } else
      ros_adapters::SetParam(&p, "network_file", args_.radio_network);
    if (!args_.site.empty()) ros_adapters::SetParam(&p, "site_file", args_.site);
    ros_adapters::ParamReader r(p, "/radio/radio_phase_solver");
    ros_adapters::RadioParameters params;
    try {
      params = ros_adapters::ReadRadioParameters(r);
    } catch (const Error& e) {
      // As the graph: without a radio network the radio solver does not run.
      Log(std::string("radio_phase_solver not running: ") + e.what());
      return;
    }
    if (!params.has_network) {
      Log("radio_phase_solver not running: no radio network");
      return;
    }
    radio_ = std::make_unique<ros_adapters::RadioStep>(params);
  }

  void SetUpEstimator() {
    XmlRpc::XmlRpcValue p = NodeParams("deformation_estimator");
    if (!args_.site_config.empty())
      ros_adapters::MergeParams(&p, ros_adapters::LoadParamFile(args_.site_config));
    if (!args_.site.empty()) ros_adapters::SetParam(&p, "site_file", args_.site);
    ros_adapters::SetParam(&p, "database", args_.database);
    ros_adapters::SetParam(&p, "report_dir", args_.report_dir);
    std::vector<std::string> inputs = {kAdjusterDisplacements, kRadioDisplacements};
    if (targetless_) inputs.push_back(kTargetlessDisplacements);
    ros_adapters::SetParam(&p, "input_topics", StringList(inputs));
    // As deformation_estimator.launch: the pictures by scripts/plot_report.
    ros_adapters::SetParam(&p, "plot_script",
                           fs::path(ConfigDir()).parent_path().string() + "/scripts/plot_report");
    ros_adapters::ParamReader r(p, "/deformation_estimator");
    // Fused in stamp order over the inputs that run (without a radio network
    // the radio solver does not: nothing to wait for).
    std::vector<std::string> ordered = {kAdjusterDisplacements};
    if (radio_) ordered.push_back(kRadioDisplacements);
    if (targetless_) ordered.push_back(kTargetlessDisplacements);
    estimator_ = std::make_unique<ros_adapters::EstimatorStep>(
        ros_adapters::ReadEstimatorParameters(r), ordered,
        // The site's notification hook, from its worker thread: straight to
        // stderr, not through the progress line.
        [](bool, const std::string& m) {
          std::cerr << "deformation_estimator: " << m << std::endl;
        });
  }

  // The fixed_targetless cameras of --site (launch/include/processing_graph.xml
  // runs the targetless_camera nodelet for them): config/defaults/targetless_camera.yaml.
  void SetUpTargetless() {
    if (args_.site.empty()) return;
    XmlRpc::XmlRpcValue p = NodeParams("targetless_camera");
    ros_adapters::SetParam(&p, "site_file", args_.site);
    ros_adapters::SetParam(&p, "report_dir", args_.report_dir);
    ros_adapters::ParamReader r(p, "/targetless_camera");
    const ros_adapters::TargetlessParameters params = ros_adapters::ReadTargetlessParameters(r);
    r.CheckNoUnknownKeys();
    targetless_ = std::make_unique<ros_adapters::TargetlessCameras>(params);
    if (targetless_->cameras().empty()) targetless_.reset();
  }

  // A photo or camera_info of a fixed_targetless camera: re-orientation,
  // field, fused. False for any other message.
  bool OnTargetlessMessage(const rosbag::MessageInstance& m,
                           const sensor_msgs::Image::ConstPtr& image) {
    if (!targetless_) return false;
    const std::string& topic = m.getTopic();
    for (const std::string& cam : targetless_->cameras()) {
      std::optional<ros_adapters::TargetlessOutputs> out;
      try {
        if (topic == "/" + cam + "/camera/image_raw") {
          if (image) out = targetless_->AddImage(cam, image);
        } else if (topic == "/" + cam + "/camera/camera_info") {
          if (const auto info = m.instantiate<sensor_msgs::CameraInfo>())
            out = targetless_->AddCameraInfo(cam, info);
        } else {
          continue;
        }
      } catch (const std::exception& e) {
        Log("targetless_camera: dropped photo of '" + cam + "' (topic " + topic + "): " + e.what());
        return true;
      }
      if (out) PublishTargetless(*out);
      return true;
    }
    return false;
  }

  void PublishTargetless(const ros_adapters::TargetlessOutputs& out) {
    Log("targetless_camera: " + out.info);
    for (const std::string& w : out.warnings) Log("targetless_camera: WARN " + w);
    diagnostic_msgs::DiagnosticArray d;
    d.header.stamp = now_;
    d.status.push_back(out.status);
    Write("/diagnostics", d);
    if (out.site_from_optical) {
      tf2_msgs::TFMessage tf;
      tf.transforms.push_back(*out.site_from_optical);
      Write("/tf", tf);
    }
    if (out.displacements) {
      Write(kTargetlessDisplacements, *out.displacements);
      Fuse(*out.displacements, kTargetlessDisplacements);
    }
  }

  // The dense_epoch node's parameters as processing_graph.xml sets them.
  void SetUpDense() {
    XmlRpc::XmlRpcValue p = NodeParams("dense_epoch");
    ros_adapters::SetParam(&p, "report_dir", args_.report_dir);
    // The site's CRS (site file, else the overlay's geodetic_origin) is the
    // GeoTIFFs' map CRS, as in processing_graph.xml.
    if (!args_.site.empty()) ros_adapters::SetParam(&p, "site_file", args_.site);
    if (!args_.site_config.empty()) ros_adapters::SetParam(&p, "site_config", args_.site_config);
    dense_ = std::make_unique<ros_adapters::OfflineDense>(
        p,
        [this](const ros_adapters::DenseEpochOutput& out) {
          if (out.cloud) Write(ros_adapters::OfflineDense::kCloudTopic, *out.cloud);
          if (out.legend) Write(ros_adapters::OfflineDense::kLegendTopic, *out.legend);
          if (out.areas) OnAreas(*out.areas);
        },
        log_);
  }

  // The reports at the end of the input, written as the estimator nodelet
  // writes them (deformation::WriteAllReports); the hook's queue is drained first.
  void WriteReportFiles() {
    estimator_->FlushHook();
    const ros_adapters::EstimatorParameters& p = estimator_->parameters();
    const auto files = estimator_->WriteReports("", p.report_formats);
    Log("wrote " + std::to_string(files.size()) + " report file(s) to " + p.report_dir);
  }

  // ---- inputs.
  Centroider* CameraOf(const std::string& topic, const std::string& suffix) {
    if (topic.size() <= suffix.size() + 1) return nullptr;
    const std::string cam = topic.substr(1, topic.size() - suffix.size() - 1);
    const auto it = centroiders_.find(cam);
    return it != centroiders_.end() && "/" + cam + suffix == topic ? &it->second : nullptr;
  }

  void OnTf(const tf2_msgs::TFMessage& tf, bool is_static) {
    std::vector<std::string> problems;
    poses_.Add(tf, is_static, &problems);
    for (const std::string& line : problems) Log("target_centroider: " + line);
    Write(is_static ? "/tf_static" : "/tf", tf);
  }

  void OnCameraInfo(const std::string& cam, const sensor_msgs::CameraInfo& info) {
    if (const auto error = adjuster_->OnCameraInfo(cam, info))
      Log("bundle_adjuster: camera_info of '" + cam + "': " + *error);
  }

  // An image and its camera_info (same stamp, in either order) are both in:
  // its targets are centroided on another thread (the photo and its pose are
  // the task's own) and taken (written, given to the collector) by
  // TakeCentroided before the next message's effects, i.e. in bag order.
  void Pair(Centroider* c, const ros::Time& stamp) {
    TakeCentroided();
    const auto image = c->images.find(stamp);
    const auto info = c->infos.find(stamp);
    if (image == c->images.end() || info == c->infos.end()) return;
    Centroiding task;
    task.c = c;
    task.bag_time = now_;
    task.image = image->second;
    const ros_adapters::TargetCentroiderStep* step = c->step.get();
    const auto pose = step->Pose(poses_.buffer(), *image->second, *info->second);
    if (!step->has_targets()) {
      // No targets to look for: the photo's empty target list at once.
      std::promise<ros_adapters::CentroidedImage> ready;
      ready.set_value(step->Centroid(*image->second, *info->second, pose));
      task.result = ready.get_future();
    } else {
      task.result = std::async(
          std::launch::async, [this, step, image = image->second, info = info->second, pose] {
            return Timed(&stages_.targets, [&] { return step->Centroid(*image, *info, pose); });
          });
    }
    centroiding_ = std::move(task);
    c->images.erase(c->images.begin(), std::next(image));
    c->infos.erase(c->infos.begin(), std::next(info));
  }

  // Message types the graph takes input from (OnMessage's branches).
  // The image of `m`, or null when its record is larger than an image within
  // the limits can be (not read) or its header claims more pixels than the
  // limit or does not describe its data; a skipped message is named with its
  // topic and bag time (skipped()).
  sensor_msgs::Image::ConstPtr CheckedImage(const rosbag::MessageInstance& m) {
    const ros_adapters::ImageMessageLimits& limits = args_.image_limits;
    std::string why;
    sensor_msgs::Image::ConstPtr image;
    if (m.size() > ros_adapters::MaxImageMessageBytes(limits)) {
      why = Message("a record of ", m.size(), " bytes, more than an image of max_megapixels ",
                    limits.max_megapixels, " can hold (",
                    ros_adapters::MaxImageMessageBytes(limits), " bytes); not read");
    } else {
      image = m.instantiate<sensor_msgs::Image>();
      try {
        if (image) ros_adapters::CheckImageMessage(*image, limits);
      } catch (const InvalidArgument& e) {
        why = e.what();
        image.reset();
      }
    }
    if (image) return image;
    char at[32];
    std::snprintf(at, sizeof at, "%.3f", m.getTime().toSec());
    skipped_.push_back(Message("image message on ", m.getTopic(), " at ", at, " s: ", why));
    Log("skipped " + skipped_.back());
    return nullptr;
  }

  static bool Handled(const std::string& type) {
    static const std::set<std::string> types = {
        ros::message_traits::datatype<tf2_msgs::TFMessage>(),
        ros::message_traits::datatype<sensor_msgs::Image>(),
        ros::message_traits::datatype<sensor_msgs::CameraInfo>(),
        ros::message_traits::datatype<slope_monitor::EpochMarker>(),
        ros::message_traits::datatype<geometry_msgs::PoseWithCovarianceStamped>(),
        ros::message_traits::datatype<slope_monitor::RadioSampleBlock>()};
    return types.count(type) > 0;
  }

  void TakeCentroided() {
    if (!centroiding_) return;
    Centroiding task = std::move(*centroiding_);
    centroiding_.reset();
    const ros::Time now = now_;
    now_ = task.bag_time;  // written and collected at the photo's place in the bag
    try {
      const ros_adapters::CentroidedImage out = task.result.get();
      Centroider* c = task.c;
      Write("/" + c->step->camera() + "/targets", out.targets);
      c->step->Count(out);
      if (c->step->has_targets()) {
        c->last_image = task.image;
        c->last = out;
      }
      Solve(adjuster_->AddTargets(out.targets, now_.toSec()));
    } catch (const std::exception& e) {
      Log("target_centroider: " + task.c->step->Dropped(task.image->header, e.what()));
    }
    now_ = now;
  }

  void OnEpochEnd(const slope_monitor::EpochMarker& marker) {
    std::vector<ros_adapters::LogLine> ignored;
    const std::vector<ros_adapters::SolvedEpoch> epochs =
        adjuster_->AddEnd(marker, now_.toSec(), &ignored);
    for (const ros_adapters::LogLine& line : ignored) Log("bundle_adjuster: " + line.text);
    Solve(epochs);
  }

  // A receiver's block (/radio/<id>/samples) through the radio step, as the
  // radio_phase_solver nodelet takes it (a recording: no wall-clock test of
  // the stamps, now = 0).
  void OnRadioBlock(const slope_monitor::RadioSampleBlock& block, const std::string& topic) {
    const std::string receiver = ros_adapters::RadioReceiverOfTopic(topic);
    if (!radio_ || receiver.empty()) return;
    if (!radio_->Accept(block, receiver, 0.0)) {
      Log("radio_phase_solver: rejected " + radio_->last_problem());
      return;
    }
    std::vector<ros_adapters::LogLine> dropped;
    for (const ros_adapters::RadioEpochOutput& out : radio_->Assemble(block, &dropped)) {
      for (const ros_adapters::LogLine& line : out.log)
        if (line.level >= ros_adapters::LogLine::kError) Log("radio_phase_solver: " + line.text);
      Write("/radio/phase_observations", out.messages.observations);
      if (out.messages.displacements) {
        Write(kRadioDisplacements, *out.messages.displacements);
        Fuse(*out.messages.displacements, kRadioDisplacements);
      }
    }
    for (const ros_adapters::LogLine& line : dropped) Log("radio_phase_solver: " + line.text);
  }

  // ---- the hex matcher (mode sequence), one per UAV camera.
  struct UavMatcher {
    std::unique_ptr<ros_adapters::SequenceMatcherStep> step;  // parameters().camera: the UAV camera
    ros_adapters::UavTopics topics;
  };

  // The matcher whose topic `field` (image or prior) is `topic`, if any.
  UavMatcher* UavMatcherOf(const std::string& topic, std::string ros_adapters::UavTopics::*field) {
    for (UavMatcher& uav : uav_matchers_)
      if (uav.topics.*field == topic) return &uav;
    return nullptr;
  }

  // The adjuster's position priors: each site UAV camera's topic, or the
  // graph's /uav/camera/position_prior without a site file.
  bool IsPriorTopic(const std::string& topic) const {
    const ros_adapters::AdjusterParameters& params = adjuster_->parameters();
    if (!params.cameras_from_site)
      return topic == ros_adapters::UavCameraTopics(adjustment::DefaultUavCameras().front()).prior;
    const std::vector<std::string>& topics = params.prior_topics;
    return std::find(topics.begin(), topics.end(), topic) != topics.end();
  }

  void OnUavImage(UavMatcher* uav, const sensor_msgs::Image::ConstPtr& image) {
    OnSequenceStep(*uav, Timed(&stages_.matching, [&] { return uav->step->AddImage(image, 0.0); }));
  }

  // The sequence matcher's step for a UAV position prior (pure: nothing is
  // written or collected); none for a prior in another frame (logged).
  std::optional<ros_adapters::SequenceOutput> MatchUavPrior(
      UavMatcher* uav, const geometry_msgs::PoseWithCovarianceStamped& prior) {
    if (const auto why = uav->step->CheckPrior(prior)) {
      Log("hex_matcher: " + *why);
      return std::nullopt;
    }
    return Timed(&stages_.matching, [&] { return uav->step->AddPrior(prior); });
  }

  // The tie points written and collected; the pairs' progress only with --verbose.
  void OnSequenceStep(const UavMatcher& uav, const ros_adapters::SequenceOutput& out) {
    for (const ros_adapters::LogLine& line : out.log)
      if (line.level != ros_adapters::LogLine::kDebug || args_.verbose)
        Log("hex_matcher: " + line.text);
    for (const slope_monitor::TiePointArray& msg : out.tie_points) {
      ++stages_.pairs;
      stages_.tie_points += static_cast<int>(msg.points.size());
      Write(uav.topics.tie_points, msg);
      Solve(adjuster_->AddTies(msg, now_.toSec()));
    }
  }

  // ---- the bundle adjuster's epochs.
  void Solve(const std::vector<ros_adapters::SolvedEpoch>& epochs) {
    for (const ros_adapters::SolvedEpoch& e : epochs) Solve(e);
  }

  void Solve(const ros_adapters::SolvedEpoch& out) {
    const double adjustment = out.wall_time;
    const uint32_t epoch = out.solution.epoch;
    if (!out.accepted)
      last_failure_ = "epoch " + std::to_string(epoch) + " not accepted: " + out.solution.message;
    for (const ros_adapters::LogLine& line : out.log)
      if (line.level >= ros_adapters::LogLine::kWarn || args_.verbose)
        Log("bundle_adjuster: " + line.text);
    Publish(out);
    LogStages(epoch, out, adjustment);
  }

  // Wall time of each stage since the previous adjustment epoch, and the
  // process's peak memory so far: one line per epoch (doc/process_bag.md).
  void LogStages(uint32_t epoch, const ros_adapters::SolvedEpoch& out, double adjustment) {
    char line[400];
    std::snprintf(line, sizeof line,
                  "epoch %u stages: targets %.2f s, tie points %.2f s (%d pairs, %d points, "
                  "photo features %.2f s), adjustment %.2f s (Ceres %.2f s in %u iterations, "
                  "covariance %.2f s), dense %.2f s, estimator %.2f s; peak memory %.0f MB",
                  epoch, stages_.targets, stages_.matching, stages_.pairs, stages_.tie_points,
                  FeatureSeconds() - stages_.features_before, adjustment, out.solution.solve_time,
                  out.solution.iterations, out.covariance_time, stages_.dense, stages_.estimator,
                  PeakMemoryMb());
    Log(std::string(line) +
        (out.adjusted && out.photos.total > 0 ? "; " + out.photos.Brief() : ""));
    stages_ = StageTimes();
    stages_.features_before = FeatureSeconds();
  }

  // The sequence matchers' time on photo features so far [s].
  double FeatureSeconds() const {
    double s = 0.0;
    for (const UavMatcher& uav : uav_matchers_) s += uav.step->matcher().summary().feature_seconds;
    return s;
  }

  // Publishes a solved epoch as the bundle adjuster nodelet does; the
  // accepted one's displacements go to the estimator.
  void Publish(const ros_adapters::SolvedEpoch& out) {
    Write("/bundle_adjuster/solution", out.solution);
    if (dense_) Timed(&stages_.dense, [&] { dense_->OnSolution(out.solution, now_.toSec()); });
    if (!out.accepted) return;
    if (!out.fixed_transforms.empty()) {
      tf2_msgs::TFMessage tf;
      tf.transforms = out.fixed_transforms;
      Write("/tf_static", tf);
    }
    if (!out.moving_transforms.empty()) {
      tf2_msgs::TFMessage tf;
      tf.transforms = out.moving_transforms;
      Write("/tf", tf);
    }
    Write("/bundle_adjuster/points", out.points);
    Write("/bundle_adjuster/frustums", adjuster_->Frustums(out));
    if (out.displacements) {
      Write(kAdjusterDisplacements, *out.displacements);
      Fuse(*out.displacements, kAdjusterDisplacements);
    }
  }

  // ---- the deformation estimator (its inputs in one stamp order, no time-out).
  void Fuse(const slope_monitor::PointDisplacementArray& msg, const std::string& topic) {
    Publish(
        Timed(&stages_.estimator, [&] { return estimator_->AddDisplacements(msg, topic, 0.0); }));
  }

  // The dense step's areas of significant change (source surface), as the
  // estimator nodelet takes them from /dense/change_areas.
  void OnAreas(const slope_monitor::ChangeAreaArray& msg) {
    Write(ros_adapters::OfflineDense::kAreasTopic, msg);
    Publish(estimator_->AddAreas(msg, ros_adapters::OfflineDense::kAreasTopic));
  }

  // The estimator's problems and snapshots, written as the estimator nodelet publishes them.
  void Publish(const ros_adapters::EstimatorResult& result) {
    for (const ros_adapters::LogLine& line : result.problems)
      Log("deformation_estimator: " + line.text);
    for (const ros_adapters::EstimatorPublication& p : result.publications) {
      for (const ros_adapters::LogLine& line : p.log) Log("deformation_estimator: " + line.text);
      Write("/deformation_estimator/deformation", ros_adapters::ToMsg(p.snapshot, p.header));
      Write("/deformation_estimator/markers",
            ros_adapters::ToMarkers(p.snapshot, p.header, estimator_->parameters().markers));
      Write("/deformation_estimator/points", ros_adapters::ToCloud(p.snapshot, p.header));
      Write("/deformation_estimator/alerts", ros_adapters::ToAlerts(p.snapshot, p.header));
    }
  }

  template <typename M>
  void Write(const std::string& topic, const M& msg) {
    if (output_) output_->write(topic, now_, msg);
  }

  // Wall time per stage since the previous adjustment epoch [s] (LogStages).
  struct StageTimes {
    double targets = 0.0, matching = 0.0, dense = 0.0, estimator = 0.0;
    int pairs = 0, tie_points = 0;  // tie-point messages and their points
    double features_before = 0.0;   // FeatureSeconds() at the epoch's start
  };
  StageTimes stages_;
  // The photo being centroided on another thread (Pair, TakeCentroided).
  struct Centroiding {
    Centroider* c = nullptr;
    ros::Time bag_time;
    sensor_msgs::Image::ConstPtr image;
    std::future<ros_adapters::CentroidedImage> result;
  };
  std::optional<Centroiding> centroiding_;
  std::function<void(const std::string&)> log_;
  const Args& args_;
  rosbag::Bag* output_;
  ros::Time now_;                         // bag time of the message being processed
  ros_adapters::CameraPoses poses_{1e6};  // the centroiders' (a bag's length of /tf)
  std::map<std::string, Centroider> centroiders_;
  std::unique_ptr<ros_adapters::TargetlessCameras> targetless_;  // fixed_targetless cameras
  // bundle_adjuster
  std::unique_ptr<ros_adapters::AdjusterStep> adjuster_;
  std::string last_failure_;          // the last epoch not accepted and why
  std::vector<std::string> skipped_;  // messages skipped, named (CheckedImage)
  std::optional<io::SiteFile> site_;  // --site
  // hex_matcher (mode sequence; --uav-tie-points): one per UAV camera
  std::vector<UavMatcher> uav_matchers_;
  std::unique_ptr<ros_adapters::RadioStep> radio_;  // radio_phase_solver; null: not running
  // deformation_estimator
  std::unique_ptr<ros_adapters::EstimatorStep> estimator_;
  std::unique_ptr<ros_adapters::OfflineDense> dense_;  // dense_matcher
};

// ---------------------------------------------------------------- progress

// One line on stderr: bag time reached, percent, epochs solved, time left
// (from the wall time so far); redrawn on a terminal, plain lines in a log
// (core/common/progress_line.h): every 30 s and at each epoch solved.
class Progress {
 public:
  Progress(const ros::Time& begin, const ros::Time& end) : begin_(begin), end_(end) {}

  // In a log, besides the interval's lines, a line whenever another epoch
  // is solved (what a crew watching the log, or a test, waits for).
  void Update(const ros::Time& t, int epochs, bool force = false) {
    if (!line_.Due(force || epochs != shown_epochs_)) return;
    shown_epochs_ = epochs;
    const double span = (end_ - begin_).toSec();
    const double done = span > 0 ? std::clamp((t - begin_).toSec() / span, 0.0, 1.0) : 1.0;
    const double elapsed = this->elapsed();
    char line[160];
    std::snprintf(
        line, sizeof(line), "process_bag: bag time %.1f s (%.0f %%), %d epochs solved, %s",
        (t - begin_).toSec(), 100.0 * done, epochs,
        done > 0.01
            ? (std::to_string(static_cast<int>(elapsed * (1 - done) / done + 0.5)) + " s left")
                  .c_str()
            : "time left unknown");
    line_.Show(line);
  }
  // A log line: on a line of its own, the progress line redrawn after.
  void Print(const std::string& text) { line_.Print(text); }
  void End() { line_.End(); }
  double elapsed() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  ros::Time begin_, end_;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  ProgressLine line_{stderr};
  int shown_epochs_ = 0;
};

int Run(Args args) {
  std::vector<fs::path> temporaries;
  struct Cleanup {
    std::vector<fs::path>* dirs;
    ~Cleanup() {
      std::error_code ec;
      for (const fs::path& d : *dirs) fs::remove_all(d, ec);
    }
  } cleanup{&temporaries};
  std::vector<std::unique_ptr<rosbag::Bag>> bags;
  std::vector<BagBreak> breaks;
  for (const std::string& path : args.bags) bags.push_back(OpenBag(path, &temporaries, &breaks));
  CheckInputFiles(args);
  // The bag's own history from an earlier run: continued, and said so.
  if (args.default_database && fs::exists(args.database))
    std::cerr << "process_bag: continuing the history '" << args.database
              << "' of an earlier run of this bag (no --database given); --database FILE "
                 "starts another\n";
  rosbag::View view;
  for (const auto& bag : bags) view.addQuery(*bag);
  if (view.size() == 0) throw InvalidArgument("bag '" + args.bags.front() + "' holds no messages");
  const std::vector<std::string> cameras = CamerasOf(view);

  std::unique_ptr<rosbag::Bag> output;
  if (!args.output_bag.empty()) {
    output = std::make_unique<rosbag::Bag>();
    try {
      output->open(args.output_bag, rosbag::bagmode::Write);
    } catch (const rosbag::BagException& e) {
      throw IoError("cannot write --output-bag '" + args.output_bag + "': " + e.what());
    }
  }
  Progress progress(view.getBeginTime(), view.getEndTime());
  ResolveTargets(&args,
                 [&progress](const std::string& line) { progress.Print("process_bag: " + line); });
  std::vector<std::string> incomplete_at_end;  // "epoch 1 (end of input): incomplete: ..." lines
  OfflineGraph graph(args, cameras, output.get(),
                     [&progress, &incomplete_at_end](const std::string& line) {
                       progress.Print("process_bag: " + line);
                       const std::string mark = " (end of input): incomplete: ";
                       const size_t at = line.find(mark);
                       if (at != std::string::npos) {
                         const size_t epoch = line.rfind("epoch ", at);
                         incomplete_at_end.push_back(line.substr(epoch, at - epoch) + ": " +
                                                     line.substr(at + mark.size()));
                       }
                     });
  if (args.uav_tie_points)
    graph.SetUpUavTiePoints([&view](const std::string& topic) { return HasTopic(view, topic); });
  for (const rosbag::MessageInstance& m : view) {
    graph.OnMessage(m);
    progress.Update(m.getTime(), graph.epochs_solved());
  }
  progress.Update(view.getEndTime(), graph.epochs_solved(), true);
  progress.End();
  graph.Finish();
  if (output) output->close();
  std::cerr << "process_bag: " << view.size() << " messages of " << args.bags.size() << " bag(s) ("
            << cameras.size() << " cameras) processed in " << progress.elapsed() << " s\n";
  SayBreaks(breaks, incomplete_at_end);
  // Messages skipped (the rest processed): named again at the end, exit 2.
  if (!graph.skipped().empty()) {
    std::cerr << "process_bag: " << graph.skipped().size() << " message(s) skipped:\n";
    for (const std::string& line : graph.skipped()) std::cerr << "  " << line << "\n";
  }
  if (graph.epochs_solved() == 0 && !graph.has_points()) {
    // A run that solves nothing (no adjusted or radio epoch, and no point
    // from elsewhere, e.g. a fixed_targetless camera's field) fails with
    // status 1 (nothing produced), saying why in one line.
    std::cerr << "process_bag: nothing solved: " << graph.WhyNothingSolved() << "\n";
    return 1;
  }

  // The summary scripts/demo prints (the deformation_summary tool's table).
  const std::string stem = args.bags.front().substr(0, args.bags.front().size() - 4);
  const std::string truth_path = stem + ".truth.yaml";
  if (graph.has_points() && fs::exists(truth_path)) {
    const auto evaluation =
        evaluation::EvaluateHistory(args.database, sim::SurveyTruth::Load(truth_path));
    std::cout << "\nDeformation summary (fused estimate against the simulator's truth):\n"
              << evaluation::FormatTable(evaluation);
  }
  // As scripts/demo ends.
  std::cout << "\nReports in " << args.report_dir << ":\n";
  std::vector<std::string> files;
  if (fs::is_directory(args.report_dir))
    for (const fs::directory_entry& f : fs::directory_iterator(args.report_dir))
      files.push_back(f.path().filename().string());
  std::sort(files.begin(), files.end());
  for (const std::string& f : files) std::cout << "  " << f << "\n";
  std::cout << "History (SQLite): " << args.database << "\n";
  if (output) std::cout << "Outputs (rosbag play --clock): " << args.output_bag << "\n";
  // Input that ended early (processed up to the break) or messages skipped
  // (the rest processed), named above: exit 2.
  return breaks.empty() && graph.skipped().empty() ? 0 : 2;
}

}  // namespace
}  // namespace slope_monitor

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  try {
    return slope_monitor::Run(slope_monitor::ParseArgs(argc, argv));
  } catch (const slope_monitor::deformation::HistoryInUse& e) {
    // Another writer on --database: that one line, no usage text (issue 38).
    std::cerr << "process_bag: " << e.what() << "\n";
    return 1;
  } catch (const slope_monitor::Error& e) {
    std::cerr << "process_bag: " << e.what() << "\n" << slope_monitor::kUsage;
    return 1;
  } catch (const rosbag::BagException& e) {
    std::cerr << "process_bag: " << e.what() << "\n";
    return 1;
  }
}
