// make_survey_bag: renders a simulated slope survey and writes it as a bag
// plus its ground truth (doc/simulator.md).
//
//   make_survey_bag --config config/sim/demo_site.yaml --out demo.bag [--compression lz4|bz2|none]
//   [--seed N]
//
// Writes demo.bag, demo.truth.yaml, demo.targets.yaml, demo.surface_eNN.tif.
// Also runs as a ROS node from launch/make_survey_bag.launch (arguments
// passed on the command line; ROS remapping arguments are ignored).
#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>

#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/progress_line.h"
#include "slope_monitor/core/sim/survey.h"
#include "slope_monitor/ros/sim_bag_writer.h"

namespace {

void Usage(std::ostream& out = std::cerr) {  // --help: std::cout
  out << "usage: make_survey_bag --config <site.yaml> --out <name.bag> [--compression "
         "lz4|bz2|none] "
         "[--seed N] [--quiet]\n";
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  // lz4, as record.launch writes: a survey bag is read many times (replays,
  // process_bag, the tests), and lz4 chunks decompress several times faster
  // than bz2 (process_bag on the estimator_restart survey: 8.1 -> 5.8 s).
  std::string config_path, out, compression = "lz4";
  long seed = -1;
  bool quiet = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "make_survey_bag: " << name << " needs a value\n";
        Usage();
        std::exit(1);
      }
      return argv[++i];
    };
    if (a == "--config") {
      config_path = value("--config");
    } else if (a == "--out") {
      out = value("--out");
    } else if (a == "--compression") {
      const std::string v = value("--compression");
      if (v != "default") compression = v;  // make_survey_bag.launch's default
    } else if (a == "--seed") {
      const std::string v = value("--seed");
      size_t used = 0;
      try {
        seed = std::stol(v, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (v.empty() || used != v.size() || seed < 0 || seed > 4294967295L) {
        std::cerr << "make_survey_bag: --seed '" << v
                  << "' must be an integer in [0, 4294967295]\n";
        return 1;
      }
    } else if (a == "--quiet") {
      quiet = true;
    } else if (a == "-h" || a == "--help") {
      Usage(std::cout);
      return 0;
    } else if (a.rfind("__", 0) == 0 || a.find(":=") != std::string::npos) {
      continue;  // ROS arguments (__name:=..., __log:=...) when launched as a node
    } else {
      std::cerr << "make_survey_bag: unknown argument '" << a << "'\n";
      Usage();
      return 1;
    }
  }
  if (config_path.empty() || out.empty()) {
    std::cerr << "make_survey_bag: --config and --out are required\n";
    Usage();
    return 1;
  }
  std::string stem = out;
  if (stem.size() > 4 && stem.substr(stem.size() - 4) == ".bag")
    stem = stem.substr(0, stem.size() - 4);
  const std::string bag_path = stem + ".bag";

  const auto t_start = std::chrono::steady_clock::now();
  try {
    slope_monitor::sim::SurveyConfig config = slope_monitor::sim::SurveyConfig::Load(config_path);
    if (seed >= 0) {
      config.seed = static_cast<unsigned int>(seed);
      config.scene.seed = config.seed;
      config.radio.sim.seed = config.seed;
    }
    slope_monitor::sim::SurveyGenerator generator(config);
    // Redrawn on a terminal, plain lines in a log (core/common/progress_line.h).
    slope_monitor::ProgressLine progress(stderr);
    slope_monitor::sim::Survey survey = generator.Generate([&](int i, int n) {
      if (!quiet && progress.Due(i == n))
        progress.Show("rendered " + std::to_string(i) + "/" + std::to_string(n) + " images");
    });
    progress.End();
    slope_monitor::sim::WriteSurveyFiles(&survey, stem);
    const auto s = slope_monitor::ros_adapters::WriteSurveyBag(survey, bag_path, compression);
    const double secs =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    std::printf("wrote %s: %d images, %d GNSS fixes, %d radio blocks, %d epoch markers in %.1f s\n",
                bag_path.c_str(), s.images, s.gnss_fixes, s.radio_blocks, s.epoch_markers, secs);
    std::printf("truth: %s.truth.yaml  targets: %s.targets.yaml  surfaces: %s.surface_eNN.tif\n",
                stem.c_str(), stem.c_str(), stem.c_str());
  } catch (const std::exception& e) {
    std::cerr << "make_survey_bag: " << config_path << ": " << e.what() << "\n";
    return 1;
  }
  return 0;
}
