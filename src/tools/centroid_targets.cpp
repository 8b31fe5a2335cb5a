// centroid_targets: run the target centroider over an image folder or a bag
// topic and write CSV (image, stamp, id, family, role, x, y, cov_xx, cov_xy,
// cov_yy, quality).
//
//   centroid_targets --images DIR --out targets.csv [--targets list.yaml] [--config target_centroider.yaml]
//   centroid_targets --bag survey.bag --topic /fixed_cam_1/camera/image_raw --out targets.csv [...]
//
// --config reads the same keys as config/defaults/target_centroider.yaml
// through the reader the nodelet uses (targets/options_reader.h; unknown keys
// are an error naming the file and key).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <map>
#include <string>

#include <cv_bridge/cv_bridge.h>
#include <opencv2/imgcodecs.hpp>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/yaml_map.h"
#include "slope_monitor/core/targets/options_reader.h"
#include "slope_monitor/core/targets/target_centroider.h"

using namespace slope_monitor;

namespace {

// --config: the node's parameter file, read by the same targets::ReadOptions
// as the nodelet (node-only keys are read and checked too; --targets, when
// not given, defaults to the file's target_list).
targets::Options LoadOptions(const std::string& path, targets::NodeOptions* node) {
  if (path.empty()) return targets::Options();
  io::YamlMap m = io::YamlMap::Load(path);
  const targets::Options o = targets::ReadOptions(m);
  *node = targets::ReadNodeOptions(m);
  m.CheckNoUnknownKeys();
  return o;
}

std::string RoleName(const targets::Observation& o) {
  return o.role ? io::TargetRoleName(*o.role) : "unknown";
}

void WriteRows(std::ostream& out, const std::string& image, double stamp, const targets::Result& r) {
  for (const auto& o : r.observations) {
    out << image << ',' << std::fixed << std::setprecision(6) << stamp << ',' << o.id << ',' << o.family << ','
        << RoleName(o) << ',' << std::setprecision(4) << o.centre.x() << ',' << o.centre.y() << ','
        << std::scientific << std::setprecision(4) << o.covariance(0, 0) << ',' << o.covariance(0, 1) << ','
        << o.covariance(1, 1) << ',' << std::fixed << std::setprecision(3) << o.quality << '\n';
  }
}

int Usage() {
  std::cerr << "usage: centroid_targets (--images DIR | --bag FILE --topic TOPIC) --out FILE.csv "
               "[--targets LIST.yaml] [--config OPTIONS.yaml]\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::map<std::string, std::string> args;
  for (int i = 1; i + 1 < argc; i += 2) args[argv[i]] = argv[i + 1];
  if ((argc - 1) % 2 != 0 || !args.count("--out") || (args.count("--images") == args.count("--bag"))) return Usage();
  try {
    targets::NodeOptions node;
    const targets::Options options = LoadOptions(args.count("--config") ? args["--config"] : "", &node);
    const std::string list_path = args.count("--targets") ? args["--targets"] : node.target_list;
    const io::TargetList list = list_path.empty() ? io::TargetList() : io::TargetList::Load(list_path);
    targets::TargetCentroider centroider(options, list);
    std::ofstream out(args["--out"]);
    if (!out) throw IoError(Message("cannot write '", args["--out"], "'"));
    out << "image,stamp,id,family,role,x,y,cov_xx,cov_xy,cov_yy,quality\n";
    int images = 0, observations = 0, failed = 0;
    if (args.count("--images")) {
      std::vector<std::filesystem::path> files;
      for (const auto& e : std::filesystem::directory_iterator(args["--images"])) {
        std::string ext = e.path().extension().string();
        std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
        if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".pgm")
          files.push_back(e.path());
      }
      std::sort(files.begin(), files.end());
      for (const auto& f : files) {
        const cv::Mat img = cv::imread(f.string(), cv::IMREAD_UNCHANGED);
        try {
          std::string enc = img.depth() == CV_16U ? "mono16" : img.channels() == 3 ? "bgr8" : img.channels() == 4 ? "bgra8" : "mono8";
          const targets::Result r = centroider.Detect(img, enc);
          WriteRows(out, f.filename().string(), 0.0, r);
          observations += r.observations.size();
          ++images;
        } catch (const Error& e) {
          std::cerr << "centroid_targets: skipped " << f << ": " << e.what() << "\n";
          ++failed;
        }
      }
    } else {
      if (!args.count("--topic")) return Usage();
      rosbag::Bag bag;
      try {
        bag.open(args["--bag"], rosbag::bagmode::Read);
      } catch (const rosbag::BagException& e) {
        throw IoError(Message("cannot read bag '", args["--bag"], "': ", e.what()));
      }
      rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{args["--topic"]}));
      if (view.size() == 0) throw IoError(Message("bag '", args["--bag"], "' has no messages on topic '", args["--topic"], "'"));
      for (const rosbag::MessageInstance& m : view) {
        sensor_msgs::ImageConstPtr img = m.instantiate<sensor_msgs::Image>();
        if (!img) throw IoError(Message("topic '", args["--topic"], "' is not sensor_msgs/Image"));
        try {
          const cv_bridge::CvImageConstPtr cv_img = cv_bridge::toCvShare(img);
          const targets::Result r = centroider.Detect(cv_img->image, img->encoding);
          WriteRows(out, args["--topic"] + "#" + std::to_string(img->header.seq), img->header.stamp.toSec(), r);
          observations += r.observations.size();
          ++images;
        } catch (const std::exception& e) {
          std::cerr << "centroid_targets: skipped image at " << img->header.stamp.toSec() << ": " << e.what() << "\n";
          ++failed;
        }
      }
    }
    std::cerr << "centroid_targets: " << images << " images, " << observations << " observations, " << failed
              << " skipped -> " << args["--out"] << "\n";
  } catch (const Error& e) {
    std::cerr << "centroid_targets: " << e.what() << "\n";
    return 1;
  } catch (const std::filesystem::filesystem_error& e) {
    std::cerr << "centroid_targets: cannot read '" << e.path1().string() << "': " << e.code().message() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "centroid_targets: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
