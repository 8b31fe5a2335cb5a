// bag_check: reports what recorded bags hold — topics, message counts, time
// span, epoch boundaries (EpochMarker messages, or pauses of the whole bag
// longer than --epoch-gap) and per-topic gaps longer than --gap. Fails with a
// message naming the file on an empty, truncated or non-bag file.
//
//   bag_check [--gap S] [--epoch-gap S] [--session] file.bag [more.bag ...]
//
// --session: the bags are the split parts of one recording (record.launch):
// one report over all of them in time order, so an epoch or gap that spans a
// split is reported once.
//
// Exit status: 0 all bags readable, 1 some bag unreadable or a usage error
// (the tools' convention, doc/security.md).
#include <cstdlib>
#include <iostream>
#include <string>
#include <vector>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/capture_conversions.h"

namespace {

// The usage, after `why` (none for --help, which goes to stdout).
int Usage(const std::string& why, std::ostream& out = std::cerr) {
  if (!why.empty()) out << "bag_check: " << why << "\n";
  out << "usage: bag_check [--gap SECONDS] [--epoch-gap SECONDS] [--session] file.bag "
         "[more.bag ...]\n";
  return 1;
}

bool ParsePositive(const std::string& text, double* out) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !(v > 0.0)) return false;
  *out = v;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::ros_adapters::BagCheckOptions options;
  std::vector<std::string> bags;
  bool session = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--session") {
      session = true;
    } else if (a == "--gap" || a == "--epoch-gap") {
      if (i + 1 >= argc) return Usage(a + " needs a value");
      double* target = a == "--gap" ? &options.gap : &options.epoch_gap;
      if (!ParsePositive(argv[++i], target))
        return Usage(a + " value '" + argv[i] + "' is not a positive number");
    } else if (a == "-h" || a == "--help") {
      Usage("", std::cout);
      return 0;
    } else if (!a.empty() && a[0] == '-') {
      return Usage("unknown option '" + a + "'");
    } else {
      bags.push_back(a);
    }
  }
  if (bags.empty()) return Usage("no bag file given");
  if (session) {
    try {
      std::cout << slope_monitor::ros_adapters::FormatBagReport(
          slope_monitor::ros_adapters::CheckBags(bags, options));
      return 0;
    } catch (const slope_monitor::Error& e) {
      std::cerr << "bag_check: " << e.what() << "\n";
      return 1;
    }
  }
  int status = 0;
  for (const auto& path : bags) {
    try {
      std::cout << slope_monitor::ros_adapters::FormatBagReport(
          slope_monitor::ros_adapters::CheckBag(path, options));
    } catch (const slope_monitor::Error& e) {
      std::cerr << "bag_check: " << e.what() << "\n";
      status = 1;
    }
  }
  return status;
}
