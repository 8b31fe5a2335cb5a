// The truth checks of the former UAV replay rostests (uav_graph_replay: two
// fixed cameras and a UAV strip; uav_block_replay: the UAV alone,
// self-calibrated, tie points from the sequence matcher), now on the output
// bag of process_bag (process_bag_uav_test.cpp): the bundle adjuster's
// outputs (/bundle_adjuster/solution, /bundle_adjuster/displacements)
// against the simulator's truth: UAV photos kept per epoch, their positions
// and attitudes, every adjusted target coordinate within 3 sigma, the
// displacement of the monitoring targets the kept UAV photos see, and
// (check_interior) the self-calibrated c, principal point and k1. The
// tolerances are those of the rostests; the numbers are printed.
#pragma once

#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <string>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <Eigen/Geometry>

#include "slope_monitor/AdjustmentSolution.h"
#include "slope_monitor/PointDisplacementArray.h"
#include "slope_monitor/TiePointArray.h"
#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/sim/truth.h"

namespace slope_monitor {
namespace uav_replay {

struct Tolerances {
  int min_uav_photos = 5;                     // kept per epoch
  double max_uav_position_error = 0.15;       // [m] each kept photo vs truth
  double max_uav_attitude_error = 0.005;      // [rad] each kept photo vs truth
  double min_fraction_within_3_sigma = 0.99;  // adjusted monitoring / check targets; control apart
  double max_uav_displacement_rms = 0.02;     // [m] monitoring targets seen in kept UAV photos
  bool check_interior = false;
  double max_c_error = 0.005;                // [mm]
  double max_principal_point_error = 0.005;  // [mm]
  double max_k1_error = 2e-5;                // [mm^-2]
  // The UAV camera's name in the outputs: "" = the survey truth's (a bag
  // whose topics were renamed: the site file's name).
  std::string uav_camera;
};

// The bundle adjuster's last solution and displacements of each epoch in the output bag.
struct Outputs {
  std::map<int, slope_monitor::AdjustmentSolution> solutions;
  std::map<int, slope_monitor::PointDisplacementArray> displacements;
  int tie_point_messages = 0, tie_points = 0;
};

inline Outputs ReadOutputs(const std::string& bag_path,
                           const std::string& tie_topic = "/uav/tie_points") {
  Outputs o;
  rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (m.getTopic() == "/bundle_adjuster/solution") {
      if (const auto s = m.instantiate<slope_monitor::AdjustmentSolution>())
        o.solutions[static_cast<int>(s->epoch)] = *s;
    } else if (m.getTopic() == "/bundle_adjuster/displacements") {
      if (const auto d = m.instantiate<slope_monitor::PointDisplacementArray>())
        o.displacements[static_cast<int>(d->epoch)] = *d;
    } else if (m.getTopic() == tie_topic) {
      if (const auto t = m.instantiate<slope_monitor::TiePointArray>()) {
        ++o.tie_point_messages;
        o.tie_points += static_cast<int>(t->points.size());
      }
    }
  }
  return o;
}

inline const sim::ImageTruth* FindImage(const sim::CameraTruth& cam, double stamp) {
  for (const sim::ImageTruth& im : cam.images)
    if (std::abs(im.stamp - stamp) < 1e-3) return &im;
  return nullptr;
}

// The checks of both UAV replays (tolerances from the caller).
inline void CheckUavReplay(const Outputs& outputs, const std::string& truth_path,
                           const Tolerances& tol) {
  const int min_photos = tol.min_uav_photos;
  const double max_pos = tol.max_uav_position_error;
  const double max_att = tol.max_uav_attitude_error;
  const double min_within = tol.min_fraction_within_3_sigma;
  const double max_rms = tol.max_uav_displacement_rms;
  const bool check_interior = tol.check_interior;
  const double max_c = tol.max_c_error;
  const double max_pp = tol.max_principal_point_error;
  const double max_k1 = tol.max_k1_error;
  const sim::SurveyTruth truth = sim::SurveyTruth::Load(truth_path);

  const sim::CameraTruth* uav = nullptr;
  for (const sim::CameraTruth& c : truth.cameras)
    if (c.kind == "uav") uav = &c;
  ASSERT_NE(uav, nullptr) << "the survey has no UAV";
  const std::string uav_name = tol.uav_camera.empty() ? uav->name : tol.uav_camera;
  const auto& solutions = outputs.solutions;
  const auto& displacements = outputs.displacements;
  std::map<int, std::set<std::string>> seen_by_uav;  // epoch -> targets visible in kept UAV photos
  int coords = 0, coords_within = 0, control_coords = 0, control_within = 0;
  for (const sim::EpochTruth& ep : truth.epochs) {
    auto it = solutions.find(ep.index);
    ASSERT_NE(it, solutions.end()) << "no solution for epoch " << ep.index;
    const slope_monitor::AdjustmentSolution& s = it->second;
    ASSERT_TRUE(s.usable) << "epoch " << ep.index << ": " << s.message;
    int photos = 0;
    double worst_pos = 0.0, worst_att = 0.0;
    for (const auto& c : s.cameras) {
      if (c.camera_name != uav_name) continue;
      const sim::ImageTruth* im = FindImage(*uav, c.image_header.stamp.toSec());
      ASSERT_NE(im, nullptr) << "UAV photo at " << c.image_header.stamp << " is not in the truth";
      ++photos;
      const Eigen::Vector3d p(c.site_from_optical.position.x, c.site_from_optical.position.y,
                              c.site_from_optical.position.z);
      const Eigen::Quaterniond q(
          c.site_from_optical.orientation.w, c.site_from_optical.orientation.x,
          c.site_from_optical.orientation.y, c.site_from_optical.orientation.z);
      const double pos = (p - im->exterior.position).norm();
      const double att =
          Eigen::AngleAxisd(q.inverse() * im->exterior.SiteFromOptical().rotation).angle();
      worst_pos = std::max(worst_pos, pos);
      worst_att = std::max(worst_att, att);
      EXPECT_LT(pos, max_pos) << "UAV photo at " << im->stamp;
      EXPECT_LT(att, max_att) << "UAV photo at " << im->stamp;
      for (const std::string& key : im->visible) seen_by_uav[ep.index].insert(key);
      if (check_interior && photos == 1) {  // one interior per camera and epoch: check it once
        const auto& t = uav->model.interior();
        const auto& n = uav->nominal.interior();
        ASSERT_GE(c.distortion.size(), 1u);
        ASSERT_GE(c.interior_sigma.size(), 4u);
        const double est[4] = {c.principal_distance, c.x0, c.y0, c.distortion[0]};
        const int idx[4] = {camera::kC, camera::kX0, camera::kY0, camera::kK1};
        const double tol[4] = {max_c, max_pp, max_pp, max_k1};
        const char* name[4] = {"c [mm]", "x0 [mm]", "y0 [mm]", "k1 [mm^-2]"};
        for (int k = 0; k < 4; ++k) {
          const double err = est[k] - t[idx[k]];
          const double sigma = c.interior_sigma[idx[k]];
          std::printf(
              "  epoch %d self-calibration %-10s %.6g (truth %.6g, nominal %.6g): error %.3g, "
              "sigma %.3g (%.1f sigma)\n",
              ep.index, name[k], est[k], t[idx[k]], n[idx[k]], err, sigma,
              sigma > 0 ? std::abs(err) / sigma : 0.0);
          if (sigma == 0.0 && (idx[k] == camera::kX0 || idx[k] == camera::kY0))
            continue;  // held at nominal
          EXPECT_GT(sigma, 0.0) << name[k] << " was not self-calibrated";
          EXPECT_LT(std::abs(err), tol[k]) << "epoch " << ep.index << " " << name[k];
          // The published sigma covers the error.
          EXPECT_LE(std::abs(err), 3.0 * sigma) << "epoch " << ep.index << " " << name[k];
          // c and k1: closer to the truth than the nominal value they started
          // from. The principal point of a nadir block flown in one direction
          // trades against the attitude (sigma 5-8 um, 1-2 px): not asserted.
          if (idx[k] == camera::kC || idx[k] == camera::kK1)
            EXPECT_LT(std::abs(err), std::abs(n[idx[k]] - t[idx[k]]))
                << "epoch " << ep.index << " " << name[k];
        }
      }
    }
    int uav_images = 0;
    for (const sim::ImageTruth& im : uav->images) uav_images += im.epoch == ep.index ? 1 : 0;
    std::printf(
        "epoch %d: %d of %d UAV photos kept; worst position error %.3f m, attitude %.2f mrad; "
        "sigma0 %.2f; %s\n",
        ep.index, photos, uav_images, worst_pos, worst_att * 1e3, s.sigma0, s.message.c_str());
    EXPECT_GE(photos, min_photos) << "epoch " << ep.index;
    for (const auto& p : s.points) {
      const sim::TargetTruth* t = truth.FindTarget(p.id);
      if (t == nullptr) continue;  // tie points
      // Control points are their survey (3 cm in the simulator) nudged by the
      // images; their sigma is scaled by sigma0^2 < 1 like the rest (see
      // min_variance_factor): counted apart, printed, not asserted.
      const bool control = p.role == slope_monitor::PointEstimate::ROLE_CONTROL;
      const Eigen::Vector3d err =
          Eigen::Vector3d(p.position.x, p.position.y, p.position.z) - t->positions.at(ep.index);
      int ok = 0;
      for (int k = 0; k < 3; ++k) {
        const double sigma = std::sqrt(std::max(0.0, p.covariance[4 * k]));
        ok += std::abs(err(k)) <= 3.0 * sigma ? 1 : 0;
      }
      (control ? control_coords : coords) += 3;
      (control ? control_within : coords_within) += ok;
      if (ok < 3)
        std::printf("  epoch %d %s: error %.1f %.1f %.1f mm, sigma %.1f %.1f %.1f mm\n", ep.index,
                    p.id.c_str(), err.x() * 1e3, err.y() * 1e3, err.z() * 1e3,
                    std::sqrt(p.covariance[0]) * 1e3, std::sqrt(p.covariance[4]) * 1e3,
                    std::sqrt(p.covariance[8]) * 1e3);
    }
  }
  const double fraction = coords > 0 ? static_cast<double>(coords_within) / coords : 0.0;
  std::printf(
      "adjusted monitoring / check target coordinates within 3 sigma: %d of %d (%.3f); control: %d "
      "of %d\n",
      coords_within, coords, fraction, control_within, control_coords);
  EXPECT_GE(fraction, min_within);
  // Control coordinates: their error is the survey's (3 cm / 1 cm), which the
  // published sigma must cover (min_variance_factor 1 keeps sigma0 < 1 from
  // shrinking it).
  ASSERT_GT(control_coords, 0);
  EXPECT_GE(static_cast<double>(control_within) / control_coords, min_within);

  double ss_uav = 0.0, ss_all = 0.0;
  int n_uav = 0, n_all = 0;
  for (const auto& [epoch, msg] : displacements) {
    for (const auto& d : msg.displacements) {
      const sim::TargetTruth* t = truth.FindTarget(d.point_id);
      if (t == nullptr || t->role != io::TargetRole::kMonitoring) continue;
      const Eigen::Vector3d truth_d = t->positions.at(epoch) - t->positions.at(0);
      const Eigen::Vector3d err =
          Eigen::Vector3d(d.displacement.x, d.displacement.y, d.displacement.z) - truth_d;
      const bool by_uav = seen_by_uav[epoch].count(d.point_id) > 0;
      std::printf("  epoch %d %-12s |d| %6.1f mm, error %5.1f mm%s\n", epoch, d.point_id.c_str(),
                  truth_d.norm() * 1e3, err.norm() * 1e3, by_uav ? " (seen by UAV photos)" : "");
      ss_all += err.squaredNorm();
      ++n_all;
      if (by_uav) {
        ss_uav += err.squaredNorm();
        ++n_uav;
      }
    }
  }
  ASSERT_GT(n_uav, 0) << "no monitoring displacement of a target seen by a kept UAV photo";
  const double rms_uav = std::sqrt(ss_uav / n_uav);
  std::printf(
      "monitoring displacements vs truth: RMS %.2f mm over %d (targets seen by UAV photos), %.2f "
      "mm over all %d\n",
      rms_uav * 1e3, n_uav, std::sqrt(ss_all / n_all) * 1e3, n_all);
  EXPECT_LT(rms_uav, max_rms);
}

}  // namespace uav_replay
}  // namespace slope_monitor
