// centroid_targets: run the target centroider over an image folder or a bag
// topic and write CSV, one row per observation: image, stamp, id, family,
// role, method (what gave the centre: edge_model / detector for tags,
// ellipse_model / gray_centroid / ring_centre for circles), x, y, cov_xx, cov_xy, cov_yy,
// quality, fit residual, the perspective correction subtracted from a
// circle's centre, and the four corners of a tag. The header lines (starting
// with '#') state the pixel convention.
//
//   centroid_targets --images DIR [--out targets.csv] [--targets list.yaml] [--config
//   target_centroider.yaml] [--explain] centroid_targets --bag survey.bag --topic
//   /north_ridge/camera/image_raw [--out targets.csv] [...]
//
// One line per image on stderr: "<image>: <t> tags, <c> circles, <r> rejected".
// --layout FILE (a board layout: ringgrid's target JSON or our YAML, see
// core/targets/board_layout.h) numbers the circles by their lattice index
// (the CSV's id) and prints the fit per image: markers, rows x columns, RMS
// of the lattice fit [px], circles off the lattice; a layout that does not
// fit is named with the reason.
//
// Without --out the CSV goes to stdout. --explain prints one line per
// rejected target and per discarded circle candidate with its reason to
// stderr. --config reads the same keys as config/defaults/target_centroider.yaml
// through the reader the nodelet uses (targets/options_reader.h; unknown keys
// are an error naming the file and key); without it the in-class defaults
// (the values of that file) are used.
//
// Every photo of --images is checked before it is decoded (io::ReadImageChecked,
// core/io/image_file.h): its size from the header (refused above
// --max-megapixels, default 100, before any pixel is allocated), its format
// from the content (a PNG named .jpg is read as PNG, with a note), and a JPEG
// or PNG must be whole (a truncated JPEG, which OpenCV would decode with the
// missing rows gray, is refused). A photo that fails is named with the reason
// on stderr, e.g.
//   centroid_targets: skipped image 'DIR/a.jpg': truncated JPEG: the data ends at byte ...
// and the other photos are processed.
//
// Exit status: 0 every input read and at least one image processed; 2 some
// images (files or bag messages) skipped, the rest processed and written;
// 1 nothing processed (no image readable), a usage error or a fatal error
// (missing folder, unreadable bag, bad --config or --targets).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <string>

#include <cv_bridge/cv_bridge.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Image.h>
#include <opencv2/imgcodecs.hpp>

#include "slope_monitor/core/common/allocator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/image_file.h"
#include "slope_monitor/core/io/target_file.h"
#include "slope_monitor/core/io/yaml_map.h"
#include "slope_monitor/core/targets/board_layout.h"
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
  targets::Options o = targets::ReadOptions(m);
  *node = targets::ReadNodeOptions(m);
  m.CheckNoUnknownKeys();
  return o;
}

std::string RoleName(const targets::Observation& o) {
  return o.role ? io::TargetRoleName(*o.role) : "unknown";
}

void WriteHeader(std::ostream& out) {
  out << "# centroid_targets: pixel convention OpenCV: x = column (right), y = row (down), (0, 0) "
         "= centre of the "
         "top-left pixel (libapriltag's coordinates minus 0.5 px)\n"
         "# method: edge_model (tag corners from the edge-model fit), detector (libapriltag's "
         "corners), ellipse_model, "
         "gray_centroid, ring_centre (a marker of three or more rings: the rings' common "
         "centre); cov in px^2; persp_dx/dy: perspective bias subtracted from a circle's "
         "centre [px]\n"
         "# c0..c3: tag corners in libapriltag order (tag's bottom-left, bottom-right, top-right, "
         "top-left); empty for "
         "circles\n"
         "image,stamp,id,family,role,method,x,y,cov_xx,cov_xy,cov_yy,quality,fit_residual,persp_dx,"
         "persp_dy,c0x,c0y,"
         "c1x,c1y,c2x,c2y,c3x,c3y\n";
}

void WriteRows(std::ostream& out, const std::string& image, double stamp,
               const targets::Result& r) {
  for (const auto& o : r.observations) {
    out << image << ',' << std::fixed << std::setprecision(6) << stamp << ',' << o.id << ','
        << o.family << ',' << RoleName(o) << ',' << targets::CentreMethodName(o.method) << ','
        << std::setprecision(4) << o.centre.x() << ',' << o.centre.y() << ',' << std::scientific
        << std::setprecision(4) << o.covariance(0, 0) << ',' << o.covariance(0, 1) << ','
        << o.covariance(1, 1) << ',' << std::fixed << std::setprecision(3) << o.quality << ','
        << std::setprecision(4) << o.fit_residual << ',' << o.perspective_correction.x() << ','
        << o.perspective_correction.y();
    for (int k = 0; k < 4; ++k) {
      if (o.has_corners) {
        out << ',' << o.corners[k].x() << ',' << o.corners[k].y();
      } else {
        out << ",,";
      }
    }
    out << '\n';
  }
}

// Numbers the circles by the layout's lattice index (their id) and prints the
// fit; a fit that fails leaves the ids as they are and says why.
void IdentifyOnLayout(const std::string& image, const targets::BoardLayout& layout,
                      targets::Result* r) {
  std::vector<Eigen::Vector2d> centres;
  std::vector<double> outer;
  std::vector<size_t> which;
  for (size_t k = 0; k < r->observations.size(); ++k) {
    const targets::Observation& o = r->observations[k];
    if (o.family != "circle" || o.id >= 0) continue;
    centres.push_back(o.centre);
    outer.push_back(o.size_px * std::max(o.ring_ratio, 1.0));
    which.push_back(k);
  }
  const targets::LatticeFit fit = targets::FitLattice(centres, outer, layout, r->width, r->height);
  if (!fit.ok) {
    std::fprintf(stderr, "%s: lattice: %s\n", image.c_str(), fit.message.c_str());
    return;
  }
  for (const targets::LatticeMarker& m : fit.markers)
    r->observations[which[m.observation]].id = m.id;
  if (layout.kind == targets::BoardLayout::Kind::kList) {
    std::fprintf(stderr,
                 "%s: layout: %zu of %zu listed markers, RMS %.3f px (homography), %zu circles off "
                 "the list\n",
                 image.c_str(), fit.markers.size(), layout.positions.size(), fit.rms_px,
                 fit.off_lattice.size());
    return;
  }
  std::fprintf(stderr,
               "%s: lattice: %zu markers on %d rows x %d columns, RMS %.3f px (homography alone "
               "%.3f px), %zu circles off the lattice\n",
               image.c_str(), fit.markers.size(), fit.rows_seen, fit.cols_seen, fit.rms_px,
               fit.rms_homography_px, fit.off_lattice.size());
  if (!fit.warning.empty())
    std::fprintf(stderr, "%s: lattice: note: %s\n", image.c_str(), fit.warning.c_str());
}

void Explain(const std::string& image, const targets::Result& r) {
  auto line = [&](const char* what, const targets::Rejection& rj) {
    std::fprintf(stderr, "explain: %s: %s %s/%d at (%.1f, %.1f): %s: %s\n", image.c_str(), what,
                 rj.family.c_str(), rj.id, rj.where.x(), rj.where.y(),
                 targets::RejectReasonName(rj.reason).c_str(), rj.detail.c_str());
  };
  for (const auto& rj : r.rejections) line("rejected", rj);
  for (const auto& rj : r.discarded) line("not a target:", rj);
}

int Usage(std::ostream& out = std::cerr) {  // --help: std::cout
  out << "usage: centroid_targets (--images DIR | --bag FILE --topic TOPIC) [--out FILE.csv] "
         "[--targets LIST.yaml] [--config OPTIONS.yaml] [--layout BOARD] [--max-megapixels MP] "
         "[--explain]\n"
         "exit status: 0 all read, 2 some images skipped, 1 nothing processed or an error\n";
  return 1;
}

// The image files of --images DIR (.png .jpg .jpeg .tif .tiff .pgm), sorted;
// a folder that is missing or holds none is named.
std::vector<std::filesystem::path> ImageFilesIn(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw IoError(Message("--images '", dir.string(), "' ",
                          std::filesystem::exists(dir, ec) ? "is not a folder" : "does not exist"));
  }
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    std::string ext = e.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" ||
        ext == ".pgm")
      files.push_back(e.path());
  }
  if (files.empty()) {
    throw IoError(
        Message("--images '", dir.string(), "' holds no image (.png .jpg .jpeg .tif .tiff .pgm)"));
  }
  std::sort(files.begin(), files.end());
  return files;
}

// What main does with each image's result (print, identify, write a row).
using TakeResult = std::function<void(const std::string& name, double stamp, targets::Result)>;

// Each image file through the centroider; an unreadable or refused file is
// named and skipped. Returns the number skipped.
int CentroidFiles(const std::vector<std::filesystem::path>& files,
                  const io::ImageFileOptions& image_options, targets::TargetCentroider& centroider,
                  const TakeResult& take) {
  int failed = 0;
  for (const auto& f : files) {
    cv::Mat img;
    try {
      const io::ImageHeader header = io::ReadImageHeader(f.string(), image_options);
      const std::string note = io::FormatNote(f.string(), header);
      if (!note.empty()) std::cerr << "centroid_targets: note: " << note << "\n";
      img = io::ReadImageChecked(f.string(), cv::IMREAD_UNCHANGED, image_options);
    } catch (const IoError& e) {
      std::cerr << "centroid_targets: skipped " << e.what() << "\n";
      ++failed;
      continue;
    }
    try {
      const std::string enc = img.depth() == CV_16U ? "mono16"
                              : img.channels() == 3 ? "bgr8"
                              : img.channels() == 4 ? "bgra8"
                                                    : "mono8";
      take(f.filename().string(), 0.0, centroider.Detect(img, enc));
    } catch (const Error& e) {
      std::cerr << "centroid_targets: skipped " << f << ": " << e.what() << "\n";
      ++failed;
    }
  }
  return failed;
}

// Each sensor_msgs/Image of `topic` in the bag through the centroider; an
// image that does not convert is named and skipped. Returns the number skipped.
int CentroidBagTopic(const std::string& bag_path, const std::string& topic,
                     targets::TargetCentroider& centroider, const TakeResult& take) {
  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw IoError(Message("cannot read bag '", bag_path, "': ", e.what()));
  }
  rosbag::View view(bag, rosbag::TopicQuery(std::vector<std::string>{topic}));
  if (view.size() == 0)
    throw IoError(Message("bag '", bag_path, "' has no messages on topic '", topic, "'"));
  int failed = 0;
  for (const rosbag::MessageInstance& m : view) {
    sensor_msgs::ImageConstPtr img = m.instantiate<sensor_msgs::Image>();
    if (!img) throw IoError(Message("topic '", topic, "' is not sensor_msgs/Image"));
    try {
      const cv_bridge::CvImageConstPtr cv_img = cv_bridge::toCvShare(img);
      take(topic + "#" + std::to_string(img->header.seq), img->header.stamp.toSec(),
           centroider.Detect(cv_img->image, img->encoding));
    } catch (const std::exception& e) {
      std::cerr << "centroid_targets: skipped image at " << img->header.stamp.toSec() << ": "
                << e.what() << "\n";
      ++failed;
    }
  }
  return failed;
}

}  // namespace

int main(int argc, char** argv) {
  slope_monitor::KeepFreedMemoryForReuse();  // core/common/allocator.h
  std::map<std::string, std::string> args;
  bool explain = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--explain") {
      explain = true;
    } else if (a == "-h" || a == "--help") {
      Usage(std::cout);
      return 0;
    } else if ((a == "--images" || a == "--bag" || a == "--topic" || a == "--out" ||
                a == "--targets" || a == "--config" || a == "--max-megapixels" ||
                a == "--layout") &&
               i + 1 < argc) {
      args[a] = argv[++i];
    } else {
      std::cerr << "centroid_targets: unknown or incomplete argument '" << a << "'\n";
      return Usage();
    }
  }
  if (args.count("--images") == args.count("--bag")) return Usage();
  try {
    // The input first: a bad one is named before anything is written.
    std::vector<std::filesystem::path> files;
    if (args.count("--images")) files = ImageFilesIn(args["--images"]);
    io::ImageFileOptions image_options;
    if (args.count("--max-megapixels")) {
      const std::string& v = args["--max-megapixels"];
      char* end = nullptr;
      image_options.max_megapixels = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0')
        throw InvalidArgument(Message("--max-megapixels '", v, "' is not a number"));
    }
    image_options.Check();
    targets::NodeOptions node;
    const targets::Options options =
        LoadOptions(args.count("--config") ? args["--config"] : "", &node);
    const std::string list_path = args.count("--targets") ? args["--targets"] : node.target_list;
    const io::TargetList list =
        list_path.empty() ? io::TargetList() : io::LoadTargetFile(list_path, nullptr);
    targets::TargetCentroider centroider(options, list);
    std::optional<targets::BoardLayout> layout;
    if (args.count("--layout")) layout = targets::BoardLayout::Load(args["--layout"]);
    std::ofstream file;
    if (args.count("--out")) {
      file.open(args["--out"]);
      if (!file) throw IoError(Message("cannot write '", args["--out"], "'"));
    }
    std::ostream& out = args.count("--out") ? file : std::cout;
    WriteHeader(out);
    int images = 0, tags = 0, circles = 0, rejected = 0, discarded = 0, failed = 0;
    auto take = [&](const std::string& name, double stamp, targets::Result r) {
      std::fprintf(stderr, "%s: %d tags, %d circles, %zu rejected\n", name.c_str(),
                   r.summary.num_tags, r.summary.num_circles, r.rejections.size());
      if (layout) IdentifyOnLayout(name, *layout, &r);
      WriteRows(out, name, stamp, r);
      if (explain) Explain(name, r);
      tags += r.summary.num_tags;
      circles += r.summary.num_circles;
      rejected += r.rejections.size();
      discarded += r.discarded.size();
      ++images;
    };
    if (args.count("--images")) {
      failed = CentroidFiles(files, image_options, centroider, take);
    } else {
      if (!args.count("--topic")) return Usage();
      failed = CentroidBagTopic(args["--bag"], args["--topic"], centroider, take);
    }
    std::cerr << "centroid_targets: " << images << " images, " << tags << " tags, " << circles
              << " circles, " << rejected << " rejected, " << discarded
              << " circle candidates discarded, " << failed << " skipped -> "
              << (args.count("--out") ? args["--out"] : std::string("stdout")) << "\n";
    if (images == 0) {
      std::cerr << "centroid_targets: no image could be processed\n";
      return 1;
    }
    if (failed > 0) return 2;
  } catch (const std::filesystem::filesystem_error& e) {
    std::cerr << "centroid_targets: cannot read '" << e.path1().string()
              << "': " << e.code().message() << "\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "centroid_targets: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
