// bench_targets_detect: on the same rendered images, in one process:
//   (1) the bare libapriltag detector,
//   (2) our full centroider (libapriltag + edge-model refinement + circles),
//   (3) the plain gray-weighted centroid of DESIGN.md on the circles,
// printing the centre accuracy of each against the render truth and the
// throughput ratio ours / bare detector at 1280x720 and 4000x3000
// (quad_decimate 2, one thread). Targets: overhead <= 15 % at the same
// detector settings; >= 20 frames/s at 1280x720.
#include <chrono>
#include <cstdio>
#include <random>

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include "../test/core/targets/planar_target_renderer.h"
#include "slope_monitor/core/targets/target_centroider.h"

using namespace slope_monitor;
using namespace slope_monitor::targets;

namespace {

struct Scene {
  cv::Mat image;
  std::vector<Eigen::Vector2d> tag_truth, circle_truth;
};

// A grid of tags (40 px) and circles (30 px) seen obliquely by a nadir camera.
Scene MakeScene(int w, int h, int n_tags, int n_circles, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(0, 1);
  const double focal = 1000.0, height = 10.0, mpp = height / focal;
  const camera::CameraModel cam = testing::NadirCamera(w, h, focal);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, height);
  testing::RenderOptions ro;
  ro.read_noise = 1.0;
  ro.photons_per_dn = 50.0;
  ro.seed = seed;
  Scene s;
  cv::Mat f = testing::Background(w, h, ro);
  const int n = n_tags + n_circles;
  const int cols = static_cast<int>(std::ceil(std::sqrt(n * double(w) / h)));
  const int rows = (n + cols - 1) / cols;
  for (int i = 0; i < n; ++i) {
    const double cx = (i % cols + 0.5 + 0.2 * (uni(rng) - 0.5)) * w / cols;
    const double cy = (i / cols + 0.5 + 0.2 * (uni(rng) - 0.5)) * h / rows;
    const Eigen::Vector3d centre((cx - 0.5 * (w - 1)) * mpp, -(cy - 0.5 * (h - 1)) * mpp, 0);
    const testing::Plate plate = testing::TiltedPlate(centre, 0.6 * uni(rng), 6.28 * uni(rng), 6.28 * uni(rng));
    const Eigen::Matrix3d hm = testing::PlaneToPixel(cam, pose, plate);
    if (i < n_tags) {
      testing::TagPattern tag(i % 500, 40 * mpp);
      testing::RenderPlate(&f, hm, tag.AsPattern(), tag.half_extent(), ro);
      s.tag_truth.push_back(testing::Apply(hm, 0, 0));
    } else {
      testing::RenderPlate(&f, hm, testing::CirclePattern(30 * mpp), 30 * mpp, ro);
      s.circle_truth.push_back(testing::Apply(hm, 0, 0));
    }
  }
  s.image = testing::ToMono8(f, ro);
  return s;
}

double Nearest(const std::vector<Eigen::Vector2d>& truth, const Eigen::Vector2d& p) {
  double best = 1e9;
  for (const auto& t : truth) best = std::min(best, (t - p).norm());
  return best;
}

template <typename F>
double SecondsPerFrame(F f, int reps) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < reps; ++i) f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / reps;
}

void Run(int w, int h, int n_tags, int n_circles, int reps) {
  const Scene s = MakeScene(w, h, n_tags, n_circles, 7);
  // (1) bare libapriltag.
  apriltag_detector_t* td = apriltag_detector_create();
  td->quad_decimate = 2.0;
  td->nthreads = 1;
  apriltag_family_t* tf = tag36h11_create();
  apriltag_detector_add_family_bits(td, tf, 1);
  image_u8_t im{s.image.cols, s.image.rows, static_cast<int32_t>(s.image.step[0]), const_cast<uint8_t*>(s.image.data)};
  double bare_sq = 0;
  int bare_n = 0;
  {
    zarray_t* d = apriltag_detector_detect(td, &im);
    for (int i = 0; i < zarray_size(d); ++i) {
      apriltag_detection_t* det;
      zarray_get(d, i, &det);
      const double e = Nearest(s.tag_truth, Eigen::Vector2d(det->c[0] - 0.5, det->c[1] - 0.5));
      if (e < 2) bare_sq += e * e / 2, ++bare_n;
    }
    apriltag_detections_destroy(d);
  }
  const double t_bare = SecondsPerFrame([&] { apriltag_detections_destroy(apriltag_detector_detect(td, &im)); }, reps);
  // (2) ours, tags only (same detector settings) and with circles.
  Options tags_only;
  tags_only.detect_circles = false;
  TargetCentroider ours_tags(tags_only, io::TargetList());
  Options full;
  TargetCentroider ours_full(full, io::TargetList());
  const Result r = ours_full.Detect(s.image, "mono8");
  double tag_sq = 0, circ_sq = 0, gray_sq = 0;
  int tag_n = 0, circ_n = 0;
  for (const auto& o : r.observations) {
    if (o.family == "circle") {
      const double e = Nearest(s.circle_truth, o.centre), g = Nearest(s.circle_truth, o.gray_centroid);
      circ_sq += e * e / 2, gray_sq += g * g / 2, ++circ_n;
    } else {
      const double e = Nearest(s.tag_truth, o.centre);
      tag_sq += e * e / 2, ++tag_n;
    }
  }
  const double t_tags = SecondsPerFrame([&] { ours_tags.Detect(s.image, "mono8"); }, reps);
  const double t_full = SecondsPerFrame([&] { ours_full.Detect(s.image, "mono8"); }, reps);
  std::printf("%dx%d: bare_apriltag  %d/%zu tags, centre RMS %.4f px, %.2f frames/s\n", w, h, bare_n, s.tag_truth.size(),
              std::sqrt(bare_sq / std::max(1, bare_n)), 1 / t_bare);
  std::printf("%dx%d: ours (tags)    %d/%zu tags, centre RMS %.4f px, %.2f frames/s\n", w, h, tag_n, s.tag_truth.size(),
              std::sqrt(tag_sq / std::max(1, tag_n)), 1 / t_tags);
  std::printf("%dx%d: ours (circles) %d/%zu circles, centre RMS %.4f px; plain gray-weighted centroid RMS %.4f px\n", w,
              h, circ_n, s.circle_truth.size(), std::sqrt(circ_sq / std::max(1, circ_n)),
              std::sqrt(gray_sq / std::max(1, circ_n)));
  std::printf("%dx%d: ours (tags + circles) %.2f frames/s\n", w, h, 1 / t_full);
  std::printf("%dx%d: ratio ours_tags/bare_apriltag time = %.3f (overhead %.1f %%, target <= 15 %%)\n", w, h,
              t_tags / t_bare, 100 * (t_tags / t_bare - 1));
  std::printf("%dx%d: ratio ours_full/bare_apriltag time = %.3f\n", w, h, t_full / t_bare);
  apriltag_detector_destroy(td);
  tag36h11_destroy(tf);
}

}  // namespace

int main() {
  Run(1280, 720, 12, 12, 10);
  Run(4000, 3000, 40, 40, 2);
  return 0;
}
