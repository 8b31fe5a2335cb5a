// process_bag: a recorded (or simulated) survey through the whole processing
// graph, offline, at CPU speed:
//
//   rosrun slope_monitor process_bag --bag FILE [--bag FILE2 ...] [--site-config FILE]
//       [--target-list FILE] [--radio-network FILE] [--adjuster-config FILE]
//       [--uav-tie-points] [--database FILE] [--report-dir DIR] [--output-bag FILE]
//       [--no-dense] [--verbose] [--new-reference]
//
// The bags are read with rosbag::View in bag-time order (several bags, e.g.
// the split files of one recording, merged by time) and every message goes,
// in that order, to ros_adapters::OfflineGraph (ros/offline_graph.h): the
// same steps the nodelets of launch/replay.launch run, set up from the same
// parameters: a target centroider per camera, the bundle
// adjuster's EpochCollector and epoch solver, the radio phase solver with its
// epoch assembler, the deformation estimator with its SQLite history and
// reports. One process, no ROS master, no sleeps; completion of an epoch is
// decided by the messages only, so the result does not depend on the CPU load.
// Parameters: config/defaults/<node>.yaml, then config/process_bag/<node>.yaml
// (what the launch files add), then the command line and overlays, as
// replay.launch loads them. Defaults of the options: those of replay.launch
// (target list and truth beside the bag, reports under ~/.ros/slope_monitor).
// See doc/process_bag.md.
//
// The site's one history: without --database, every recording of
// a site continues ~/.ros/slope_monitor/<site name>.db (the name from the
// --site file, the overlay's site_name, the truth beside the bag; else the
// bag's name: ros/replay_defaults.h). The first line says which history and
// what it holds:
//   process_bag: history '<file>' of site '<name>': continuing: reference epoch <n> (<UTC>, from
//   <recording>), <k> epochs
// or that it starts one. The references (the adjuster's reference epoch, the
// radio network's reference solution) are the history's; they change only
// with --new-reference (the next epoch becomes the reference; the
// observations stay). A recording already in the history adds nothing:
//   process_bag: <bag>: already in the history: <n> epochs
// A recording of another site than the history's is refused with one line
// naming both (exit 1, nothing written).
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
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>

#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/common/progress_line.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/evaluation/deformation_truth.h"
#include "slope_monitor/core/io/safe_file.h"
#include "slope_monitor/ros/offline_graph.h"
#include "slope_monitor/ros/replay_defaults.h"

namespace fs = std::filesystem;

namespace slope_monitor {
namespace {

constexpr char kUsage[] =
    "usage: process_bag --bag FILE [--bag FILE2 ...] [--site FILE] [--site-config FILE] "
    "[--target-list FILE]\n"
    "                   [--radio-network FILE] [--adjuster-config FILE] [--uav-tie-points]\n"
    "                   [--database FILE] [--report-dir DIR] [--output-bag FILE] [--no-dense] "
    "[--verbose]\n"
    "                   [--max-megapixels MP] [--new-reference]\n";

// The graph's options (ros/offline_graph.h) and what only the tool uses.
struct Args : ros_adapters::OfflineGraphOptions {
  std::string output_bag;
  bool default_database = false;  // --database not given: the site's history
  bool new_reference = false;     // --new-reference
  std::string site_from;          // where the site name was read
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
    if (flag == "--new-reference") {
      a.new_reference = true;
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
  // The defaults of replay.launch: the site's history (ros/replay_defaults.h).
  const char* home = std::getenv("HOME");
  const std::string ros_dir = std::string(home ? home : ".") + "/.ros/slope_monitor";
  ros_adapters::SiteNameSources sources;
  sources.site_file = a.site;
  sources.site_config = a.site_config;
  sources.truth_file = a.bags.front().substr(0, a.bags.front().size() - 4) + ".truth.yaml";
  sources.recording = a.bags.front();
  a.site_name = ros_adapters::SiteNameOf(sources, &a.site_from);
  a.default_database = a.database.empty();
  if (a.default_database) a.database = ros_adapters::DefaultHistory(sources, home ? home : ".");
  if (a.report_dir.empty()) a.report_dir = ros_dir + "/reports";
  return a;
}

// The other input files (after the bags: a bag that is not one is named first).
void CheckInputFiles(const Args& a) {
  for (const std::string* f :
       {&a.site, &a.site_config, &a.target_list, &a.radio_network, &a.adjuster_config})
    if (!f->empty() && !fs::is_regular_file(*f))
      throw InvalidArgument("file '" + *f + "' not found");
  // Fail early: the outputs' folders are written before a message is processed.
  io::CheckFolderWritable(a.report_dir, "--report-dir");
  const fs::path database_folder = fs::path(a.database).parent_path();
  io::CheckFolderWritable(database_folder.empty() ? "." : database_folder.string(),
                          "folder of --database");
}

// ------------------------------------------------------------------ bags

// A bag read only up to its break (cut while recording or copying): named at
// the end of the run, which then exits 2.
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
        done > 0.01 ? (std::to_string(std::lround(elapsed * (1 - done) / done)) + " s left").c_str()
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

// What a run that solved something prints at its end on stdout (as
// scripts/demo ends): the fused estimate against the simulator's truth when
// there is one, the report files, the history and the output bag.
void PrintSummary(const Args& args, bool has_points, bool has_output) {
  // The summary scripts/demo prints (the deformation_summary tool's table).
  const std::string stem = args.bags.front().substr(0, args.bags.front().size() - 4);
  const std::string truth_path = stem + ".truth.yaml";
  if (has_points && fs::exists(truth_path)) {
    const auto evaluation =
        evaluation::EvaluateHistory(args.database, sim::SurveyTruth::Load(truth_path));
    std::cout << "\nDeformation summary (fused estimate against the simulator's truth):\n"
              << evaluation::FormatTable(evaluation);
  }
  // As scripts/demo ends.
  std::vector<std::string> files;
  if (fs::is_directory(args.report_dir))
    for (const fs::directory_entry& f : fs::directory_iterator(args.report_dir))
      files.push_back(f.path().filename().string());
  std::sort(files.begin(), files.end());
  if (files.empty())
    std::cout << "\nNo reports in " << args.report_dir << ": no monitoring point was measured"
              << (has_output ? " (the adjusted epochs are on /bundle_adjuster/solution and "
                               "/bundle_adjuster/points in the output bag)"
                             : "")
              << "\n";
  else
    std::cout << "\nReports in " << args.report_dir << ":\n";
  for (const std::string& f : files) std::cout << "  " << f << "\n";
  std::cout << "History (SQLite): " << args.database << "\n";
  if (has_output) std::cout << "Outputs (rosbag play --clock): " << args.output_bag << "\n";
}

// The first line: which history this run continues (its reference epoch,
// the recording it came from, its epochs) or that it starts one; with
// --new-reference the history's reference is cleared. False (said in one
// line) when the history is of another site.
bool SayHistory(const Args& a, deformation::History* history) {
  const deformation::HistoryInfo h = deformation::DescribeHistory(a.database);
  const std::string site = a.site_name.empty() ? "(unnamed)" : a.site_name;
  if (!h.site.empty() && !a.site_name.empty() && h.site != a.site_name) {
    std::cerr << "process_bag: the recording '" << a.bags.front() << "' is of site '" << a.site_name
              << "' (" << a.site_from << ") but the history '" << a.database << "' is of site '"
              << h.site << "': refused, nothing written\n";
    return false;
  }
  std::cerr << "process_bag: history '" << a.database << "' of site '" << site << "'";
  if (!h.exists || h.observations == 0) {
    std::cerr << ": a new history; its reference epoch is this recording's first\n";
  } else {
    std::cerr << ": continuing: ";
    // The survey's reference epoch is the adjuster's (the estimator counts
    // radio epochs too); without cameras, the estimator's.
    uint32_t epoch = h.reference_epoch;
    double stamp = h.reference_stamp;
    if (const auto saved =
            deformation::SavedStates(a.database).Get(ros_adapters::AdjusterStep::kStoreKey)) {
      adjustment::EpochStore store;
      store.Load(saved->value);
      if (const adjustment::EpochPoints* ref = store.Reference()) {
        epoch = static_cast<uint32_t>(ref->epoch);
        stamp = ref->stamp;
      }
    }
    if (h.has_reference)
      std::cerr << "reference epoch " << epoch << " (" << Utc(stamp)
                << (h.reference_recording.empty() ? "" : ", from " + h.reference_recording)
                << "), ";
    else
      std::cerr << "no reference epoch yet, ";
    std::cerr << h.epochs << " survey epochs and " << h.radio_epochs << " radio epochs"
              << (a.new_reference ? "; a new reference from this recording (--new-reference)" : "")
              << "\n";
  }
  if (a.new_reference && h.observations > 0) history->StartNewReference();
  return true;
}

// A recording whose every measurement the history already held.
void SayAlreadyHeld(const Args& a, const ros_adapters::OfflineGraph& graph) {
  const uint64_t held = graph.estimator().already_held();
  if (held == 0) return;
  if (graph.estimator().accepted() > 0) {
    std::cerr << "process_bag: " << held
              << " measurement(s) already in the history were not stored again\n";
    return;
  }
  const deformation::HistoryInfo h = deformation::DescribeHistory(a.database);
  std::cerr << "process_bag: " << a.bags.front() << ": already in the history: " << h.epochs
            << " epochs (and " << h.radio_epochs << " radio epochs)\n";
}

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
  // One writer per history: the history opened (its writer lock taken; another
  // writer named in one line) before anything else is said, then handed to
  // the graph's estimator.
  auto history = std::make_unique<deformation::History>(args.database);
  if (!SayHistory(args, history.get())) return 1;
  rosbag::View view;
  for (const auto& bag : bags) view.addQuery(*bag);
  if (view.size() == 0) throw InvalidArgument("bag '" + args.bags.front() + "' holds no messages");
  const std::vector<std::string> cameras = ros_adapters::BagCameras(view);

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
  ros_adapters::ResolveReplayTargets(
      &args, [&progress](const std::string& line) { progress.Print("process_bag: " + line); });
  std::vector<std::string> incomplete_at_end;  // "epoch 1 (end of input): incomplete: ..." lines
  ros_adapters::OfflineGraph graph(
      args, cameras, output.get(),
      [&progress, &incomplete_at_end](const std::string& line) {
        progress.Print("process_bag: " + line);
        const std::string mark = " (end of input): incomplete: ";
        const size_t at = line.find(mark);
        if (at != std::string::npos) {
          const size_t epoch = line.rfind("epoch ", at);
          incomplete_at_end.push_back(line.substr(epoch, at - epoch) + ": " +
                                      line.substr(at + mark.size()));
        }
      },
      std::move(history));
  if (args.uav_tie_points)
    graph.SetUpUavTiePoints(
        [&view](const std::string& topic) { return ros_adapters::BagHasTopic(view, topic); });
  for (const rosbag::MessageInstance& m : view) {
    graph.OnMessage(m);
    progress.Update(m.getTime(), graph.epochs_solved());
  }
  progress.Update(view.getEndTime(), graph.epochs_solved(), true);
  progress.End();
  graph.Finish();
  if (output) output->close();
  SayAlreadyHeld(args, graph);
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

  PrintSummary(args, graph.has_points(), output != nullptr);
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
    // Another writer on --database: that one line, no usage text.
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
