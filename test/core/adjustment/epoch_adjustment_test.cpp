// AdjustEpoch on a UAV strip like the demo site's (1280 x 960 px, c 8.8 mm,
// 60 m above ground, GSD 3.3 cm): photos oriented from a GNSS prior and the
// few tags they see (control tags 4 and 5 at the strip's ends, monitoring
// tags known only approximately, 0.3 m), circles named by projection, and
// the monitoring points' displacement between two epochs against the truth.
// A wrong name is caught by the residual test; ambiguity leaves circles
// unnamed.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/adjustment/epochs.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {
namespace {

double Ground(double /*x*/, double y) { return 0.25 * y; }

struct TargetTruth {
  std::string id, family;
  PointRole role;
  Eigen::Vector3d position;  // epoch 0
};

std::vector<TargetTruth> Targets() {
  struct Row {
    const char* family;
    int id;
    PointRole role;
    double x, y;
  };
  const Row rows[] = {{"tag36h11", 4, PointRole::kControl, 100, 30},
                      {"tag36h11", 5, PointRole::kControl, 100, 128},
                      {"circle", 3, PointRole::kCheck, 84, 34},
                      {"tag36h11", 10, PointRole::kMonitoring, 100, 80},
                      {"tag36h11", 11, PointRole::kMonitoring, 90, 96},
                      {"tag36h11", 12, PointRole::kMonitoring, 108, 62},
                      {"circle", 10, PointRole::kMonitoring, 86, 70},
                      {"circle", 11, PointRole::kMonitoring, 114, 92},
                      {"circle", 12, PointRole::kMonitoring, 100, 54},
                      {"circle", 13, PointRole::kMonitoring, 104, 108},
                      {"circle", 14, PointRole::kControl, 116, 44}};
  std::vector<TargetTruth> out;
  for (const Row& r : rows)
    out.push_back({std::string(r.family) + "/" + std::to_string(r.id), r.family, r.role,
                   Eigen::Vector3d(r.x, r.y, Ground(r.x, r.y) + 1.5)});
  // A denser net of circles on the body (every 12 m) and two control circles
  // half-way along the strip.
  int id = 20;
  for (double y = 42.0; y < 125.0; y += 12.0)
    for (double x : {92.0, 110.0}) {
      const double xx = x + (static_cast<int>(y) % 24 == 18 ? 3.0 : 0.0);
      out.push_back({"circle/" + std::to_string(id++), "circle", PointRole::kMonitoring,
                     Eigen::Vector3d(xx, y, Ground(xx, y) + 0.5)});
    }
  for (const auto& [x, y] : {std::pair<double, double>{81, 86}, {119, 100}})
    out.push_back({"circle/" + std::to_string(id++), "circle", PointRole::kControl,
                   Eigen::Vector3d(x, y, Ground(x, y) + 0.5)});
  return out;
}

Eigen::Vector3d Motion(const TargetTruth& t, int epoch) {
  if (t.role != PointRole::kMonitoring) return Eigen::Vector3d::Zero();
  return epoch * Eigen::Vector3d(0.0, -0.095, -0.03);
}

struct Epoch {
  Scene scene;
  std::vector<UnidentifiedObservation> unidentified;
  std::vector<std::string> unidentified_truth;  // the circle each unidentified observation is
  std::vector<ListedTarget> listed;
  std::vector<camera::ExteriorOrientation> true_poses;
};

// The same survey (control, approximate monitoring coordinates) in every
// epoch; photos, GNSS and image noise from `seed`.
Epoch MakeEpoch(int epoch, unsigned seed) {
  std::mt19937 rng(seed), list_rng(99);
  std::normal_distribution<double> n01(0.0, 1.0);
  Epoch e;
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 8.8;
  interior[camera::kK1] = -1.1e-3;
  const camera::CameraModel model(camera::Sensor{1280, 960, 0.0048},
                                  camera::DistortionModel::kRadial, interior);
  e.scene.cameras.push_back({"uav", model});
  const std::vector<TargetTruth> truth = Targets();
  std::map<std::string, Eigen::Vector3d> now;
  for (const TargetTruth& t : truth) now[t.id] = t.position + Motion(t, epoch);
  // The list: survey (1 cm) for control / check, hand-held GNSS (0.3 m) for monitoring.
  for (const TargetTruth& t : truth) {
    ListedTarget l;
    l.id = t.id;
    l.family = t.family;
    l.role = t.role;
    if (t.role == PointRole::kMonitoring) {
      l.position = t.position + 0.3 * Eigen::Vector3d(n01(list_rng), n01(list_rng), n01(list_rng));
      l.position_sigma = 0.3;
    } else {
      l.position = t.position + 0.01 * Eigen::Vector3d(n01(list_rng), n01(list_rng), n01(list_rng));
      l.position_sigma = 0.01;
      l.surveyed = l.position;
      l.surveyed_covariance = Eigen::Matrix3d::Identity() * 1e-4;
    }
    e.listed.push_back(l);
  }
  // Tags are identified: points of the scene.
  for (const TargetTruth& t : truth) {
    if (t.family == "circle") continue;
    const ListedTarget& l = *std::find_if(e.listed.begin(), e.listed.end(),
                                          [&](const ListedTarget& x) { return x.id == t.id; });
    ObjectPoint p;
    p.id = t.id;
    p.role = t.role;
    p.position_known = false;
    if (l.surveyed) {
      p.surveyed = l.surveyed;
      p.surveyed_covariance = l.surveyed_covariance;
    } else {
      p.approximate = l.position;
    }
    e.scene.points.push_back(p);
  }
  // Nine photos along the strip x = 100, y 40..122, 60 m above the middle.
  for (int k = 0; k < 9; ++k) {
    Image im;
    im.name = "uav@" + std::to_string(k);
    im.camera = 0;
    im.stamp = 2.0 * k;
    camera::ExteriorOrientation pose;
    pose.position = Eigen::Vector3d(100.0 + 0.3 * n01(rng), 40.0 + 10.25 * k + 0.3 * n01(rng),
                                    Ground(100, 81) + 60.0);
    const double a = 0.5 * M_PI / 180.0;
    pose.angles.theta = a * n01(rng);
    pose.angles.phi = a * n01(rng);
    pose.angles.kappa = a * n01(rng);
    e.true_poses.push_back(pose);
    im.exterior_known = false;
    im.position_prior =
        pose.position + Eigen::Vector3d(0.03 * n01(rng), 0.03 * n01(rng), 0.05 * n01(rng));
    im.position_prior_covariance =
        Eigen::Vector3d(0.03 * 0.03, 0.03 * 0.03, 0.05 * 0.05).asDiagonal();
    e.scene.images.push_back(im);
    for (const TargetTruth& t : truth) {
      Eigen::Vector2d px;
      if (!model.Project(pose, now[t.id], &px) || px.x() < 15 || px.y() < 15 || px.x() > 1264 ||
          px.y() > 944)
        continue;
      px += 0.1 * Eigen::Vector2d(n01(rng), n01(rng));
      const Eigen::Matrix2d cov = Eigen::Matrix2d::Identity() * 0.01;
      if (t.family == "circle") {
        e.unidentified.push_back({k, "circle", px, cov});
        e.unidentified_truth.push_back(t.id);
      } else {
        Observation o;
        o.image = k;
        o.point = e.scene.FindPoint(t.id);
        o.pixel = px;
        o.covariance = cov;
        e.scene.observations.push_back(o);
      }
    }
  }
  return e;
}

EpochAdjustmentOptions Defaults() {
  EpochAdjustmentOptions o;
  o.adjustment.min_control_points = 3;
  o.adjustment.min_observations_with_prior = 2;
  return o;
}

TEST(EpochAdjustment, NamesCirclesInGnssPhotosAndMeasuresDisplacements) {
  std::vector<EpochPoints> points;
  std::vector<Epoch> epochs;
  for (int epoch = 0; epoch < 2; ++epoch) {
    Epoch e = MakeEpoch(epoch, 40 + epoch);
    // Without the approximate orientation and the naming, the photos are dropped.
    EpochAdjustmentOptions plain = Defaults();
    plain.orient_from_approximate = false;
    plain.name_unidentified = false;
    const EpochAdjustmentResult before = AdjustEpoch(e.scene, e.unidentified, e.listed, plain);
    std::printf("epoch %d without naming: %s; %s\n", epoch, before.photos.Brief().c_str(),
                before.summary.reason.c_str());
    EXPECT_LT(before.photos.kept, 5);

    const EpochAdjustmentResult r = AdjustEpoch(e.scene, e.unidentified, e.listed, Defaults());
    std::printf("epoch %d: %s; %s; %d oriented from approximate points; %s\n", epoch,
                r.photos.Brief().c_str(), r.naming.Brief().c_str(), r.oriented_from_approximate,
                r.summary.BriefReport().c_str());
    ASSERT_TRUE(r.summary.IsSolutionUsable()) << r.summary.reason;
    EXPECT_EQ(r.photos.total, 9);
    EXPECT_GE(r.photos.kept, 8) << r.pruned.Summary();
    EXPECT_TRUE(r.rejected_names.empty());
    // Every name given is the truth; nearly all circles are named.
    ASSERT_GT(r.naming.considered, 0);
    EXPECT_EQ(r.naming.considered + r.naming.not_oriented, static_cast<int>(e.unidentified.size()));
    EXPECT_GE(r.naming.named, 0.9 * r.naming.considered) << r.naming.Brief();
    for (const auto& photo : r.scene.images) {
      const int k = std::stoi(photo.name.substr(4));
      for (const Observation& o : r.scene.observations) {
        if (o.image != r.scene.FindImage(photo.name) ||
            r.scene.points[o.point].id.rfind("circle", 0) != 0)
          continue;
        bool found = false;
        for (size_t u = 0; u < e.unidentified.size(); ++u)
          if (e.unidentified[u].image == k && (e.unidentified[u].pixel - o.pixel).norm() < 1e-9)
            found = e.unidentified_truth[u] == r.scene.points[o.point].id;
        EXPECT_TRUE(found) << r.scene.points[o.point].id << " in " << photo.name
                           << " is a wrong name";
      }
    }
    // Camera positions and attitudes against the truth.
    double worst_pos = 0.0, worst_att = 0.0;
    for (const Image& im : r.scene.images) {
      const camera::ExteriorOrientation& t = e.true_poses[std::stoi(im.name.substr(4))];
      worst_pos = std::max(worst_pos, (im.exterior.position - t.position).norm());
      const Eigen::Quaterniond dq =
          im.exterior.SiteFromOptical().rotation.inverse() * t.SiteFromOptical().rotation;
      worst_att = std::max(worst_att, Eigen::AngleAxisd(dq).angle());
    }
    std::printf("epoch %d: worst photo position error %.3f m, attitude %.2f mrad\n", epoch,
                worst_pos, worst_att * 1e3);
    EXPECT_LT(worst_pos, 0.10);
    EXPECT_LT(worst_att, 5e-3);
    // Adjusted monitoring / check points within 3 sigma of the truth.
    int n = 0, within = 0;
    const std::vector<TargetTruth> all = Targets();
    for (size_t j = 0; j < r.scene.points.size(); ++j) {
      const ObjectPoint& p = r.scene.points[j];
      if (p.role == PointRole::kControl) continue;
      const TargetTruth& t =
          *std::find_if(all.begin(), all.end(), [&](const TargetTruth& x) { return x.id == p.id; });
      const Eigen::Vector3d err = p.position - (t.position + Motion(t, epoch));
      const double m2 = err.transpose() * r.summary.precision.point_covariance[j].inverse() * err;
      ++n;
      within += m2 <= 14.16 ? 1 : 0;  // chi^2(3) at 99.73 % (the 3-D "3 sigma")
    }
    std::printf("epoch %d: %d of %d monitoring / check points within 3 sigma\n", epoch, within, n);
    EXPECT_GE(n, 15);
    EXPECT_EQ(within, n);
    points.push_back(EpochPointsFromSolution(r.scene, r.summary, epoch, 100.0 * epoch));
    epochs.push_back(e);
  }
  const EpochComparison cmp = CompareEpochs(points[0], points[1]);
  ASSERT_TRUE(cmp.success) << cmp.message;
  std::printf("co-registration rms %.1f mm, %zu stable used, %zu rejected\n",
              cmp.coregistration_rms * 1e3, cmp.stable_points_used.size(),
              cmp.stable_points_rejected.size());
  double ss = 0.0;
  int n = 0, within3 = 0;
  for (const Displacement& d : cmp.displacements) {
    const Eigen::Vector3d err = d.displacement - Eigen::Vector3d(0.0, -0.095, -0.03);
    std::printf("  %s: error %.1f %.1f %.1f mm, sigma %.1f mm\n", d.id.c_str(), err.x() * 1e3,
                err.y() * 1e3, err.z() * 1e3, std::sqrt(d.covariance.trace()) * 1e3);
    ss += err.squaredNorm();
    within3 += err.dot(d.covariance.inverse() * err) <= 14.16 ? 1 : 0;
    ++n;
  }
  const double rms = std::sqrt(ss / n);
  std::printf("  (%d of %d displacements within 3 sigma)\n", within3, n);
  EXPECT_EQ(within3, n);
  std::printf("UAV strip at 60 m: displacement RMS vs truth %.1f mm over %d monitoring points\n",
              rms * 1e3, n);
  EXPECT_GE(n, 15);
  // One nadir strip, no tie points: the heights are weak (sigma 4-9 cm); the
  // issue's 2 cm needs more photos or tie points (see doc/nodes/bundle_adjuster.md).
  EXPECT_LT(rms, 0.10);
}

TEST(EpochAdjustment, WrongNameIsCaughtAndReported) {
  Epoch e = MakeEpoch(0, 40);
  // In one photo, circle/12 is replaced by a spot 15 px away (a leaf, a stone):
  // inside the naming gate, so it gets the name, but it is not the target.
  int moved = -1;
  for (size_t u = 0; u < e.unidentified.size(); ++u) {
    if (e.unidentified_truth[u] == "circle/12" && moved < 0) {
      e.unidentified[u].pixel += Eigen::Vector2d(12.0, -9.0);
      moved = static_cast<int>(u);
    }
  }
  ASSERT_GE(moved, 0);
  const EpochAdjustmentResult r = AdjustEpoch(e.scene, e.unidentified, e.listed, Defaults());
  std::printf("%s\n", r.summary.reason.c_str());
  ASSERT_TRUE(r.summary.IsSolutionUsable()) << r.summary.reason;
  ASSERT_EQ(r.rejected_names.size(), 1u);
  EXPECT_NE(r.rejected_names[0].find("circle/12"), std::string::npos) << r.rejected_names[0];
  EXPECT_NE(r.rejected_names[0].find("uav@" + std::to_string(e.unidentified[moved].image)),
            std::string::npos);
  EXPECT_NE(r.summary.reason.find("rejected by the residual test"), std::string::npos);
  // The bad observation is gone from the adjusted scene.
  for (const Observation& o : r.scene.observations)
    EXPECT_GT((o.pixel - e.unidentified[moved].pixel).norm(), 1e-9);
}

TEST(EpochAdjustment, AmbiguousCirclesStayUnnamed) {
  Epoch e = MakeEpoch(0, 40);
  Scene scene = e.scene;
  // Orient the photos at the truth, then add a second spot 5 px from every
  // circle/13 observation: two candidates for one target.
  for (size_t i = 0; i < scene.images.size(); ++i) {
    scene.images[i].exterior = e.true_poses[i];
    scene.images[i].exterior_known = true;
  }
  std::vector<UnidentifiedObservation> u = e.unidentified;
  int doubled = 0;
  for (size_t k = 0; k < e.unidentified.size(); ++k) {
    if (e.unidentified_truth[k] != "circle/13") continue;
    UnidentifiedObservation extra = e.unidentified[k];
    extra.pixel += Eigen::Vector2d(5.0, 0.0);
    u.push_back(extra);
    ++doubled;
  }
  ASSERT_GT(doubled, 0);
  Scene plain_scene = scene;
  const NamingReport plain = NameUnidentified(&plain_scene, e.unidentified, e.listed);
  EXPECT_GT(plain_scene.FindPoint("circle/13"), -1);
  const NamingReport r = NameUnidentified(&scene, u, e.listed);
  std::printf("%s\n", r.Brief().c_str());
  EXPECT_EQ(r.ambiguous, plain.ambiguous + 2 * doubled);
  EXPECT_EQ(r.named, plain.named - doubled);
  EXPECT_EQ(scene.FindPoint("circle/13"), -1);
  EXPECT_EQ(r.notes.size(), static_cast<size_t>(plain.ambiguous + 2 * doubled));
  // Options are checked, naming the field.
  NamingOptions bad;
  bad.ambiguity_factor = 0.5;
  try {
    NameUnidentified(&scene, u, e.listed, bad);
    ADD_FAILURE() << "no error";
  } catch (const Error& err) {
    EXPECT_NE(std::string(err.what()).find("ambiguity_factor"), std::string::npos) << err.what();
  }
}

TEST(EpochAdjustment, PhotosSeeingOneKnownPointBorrowTheNeighboursAttitude) {
  // The monitoring tags are known already (intersected from fixed cameras):
  // no approximate coordinates are needed; photos that see a single known
  // point take the attitude of the nearest oriented photo, tilted onto it.
  Epoch e = MakeEpoch(0, 40);
  const std::vector<TargetTruth> all = Targets();
  for (ObjectPoint& p : e.scene.points) {
    const TargetTruth& t =
        *std::find_if(all.begin(), all.end(), [&](const TargetTruth& x) { return x.id == p.id; });
    p.position = t.position;
    p.position_known = true;
    p.approximate.reset();
  }
  Scene s = e.scene;
  InitializeScene(&s);
  int before = 0, one_point = 0, no_point = 0;
  std::vector<int> known_obs(s.images.size(), 0);
  for (const Observation& o : s.observations) ++known_obs[o.image];
  for (size_t i = 0; i < s.images.size(); ++i) {
    before += s.images[i].exterior_known ? 1 : 0;
    one_point += known_obs[i] == 1 ? 1 : 0;
    // A photo that sees no known point takes the neighbour's attitude as it
    // is (tie points, when there are any, do the rest).
    no_point += known_obs[i] == 0 && !s.images[i].exterior_known ? 1 : 0;
  }
  ASSERT_GT(before, 0);
  ASSERT_GT(one_point, 0);
  std::vector<bool> flags;
  const int n = OrientFromApproximatePoints(&s, {}, &flags);
  EXPECT_EQ(n, one_point + no_point);
  for (size_t i = 0; i < s.images.size(); ++i) {
    if (!flags[i]) continue;
    const Eigen::Quaterniond dq = s.images[i].exterior.SiteFromOptical().rotation.inverse() *
                                  e.true_poses[i].SiteFromOptical().rotation;
    std::printf("%s: borrowed attitude %.1f mrad from the truth\n", s.images[i].name.c_str(),
                Eigen::AngleAxisd(dq).angle() * 1e3);
    EXPECT_LT(Eigen::AngleAxisd(dq).angle(), 0.05);  // good enough for the coarse naming gate
  }
}

TEST(EpochAdjustment, DatumFreeCovarianceLeavesTheSurveyOut) {
  // Control points held: the monitoring points' covariance loses the part the
  // control survey (1 cm here) contributes, which is common to every epoch.
  Epoch e = MakeEpoch(0, 40);
  EpochAdjustmentOptions o = Defaults();
  o.adjustment.compute_datum_free_covariance = true;
  const EpochAdjustmentResult r = AdjustEpoch(e.scene, e.unidentified, e.listed, o);
  ASSERT_TRUE(r.summary.IsSolutionUsable()) << r.summary.reason;
  const Precision& pr = r.summary.precision;
  ASSERT_EQ(pr.point_covariance_datum_free.size(), r.scene.points.size());
  int checked = 0;
  for (size_t j = 0; j < r.scene.points.size(); ++j) {
    const double full = pr.point_covariance[j].trace(),
                 free = pr.point_covariance_datum_free[j].trace();
    if (r.scene.points[j].role == PointRole::kControl) {
      EXPECT_EQ(free, 0.0) << r.scene.points[j].id;
      continue;
    }
    EXPECT_GT(free, 0.0) << r.scene.points[j].id;
    EXPECT_LT(free, full) << r.scene.points[j].id;
    ++checked;
  }
  EXPECT_GT(checked, 10);
  const EpochPoints with = EpochPointsFromSolution(r.scene, r.summary, 0, 0.0, true);
  const EpochPoints without = EpochPointsFromSolution(r.scene, r.summary, 0, 0.0, false);
  const std::string id = "tag36h11/10";
  ASSERT_TRUE(with.points.count(id));
  EXPECT_LT(with.points.at(id).covariance.trace(), without.points.at(id).covariance.trace());
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
