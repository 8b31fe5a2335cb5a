// Benchmark (issue 19): re-orientation + displacement field of ~2000 probe
// points on a real photo pair (Columbia AK10, 3872 x 2592 px = 10 MP,
// 2009-08-03 -> 08-04; the data of test/data/timelapse_columbia and
// ../shared/data/timelapse_columbia) against OpenCV's calcOpticalFlowPyrLK +
// findHomography on the same points.
//
//   ours: hex matcher on the stable land -> adjustment::ReorientCamera ->
//         dense::ComputeDisplacementField (MLSC per probe, DEM a plane at
//         100 m: the demo's DEM is not public).
//   lk:   calcOpticalFlowPyrLK of the stable probes, findHomography (RANSAC,
//         1 px) as the re-orientation, then LK of the glacier probes from the
//         homography's prediction; windows 21/31/41 px x 3/4 pyramid levels
//         run in the same go, the baseline is the most accurate of them (on
//         the stable check probes), with its time.
// Accuracy without truth: the stable-ground check probes must not move, so
// the RMS of their residual after the re-orientation [px] is each method's
// error; and the two methods' glacier displacements are compared.
// Prints wall time per photo of each (best of 2) and `ratio ours/lk = X`.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "slope_monitor/core/adjustment/reorient_camera.h"
#include "slope_monitor/core/adjustment/resect_camera.h"
#include "slope_monitor/core/capture/calibration.h"
#include "slope_monitor/core/capture/exif.h"
#include "slope_monitor/core/dense/displacement_field.h"
#include "slope_monitor/core/io/surveyed_points.h"
#include "slope_monitor/core/matching/hex_matcher.h"

using namespace slope_monitor;

namespace {

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// The land polygons (`u v` pairs per line) as a mask.
cv::Mat LandMask(const std::string& path, const cv::Size& size) {
  cv::Mat m(size, CV_8UC1, cv::Scalar(0));
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    std::vector<cv::Point> p;
    for (double u, v; s >> u >> v;) p.emplace_back(cvRound(u), cvRound(v));
    if (p.size() >= 3) cv::fillPoly(m, std::vector<std::vector<cv::Point>>{p}, cv::Scalar(255));
  }
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string test_data = std::string(SM_SOURCE_DIR) + "/test/data/timelapse_columbia/";
  std::string photos =
      argc > 1 ? argv[1] : std::string(SM_SOURCE_DIR) + "/../shared/data/timelapse_columbia/";
  if (!std::filesystem::exists(photos + "AK10_20090803_055410.JPG"))
    photos = "/work/shared/data/timelapse_columbia/";
  const std::string ref_path = photos + "AK10_20090821_051408.JPG";
  const cv::Mat a = cv::imread(photos + "AK10_20090803_055410.JPG", cv::IMREAD_GRAYSCALE);
  const cv::Mat b = cv::imread(photos + "AK10_20090804_055410.JPG", cv::IMREAD_GRAYSCALE);
  if (a.empty() || b.empty()) {
    std::fprintf(
        stderr,
        "track_camera_vs_lk: cannot read the Columbia photos under '%s' (give the folder)\n",
        photos.c_str());
    return 1;
  }
  // The camera as resect_camera finds it (doc/targetless_camera.md).
  const capture::ExifInfo exif = capture::ReadExif(ref_path);
  const camera::CameraModel nominal =
      capture::NominalModelFromExif(exif, a.cols, a.rows, 23.6 / a.cols, ref_path);
  adjustment::ResectCameraOptions ro;
  ro.pixel_sigma = 2.0;
  ro.has_position = true;
  ro.position = Eigen::Vector3d(499211.336, 6783755.954, 478.96);
  const auto res = adjustment::ResectCamera(
      io::ReadSurveyedPoints(test_data + "AK10_20090821_gcp.txt", io::PixelOrigin::kCorner),
      nominal, ro);
  if (!res.success) {
    std::fprintf(stderr, "resection failed: %s\n", res.message.c_str());
    return 1;
  }
  const cv::Mat land = LandMask(test_data + "AK10_20090821_land.txt", a.size());
  auto stable = [&land](const Eigen::Vector2d& x) {
    const int c = cvRound(x.x()), r = cvRound(x.y());
    return c >= 0 && r >= 0 && c < land.cols && r < land.rows && land.at<unsigned char>(r, c) != 0;
  };
  io::GeoRaster plane(500, 400, 480000.0, 6790000.0, 50.0);
  plane.AddBand("height", 100.0f);
  dense::DisplacementFieldOptions fo;
  fo.spacing_px = 60.0;  // ~2000 probes on the glacier and the land

  double t_ours = 1e30;
  dense::DisplacementField field;
  adjustment::ReorientSummary reo;
  for (int run = 0; run < 2; ++run) {
    const double t0 = Now();
    matching::HexMatcherOptions mo;
    mo.interest.max_points = 40000;
    mo.lsc_prefilter_sigma = 1.0;
    matching::MatchPrior prior;
    prior.estimate_global_shift = true;
    prior.radius = 64.0;
    prior.within = stable;
    prior.moving = [&](const Eigen::Vector2d& x) { return !stable(x); };
    const auto m = matching::HexMatcher(mo).Match(a, b, prior);
    std::vector<adjustment::StableTiePoint> ties;
    for (const auto& h : m.matches)
      if (!h.IsLowQuality() && stable(h.xa)) ties.push_back({h.xa, h.xb});
    reo = adjustment::ReorientCamera(res.model, res.exterior, ties, adjustment::ReorientOptions());
    dense::FieldInput in;
    in.model = res.model;
    in.reference = res.exterior;
    in.current = reo.success ? reo.exterior : res.exterior;
    in.attitude_covariance = reo.covariance;
    in.stable = stable;
    field = dense::ComputeDisplacementField(a, b, plane, in, fo);
    t_ours = std::min(t_ours, Now() - t0);
  }
  // The same probes for LK (all the field's probes, stable and not).
  std::vector<cv::Point2f> pa_stable, pa_moving;
  for (const auto& p : field.points)
    (p.stable ? pa_stable : pa_moving).emplace_back(p.xa.x(), p.xa.y());

  // LK: each set-up twice (best time), the most accurate set-up is the baseline.
  struct Lk {
    int window = 0, levels = 0;
    double time = 1e30, rms = 1e30;
    int n = 0;
    std::vector<cv::Point2f> pb_moving;
    std::vector<unsigned char> ok_moving;
  } best;
  for (const int window : {21, 31, 41})
    for (const int levels : {3, 4}) {
      Lk lk;
      lk.window = window;
      lk.levels = levels;
      std::vector<cv::Point2f> pb_stable;
      std::vector<unsigned char> ok_stable, inl;
      cv::Mat h;
      for (int run = 0; run < 2; ++run) {
        const double t0 = Now();
        std::vector<float> err;
        cv::calcOpticalFlowPyrLK(a, b, pa_stable, pb_stable, ok_stable, err,
                                 cv::Size(window, window), levels);
        std::vector<cv::Point2f> sa, sb;
        for (size_t i = 0; i < pa_stable.size(); ++i)
          if (ok_stable[i]) sa.push_back(pa_stable[i]), sb.push_back(pb_stable[i]);
        h = cv::findHomography(sa, sb, cv::RANSAC, 1.0, inl);
        cv::perspectiveTransform(pa_moving, lk.pb_moving, h);
        cv::calcOpticalFlowPyrLK(
            a, b, pa_moving, lk.pb_moving, lk.ok_moving, err, cv::Size(window, window), levels,
            cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01),
            cv::OPTFLOW_USE_INITIAL_FLOW);
        lk.time = std::min(lk.time, Now() - t0);
      }
      // Stable check probes after the homography [px]; gross mismatches (> 3 px) left out.
      std::vector<cv::Point2f> hs;
      cv::perspectiveTransform(pa_stable, hs, h);
      double s2 = 0;
      for (size_t i = 0; i < pa_stable.size(); ++i) {
        if (!ok_stable[i]) continue;
        const double d = cv::norm(pb_stable[i] - hs[i]);
        if (d > 3.0) continue;
        s2 += d * d;
        ++lk.n;
      }
      lk.rms = std::sqrt(s2 / std::max(1, lk.n));
      std::printf("lk window %d levels %d: %.2f s, stable RMS %.3f px (%d)\n", window, levels,
                  lk.time, lk.rms, lk.n);
      if (lk.rms < best.rms) best = lk;
    }
  const double t_lk = best.time;
  const std::vector<cv::Point2f>& pb_moving = best.pb_moving;
  const std::vector<unsigned char>& ok_moving = best.ok_moving;

  // Ours: stable check probes after the re-orientation [px].
  double s_ours = 0;
  int n_ours = 0;
  for (const auto& p : field.points) {
    if (!p.stable || !p.IsUsable()) continue;
    Eigen::Vector2d pred;
    if (!res.model.Project(reo.exterior, p.x_ref, &pred)) continue;
    s_ours += (p.xb - pred).squaredNorm();
    ++n_ours;
  }
  // Agreement on the moving probes (both usable): image displacement difference.
  std::vector<double> diff;
  size_t k = 0;
  for (const auto& p : field.points) {
    if (p.stable) continue;
    const size_t i = k++;
    if (!p.IsUsable() || !ok_moving[i]) continue;
    diff.push_back(std::hypot(p.xb.x() - pb_moving[i].x, p.xb.y() - pb_moving[i].y));
  }
  std::sort(diff.begin(), diff.end());
  std::printf(
      "probes: %zu (%zu on stable land); ours: %d usable; lk baseline: window %d, %d levels, %d "
      "moving tracked\n",
      field.points.size(), pa_stable.size(), field.summary.usable, best.window, best.levels,
      static_cast<int>(std::count(ok_moving.begin(), ok_moving.end(), 1)));
  std::printf(
      "stable check probes, RMS after the re-orientation: ours %.3f px (%d usable), lk %.3f px "
      "(%d, <= 3 px)\n",
      std::sqrt(s_ours / std::max(1, n_ours)), n_ours, best.rms, best.n);
  if (!diff.empty())
    std::printf(
        "glacier probes tracked by both: %zu, |xb_ours - xb_lk| median %.3f px, 90 %% %.3f px\n",
        diff.size(), diff[diff.size() / 2], diff[diff.size() * 9 / 10]);
  std::printf("time per photo: ours %.2f s, lk %.2f s\n", t_ours, t_lk);
  std::printf("ratio ours/lk = %.2f\n", t_ours / t_lk);
  return 0;
}
