// bench_targets_design_sweep: every circle design (disc_in_ring, dot, ring,
// concentric) rendered exactly (test/core/targets/design_renderer.h) with
// its light centre 8..150 px across, sharp and blurred, facing the camera
// on the axis and tilted off the axis (perspective), with realistic noise;
// measured with the defaults a user gets (circle_design auto) and the pose
// and target list (so the perspective bias is removed). Prints per design,
// size and blur: targets measured / rendered, the RMS centre error per
// coordinate against the render truth, the median |error| / sigma per
// coordinate (0.674 for an honest covariance) and the reasons of any miss.
//
//   bench_targets_design_sweep            # the full sweep (doc/targets_real_photos.md)
//   bench_targets_design_sweep 4          # 4 renders per cell (default 8)
//   bench_targets_design_sweep --one concentric 35 40 25 0.0 1035 [out.png]
//       # one render (design, size px, tilt deg, off-axis deg, blur px, seed):
//       # every observation, rejection and discarded candidate
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "../test/core/targets/design_renderer.h"

using namespace slope_monitor;
using namespace slope_monitor::targets;

namespace {

const std::vector<double> kSweepSizes = {8, 12, 20, 35, 60, 100, 150};  // [px]
const std::vector<double> kSweepBlurs = {0.0, 0.7, 1.2};                // [px] sigma

struct Geometry {
  const char* name;
  double tilt_deg, off_axis_deg;
};
const std::vector<Geometry> kSweepGeometries = {{"facing", 0.0, 0.0},
                                                {"tilted 40, 25 off axis", 40.0, 25.0}};

// Measures one shot; false (with the reason) when the target is not measured.
bool MeasureShot(const testing::DesignShot& shot, Eigen::Vector2d* err, Eigen::Matrix2d* cov,
                 std::string* why) {
  Options o;           // the defaults a user gets, without tag families (no tag
  o.families.clear();  // here; libapriltag's decode tables take a while to build)
  const TargetCentroider c(o, shot.list);
  const ViewGeometry view{shot.camera, shot.pose};
  const Result r = c.Detect(shot.image, "mono8", &view);
  for (const Observation& ob : r.observations) {
    if (ob.id != 1) continue;
    *err = ob.centre - shot.truth;
    *cov = ob.covariance;
    return true;
  }
  *why = "not a candidate";
  for (const Rejection& rj : r.rejections) *why = RejectReasonName(rj.reason) + ": " + rj.detail;
  if (r.rejections.empty() && !r.discarded.empty())
    *why = "discarded " + RejectReasonName(r.discarded[0].reason) + ": " + r.discarded[0].detail;
  return false;
}

// --one: one render, everything the centroider says about it.
int ShowOne(int argc, char** argv) {
  if (argc < 8) {
    std::fprintf(
        stderr,
        "usage: bench_targets_design_sweep --one design size tilt off_axis blur seed [png]\n");
    return 1;
  }
  testing::DesignShotSpec s;
  s.design = ParseCircleDesign(argv[2]);
  s.centre_px = std::atof(argv[3]);
  s.tilt_deg = std::atof(argv[4]);
  s.off_axis_deg = std::atof(argv[5]);
  s.blur_px = std::atof(argv[6]);
  s.seed = static_cast<unsigned>(std::atoi(argv[7]));
  const testing::DesignShot shot = testing::RenderDesignShot(s);
  if (argc > 8) cv::imwrite(argv[8], shot.image);
  Options o;
  o.families.clear();
  const TargetCentroider c(o, shot.list);
  const ViewGeometry view{shot.camera, shot.pose};
  const Result r = c.Detect(shot.image, "mono8", &view);
  std::printf("%dx%d, truth (%.4f, %.4f)\n", shot.image.cols, shot.image.rows, shot.truth.x(),
              shot.truth.y());
  for (const Observation& ob : r.observations)
    std::printf(
        "  circle/%d %s error (%+.4f, %+.4f) sigma (%.4f, %.4f) size %.2f blur %.2f residual %.4f "
        "persp (%.3f, %.3f) gray error (%+.4f, %+.4f)\n",
        ob.id, CircleDesignName(ob.design).c_str(), ob.centre.x() - shot.truth.x(),
        ob.centre.y() - shot.truth.y(), std::sqrt(ob.covariance(0, 0)),
        std::sqrt(ob.covariance(1, 1)), ob.size_px, ob.edge_blur, ob.fit_residual,
        ob.perspective_correction.x(), ob.perspective_correction.y(),
        ob.gray_centroid.x() - shot.truth.x(), ob.gray_centroid.y() - shot.truth.y());
  for (const Rejection& rj : r.rejections)
    std::printf("  rejected at (%.1f, %.1f): %s: %s\n", rj.where.x(), rj.where.y(),
                RejectReasonName(rj.reason).c_str(), rj.detail.c_str());
  for (const Rejection& rj : r.discarded)
    std::printf("  discarded at (%.1f, %.1f): %s: %s\n", rj.where.x(), rj.where.y(),
                RejectReasonName(rj.reason).c_str(), rj.detail.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::string(argv[1]) == "--one") return ShowOne(argc, argv);
  const int trials = argc > 1 ? std::atoi(argv[1]) : 8;
  if (trials < 1) {
    std::fprintf(stderr, "usage: bench_targets_design_sweep [renders per cell >= 1]\n");
    return 1;
  }
  std::printf(
      "%d renders per cell; RMS error per coordinate [px] (measured/rendered) median |e|/sigma\n",
      trials);
  std::map<std::string, int> misses;
  // Summary per design: by size band (8-12, 20-35, 60-150 px) and blur, both geometries.
  std::map<std::string, testing::CentreErrors> bands;
  auto band_of = [](double size) { return size <= 12 ? "8-12" : size <= 35 ? "20-35" : "60-150"; };
  for (const Geometry& g : kSweepGeometries) {
    for (const testing::DesignCase& dc : testing::DesignCases()) {
      std::printf("\n%s, %s\n  size px |", CircleDesignName(dc.design).c_str(), g.name);
      for (double b : kSweepBlurs) std::printf("      blur %.1f px       |", b);
      std::printf("\n");
      for (double size : kSweepSizes) {
        std::printf("  %7.0f |", size);
        for (double blur : kSweepBlurs) {
          testing::CentreErrors e;
          for (int t = 0; t < trials; ++t) {
            testing::DesignShotSpec s;
            s.design = dc.design;
            s.centre_px = size;
            s.tilt_deg = g.tilt_deg;
            s.off_axis_deg = g.off_axis_deg;
            s.blur_px = blur;
            s.seed = 1000 * t + static_cast<unsigned>(size) + static_cast<unsigned>(100 * blur);
            const testing::DesignShot shot = testing::RenderDesignShot(s);
            ++e.rendered;
            Eigen::Vector2d err;
            Eigen::Matrix2d cov;
            std::string why;
            if (MeasureShot(shot, &err, &cov, &why)) {
              e.Add(err, cov);
            } else {
              char key[96];
              std::snprintf(key, sizeof(key),
                            "%s, %s, %.0f px, blur %.1f: ", CircleDesignName(dc.design).c_str(),
                            g.name, size, blur);
              ++misses[key + why];
            }
          }
          std::printf(" %.4f (%2d/%2d) %4.2f |", e.Rms(), e.measured(), e.rendered, e.MedianZ());
          char key[64];
          std::snprintf(key, sizeof(key), "%-12s %-6s px, blur %.1f",
                        CircleDesignName(dc.design).c_str(), band_of(size), blur);
          bands[key].Add(e);
        }
        std::printf("\n");
        std::fflush(stdout);
      }
    }
  }
  std::printf(
      "\nby design, size band and blur (both geometries): RMS [px] (measured/rendered) median "
      "|e|/sigma\n");
  for (const auto& b : bands)
    std::printf("  %s: %.4f (%3d/%3d) %4.2f\n", b.first.c_str(), b.second.Rms(),
                b.second.measured(), b.second.rendered, b.second.MedianZ());
  std::printf("\nmisses:\n");
  for (const auto& m : misses) std::printf("  %dx %s\n", m.second, m.first.c_str());
  return 0;
}
