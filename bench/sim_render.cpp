// Benchmark of the simulator's renderer: time per megapixel for a fixed-camera
// view and a UAV view of the demo site, against a baseline run in the same
// process: cv::remap (bilinear) of an image of the same size, i.e. the cost of
// a plain per-pixel geometric resampling.
//
//   bench_sim_render [config/sim/demo_site.yaml]
#include <chrono>
#include <cstdio>
#include <string>

#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/sim/renderer.h"
#include "slope_monitor/core/sim/survey.h"

namespace {

template <typename F>
double Seconds(F&& f, int repeats) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < repeats; ++i) f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() / repeats;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace slope_monitor;
  const std::string path =
      argc > 1 ? argv[1] : std::string(SM_SOURCE_DIR) + "/config/sim/demo_site.yaml";
  const sim::SurveyConfig config = sim::SurveyConfig::Load(path);
  const sim::SurveyGenerator gen(config);
  const sim::SurveyTruth& truth = gen.planned_truth();
  const sim::Scene::State state = gen.scene().AtTime(truth.epochs.back().stamp);
  sim::RenderOptions ro = config.render;
  for (size_t ci = 0; ci < truth.cameras.size(); ++ci) {
    const sim::CameraTruth& cam = truth.cameras[ci];
    const sim::Renderer renderer(gen.scene(), cam.model);
    const auto& pose = cam.images.front().exterior;
    ro.colour = cam.encoding == "bgr8";
    const int w = cam.model.sensor().width, h = cam.model.sensor().height;
    const double mp = w * h / 1e6;
    const double t_render = Seconds([&] { renderer.Render(state, pose, ro); }, 2);
    // Baseline: bilinear remap of a same-sized float image with a smooth map.
    cv::Mat src(h, w, CV_32FC1), map_x(h, w, CV_32FC1), map_y(h, w, CV_32FC1), dst;
    cv::randu(src, 0.0, 1.0);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        map_x.at<float>(r, c) = static_cast<float>(c + 0.3 * std::sin(r * 0.01));
        map_y.at<float>(r, c) = static_cast<float>(r + 0.3 * std::cos(c * 0.01));
      }
    const double t_remap =
        Seconds([&] { cv::remap(src, dst, map_x, map_y, cv::INTER_LINEAR); }, 20);
    std::printf("%s: render %.3f s per image, %.3f s/MP (%d threads); cv::remap %.5f s/MP\n",
                cam.name.c_str(), t_render, t_render / mp, ro.threads, t_remap / mp);
    std::printf("ratio ours/cv_remap %s = %.1f\n", cam.name.c_str(), t_render / t_remap);
  }
  return 0;
}
