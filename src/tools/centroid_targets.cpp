// centroid_targets: run the target centroider over an image folder or a bag
// topic and write CSV (image, stamp, id, family, role, x, y, cov_xx, cov_xy,
// cov_yy, quality).
//
//   centroid_targets --images DIR --out targets.csv [--targets list.yaml] [--config target_centroider.yaml]
//   centroid_targets --bag survey.bag --topic /fixed_cam_1/camera/image_raw --out targets.csv [...]
//
// --config reads the same keys as config/defaults/target_centroider.yaml
// (the AprilTag / circle / acceptance keys; unknown keys are an error).
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
#include "slope_monitor/core/targets/target_centroider.h"

using namespace slope_monitor;

namespace {

targets::Options LoadOptions(const std::string& path) {
  targets::Options o;
  if (path.empty()) return o;
  io::YamlMap m = io::YamlMap::Load(path);
  o.families = m.Strings("families", o.families);
  o.quad_decimate = m.Double("quad_decimate", o.quad_decimate, 1.0, 8.0);
  o.quad_sigma = m.Double("quad_sigma", o.quad_sigma, 0.0, 10.0, "px");
  o.refine_edges = m.Bool("refine_edges", o.refine_edges);
  o.decode_sharpening = m.Double("decode_sharpening", o.decode_sharpening, 0.0, 10.0);
  o.threads = m.Int("threads", o.threads, 1, 64);
  o.max_hamming = m.Int("max_hamming", o.max_hamming, 0, 3);
  o.min_decision_margin = m.Double("min_decision_margin", o.min_decision_margin, 0.0, 1000.0);
  o.refine_tags = m.Bool("refine_tags", o.refine_tags);
  o.detect_circles = m.Bool("detect_circles", o.detect_circles);
  o.circle_min_diameter = m.Double("circle_min_diameter", o.circle_min_diameter, 4.0, 2000.0, "px");
  o.circle_max_diameter = m.Double("circle_max_diameter", o.circle_max_diameter, 4.0, 2000.0, "px");
  o.circle_max_eccentricity = m.Double("circle_max_eccentricity", o.circle_max_eccentricity, 0.01, 0.99);
  o.circle_id_gate = m.Double("circle_id_gate", o.circle_id_gate, 0.01, 5.0);
  o.refine_circles = m.Bool("refine_circles", o.refine_circles);
  o.correct_perspective = m.Bool("correct_perspective", o.correct_perspective);
  o.min_contrast = m.Double("min_contrast", o.min_contrast, 0.1, 254.0, "DN");
  o.border_margin = m.Double("border_margin", o.border_margin, 0.0, 100.0, "px");
  o.saturation_level = m.Double("saturation_level", o.saturation_level, 1.0, 255.0, "DN");
  o.max_saturated_fraction = m.Double("max_saturated_fraction", o.max_saturated_fraction, 0.0, 1.0);
  o.max_edge_blur = m.Double("max_edge_blur", o.max_edge_blur, 0.01, 20.0, "px");
  o.max_residual = m.Double("max_residual", o.max_residual, 0.01, 1.0);
  o.noise_floor = m.Double("noise_floor", o.noise_floor, 0.0, 50.0, "DN");
  // Node-only keys are allowed in the shared file.
  m.String("target_list", "");
  m.String("camera_name", "");
  m.String("site_frame", "site");
  m.Bool("use_tf_pose", true);
  m.Double("pixel_size", 1.0, 1e-6, 1.0);
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
    const targets::Options options = LoadOptions(args.count("--config") ? args["--config"] : "");
    const io::TargetList list = args.count("--targets") ? io::TargetList::Load(args["--targets"]) : io::TargetList();
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
  }
  return 0;
}
