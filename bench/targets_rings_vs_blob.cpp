// Circles on the real ring-board photo (test/data/targets_real_rings/, see
// test/data/README.md): our centroider with the defaults (circle_design auto)
// against OpenCV's SimpleBlobDetector on the light centres (blobColor 255,
// area 30..2000 px, circularity >= 0.7), each followed by the same lattice
// fit (core/targets/board_layout.h: lattice growth, RANSAC homography, radial
// distortion; OpenCV's findCirclesGrid needs the whole grid in view, which
// this photo does not show). Prints time (median of 20 runs, CPU of one
// thread), circles found, markers on the lattice, off the lattice, and the
// fit's RMS over all and over the markers both found.
//
//   bench_targets_rings_vs_blob
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include "bench_timing.h"
#include "slope_monitor/core/targets/board_layout.h"
#include "slope_monitor/core/targets/target_centroider.h"

using namespace slope_monitor;

namespace {

// Median of 20 runs [ms].
template <typename F>
double MedianMs(F f) {
  return bench::MedianMs(f, 20);
}

void Report(const char* name, double ms, const std::vector<Eigen::Vector2d>& c,
            const std::vector<double>& outer, const targets::BoardLayout& layout, int w, int h) {
  const targets::LatticeFit fit = targets::FitLattice(c, outer, layout, w, h);
  if (!fit.ok) {
    std::printf("%-26s %8.1f ms %4zu circles, lattice: %s\n", name, ms, c.size(),
                fit.message.c_str());
    return;
  }
  std::printf(
      "%-26s %8.1f ms %4zu circles, %3zu on the lattice (%d rows x %d cols), %2zu off, RMS %.3f px "
      "(homography alone %.3f px)\n",
      name, ms, c.size(), fit.markers.size(), fit.rows_seen, fit.cols_seen, fit.off_lattice.size(),
      fit.rms_px, fit.rms_homography_px);
}

}  // namespace

int main() {
  const std::string dir = std::string(SM_SOURCE_DIR) + "/test/data/targets_real_rings/";
  const cv::Mat img = cv::imread(dir + "target_3_split_00.png", cv::IMREAD_GRAYSCALE);
  if (img.empty()) {
    std::fprintf(stderr, "cannot read %starget_3_split_00.png\n", dir.c_str());
    return 1;
  }
  const targets::BoardLayout layout = targets::BoardLayout::Load(dir + "board_ringgrid.json");
  const targets::TargetCentroider ours{targets::Options(), io::TargetList()};
  targets::Result r;
  const double ms_ours = MedianMs([&] { r = ours.Detect(img, "mono8"); });
  std::vector<Eigen::Vector2d> c;
  std::vector<double> outer;
  for (const auto& o : r.observations) {
    c.push_back(o.centre);
    outer.push_back(o.size_px * std::max(o.ring_ratio, 1.0));
  }
  Report("ours (defaults)", ms_ours, c, outer, layout, img.cols, img.rows);
  std::printf("%-26s %zu rejected with a reason\n", "", r.rejections.size());

  cv::SimpleBlobDetector::Params p;
  p.blobColor = 255;
  p.minArea = 30;
  p.maxArea = 2000;
  p.filterByCircularity = true;
  p.minCircularity = 0.7f;
  const cv::Ptr<cv::SimpleBlobDetector> blob = cv::SimpleBlobDetector::create(p);
  std::vector<cv::KeyPoint> kp;
  const double ms_blob = MedianMs([&] { blob->detect(img, kp); });
  std::vector<Eigen::Vector2d> cb;
  for (const auto& k : kp) cb.emplace_back(k.pt.x, k.pt.y);
  Report("SimpleBlobDetector", ms_blob, cb, {}, layout, img.cols, img.rows);
  // The same markers: the nearest blob centre within 3 px of each of ours.
  std::vector<Eigen::Vector2d> both_ours, both_blob;
  for (const auto& a : c) {
    const Eigen::Vector2d* nearest = nullptr;
    for (const auto& b : cb)
      if ((a - b).norm() < 3.0 && (!nearest || (a - b).norm() < (a - *nearest).norm()))
        nearest = &b;
    if (nearest) {
      both_ours.push_back(a);
      both_blob.push_back(*nearest);
    }
  }
  Report("ours, markers both found", 0.0, both_ours, {}, layout, img.cols, img.rows);
  Report("blob, markers both found", 0.0, both_blob, {}, layout, img.cols, img.rows);
  return 0;
}
