// A UAV photo whose position prior carries the flight log's attitude starts
// from it (GNSS centre + attitude) in BuildScene; a prior without a usable
// attitude (variance 1e6 or 0, beyond attitude_prior_max_sigma, not a unit
// quaternion), or a fixed camera's, leaves the photo to be oriented as before.
#include <cmath>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/epoch_collector.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr double kDeg = M_PI / 180.0;

CollectedImage Photo(const std::string& camera, StampNs stamp) {
  CollectedImage im;
  im.camera = camera;
  im.frame_id = camera + "_optical";
  im.stamp = stamp;
  im.key = ImageKey(camera, stamp);
  return im;
}

PositionPrior Prior(StampNs stamp, const Eigen::Vector3d& position, const Eigen::Quaterniond& q,
                    double sigma) {
  PositionPrior p;
  p.stamp = stamp;
  p.position = position;
  p.covariance = Eigen::Matrix3d::Identity() * 0.03 * 0.03;
  p.site_from_optical = q;
  p.attitude_variance = Eigen::Vector3d::Constant(sigma * sigma);
  return p;
}

struct Built {
  Scene scene;
  const Image& Of(const std::string& key) const { return scene.images.at(scene.FindImage(key)); }
};

// Looking down (optical z along -z of site), heading 30 deg.
const Eigen::Quaterniond kNadir =
    Eigen::Quaterniond(Eigen::AngleAxisd(30 * kDeg, Eigen::Vector3d::UnitZ()) *
                       Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));

Built Build(const std::vector<std::pair<CollectedImage, PositionPrior>>& photos,
            const BuildSceneOptions& options) {
  CollectedEpoch epoch;
  std::map<std::string, camera::CameraModel> models;
  for (const auto& [im, prior] : photos) {
    epoch.images[im.key] = im;
    epoch.priors.push_back(prior);
    models[im.camera] = camera::CameraModel();
  }
  return {BuildScene(epoch, models, EpochStore(), io::TargetList(), options).scene};
}

TEST(AttitudePrior, AUavPhotoStartsFromTheFlightLogsAttitude) {
  const CollectedImage a = Photo("uav", MakeStamp(100, 0)), b = Photo("uav", MakeStamp(102, 0));
  const Eigen::Vector3d pa(10, 20, 80), pb(30, 20, 81);
  BuildSceneOptions options;
  const Built built = Build({{a, Prior(a.stamp, pa, kNadir, 0.3 * kDeg)},
                             {b, Prior(b.stamp, pb, Eigen::Quaterniond::Identity(), 1e3)}},
                            options);
  const Image& ia = built.Of(a.key);
  ASSERT_TRUE(ia.exterior_known);
  EXPECT_TRUE(ia.attitude_from_prior);
  const Rigid3 site_from_optical = ia.exterior.SiteFromOptical();
  EXPECT_LT(site_from_optical.rotation.angularDistance(kNadir), 1e-9);
  EXPECT_LT((site_from_optical.translation - pa).norm(), 1e-9);
  EXPECT_LT((ia.exterior.position - pa).norm(), 1e-9);
  // Variance 1e6 (no attitude in the log, as a NavSatFix-only prior): as before.
  const Image& ib = built.Of(b.key);
  EXPECT_FALSE(ib.exterior_known);
  EXPECT_FALSE(ib.attitude_from_prior);
  ASSERT_TRUE(ib.position_prior.has_value());
}

TEST(AttitudePrior, AnAttitudeThatCannotBeUsedIsIgnored) {
  const CollectedImage a = Photo("uav", MakeStamp(100, 0)), b = Photo("uav", MakeStamp(102, 0)),
                       c = Photo("fixed_cam_1", MakeStamp(104, 0)),
                       d = Photo("uav", MakeStamp(106, 0));
  BuildSceneOptions options;  // attitude_prior_max_sigma 5 deg
  options.min_images = 1;
  const Built built = Build(
      {{a, Prior(a.stamp, Eigen::Vector3d(0, 0, 80), kNadir, 6.0 * kDeg)},  // beyond the limit
       {b, Prior(b.stamp, Eigen::Vector3d(9, 0, 80), Eigen::Quaterniond(0, 0, 0, 0),
                 0.1 * kDeg)},                                                // not a rotation
       {c, Prior(c.stamp, Eigen::Vector3d(0, -90, 30), kNadir, 0.1 * kDeg)},  // a fixed camera
       {d, Prior(d.stamp, Eigen::Vector3d(18, 0, 80), Eigen::Quaterniond::Identity(),
                 0.0)}},  // all zero: unknown
      options);
  for (const std::string& key : {a.key, b.key, c.key, d.key}) {
    EXPECT_FALSE(built.Of(key).exterior_known) << key;
    EXPECT_FALSE(built.Of(key).attitude_from_prior) << key;
  }
  // 0 turns the attitudes off.
  options.attitude_prior_max_sigma = 0.0;
  const Built off =
      Build({{a, Prior(a.stamp, Eigen::Vector3d(0, 0, 80), kNadir, 0.1 * kDeg)}}, options);
  EXPECT_FALSE(off.Of(a.key).exterior_known);
  options.attitude_prior_max_sigma = -1.0;
  const auto build = [&]() {
    Build({{a, Prior(a.stamp, Eigen::Vector3d(0, 0, 80), kNadir, 0.1 * kDeg)}}, options);
  };
  EXPECT_THROW(build(), ConfigError);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
