// dense::EpochPhotoCollector driven by hand-made message sequences: the
// solution before or after its photos, a missing photo named, release after
// use, the memory limit with a named drop, the live time-out.
#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/dense/epoch_photos.h"

namespace slope_monitor {
namespace dense {
namespace {

constexpr int64_t kSecond = 1000000000;

camera::CameraModel EpochPhotosModel() {
  std::array<double, camera::kNumInterior> interior{};
  interior[camera::kC] = 8.0;  // [mm]
  return camera::CameraModel(camera::Sensor{64, 48, 0.01}, camera::DistortionModel::kRadial,
                             interior);
}

// A 64 x 48 BGR photo: 9216 bytes.
Photo MakePhoto(const std::string& camera, int64_t stamp_s) {
  return {camera, stamp_s * kSecond, cv::Mat(48, 64, CV_8UC3, cv::Scalar(10, 20, 30))};
}

PhotoOrientation Oriented(const std::string& camera, int64_t stamp_s) {
  PhotoOrientation o;
  o.camera = camera;
  o.stamp_ns = stamp_s * kSecond;
  o.principal_distance = 8.5;
  o.x0 = 0.02;
  o.distortion = {1e-4};
  o.pose.position = Eigen::Vector3d(1.0, 2.0, 30.0);
  return o;
}

// A solution of `epoch` orienting the given UAV photos and one fixed camera's.
EpochOrientations Solution(int epoch, const std::vector<int64_t>& uav_stamps_s) {
  EpochOrientations s;
  s.epoch = epoch;
  s.stamp_ns = (1000 + epoch) * kSecond;
  s.adjusted_points = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(5, 0, 1)};
  for (int64_t t : uav_stamps_s) s.photos.push_back(Oriented("uav", t));
  s.photos.push_back(Oriented("fixed_cam_1", uav_stamps_s.front()));  // not a surface camera
  return s;
}

PhotoCollectorOptions EpochPhotosOptions() {
  PhotoCollectorOptions o;  // the defaults: uav_cameras {"uav"}, no stereo pairs
  return o;
}

TEST(EpochPhotoCollector, SolutionAfterItsPhotosIsCompleteAtOnce) {
  EpochPhotoCollector c(EpochPhotosOptions());
  c.SetCamera("uav", EpochPhotosModel());
  for (int t : {10, 12, 14}) EXPECT_TRUE(c.AddPhoto(MakePhoto("uav", t), t).empty());
  EXPECT_TRUE(c.AddPhoto(MakePhoto("fixed_cam_1", 10), 10).empty());
  EXPECT_EQ(c.photos_held(), 3);  // the fixed camera is not a surface camera: not kept
  const std::vector<PhotoEpoch> done = c.AddSolution(Solution(1, {10, 12, 14}), 20.0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].reason, "all photos");
  EXPECT_TRUE(done[0].missing.empty());
  EXPECT_TRUE(done[0].no_surface.empty());
  EXPECT_EQ(done[0].stamp_ns, 1001 * kSecond);
  ASSERT_EQ(done[0].input.images.size(), 3u);
  const EpochImage& im = done[0].input.images[1];
  EXPECT_EQ(im.image.name, "uav@12.000");
  EXPECT_EQ(im.kind, ImageKind::kUav);
  EXPECT_TRUE(im.image.oriented);
  // The adjusted interior orientation replaces camera_info's, the sensor stays.
  EXPECT_DOUBLE_EQ(im.image.camera.interior()[camera::kC], 8.5);
  EXPECT_DOUBLE_EQ(im.image.camera.interior()[camera::kX0], 0.02);
  EXPECT_DOUBLE_EQ(im.image.camera.interior()[camera::kK1], 1e-4);
  EXPECT_EQ(im.image.camera.sensor().width, 64);
  EXPECT_EQ(im.image.pose.position, Eigen::Vector3d(1.0, 2.0, 30.0));
  EXPECT_EQ(done[0].input.adjusted_points.size(), 2u);
  // Released after use.
  EXPECT_EQ(c.photos_held(), 0);
  EXPECT_DOUBLE_EQ(c.megabytes_held(), 0.0);
}

TEST(EpochPhotoCollector, SolutionBeforeItsPhotosWaitsForTheLastOne) {
  EpochPhotoCollector c(EpochPhotosOptions());
  c.SetCamera("uav", EpochPhotosModel());
  EXPECT_TRUE(c.AddPhoto(MakePhoto("uav", 10), 10).empty());
  EXPECT_TRUE(c.AddSolution(Solution(1, {10, 12, 14}), 11.0).empty());
  EXPECT_EQ(c.solutions_waiting(), 1);
  EXPECT_TRUE(c.AddPhoto(MakePhoto("uav", 12), 12).empty());
  EXPECT_TRUE(c.Poll(30.0).empty());  // 19 s < photo_wait
  const std::vector<PhotoEpoch> done = c.AddPhoto(MakePhoto("uav", 14), 31);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].input.images.size(), 3u);
  EXPECT_TRUE(done[0].missing.empty());
  EXPECT_EQ(c.solutions_waiting(), 0);
  EXPECT_EQ(c.photos_held(), 0);
}

TEST(EpochPhotoCollector, AMissingPhotoIsNamedWhenALaterOneComes) {
  EpochPhotoCollector c(EpochPhotosOptions());
  c.SetCamera("uav", EpochPhotosModel());
  c.AddPhoto(MakePhoto("uav", 10), 10);
  c.AddPhoto(MakePhoto("uav", 14), 14);  // uav@12 was lost in transport
  const std::vector<PhotoEpoch> done = c.AddSolution(Solution(1, {10, 12, 14}), 20.0);
  ASSERT_EQ(done.size(), 1u);  // no waiting: the camera's photos come in order
  EXPECT_EQ(done[0].input.images.size(), 2u);
  ASSERT_EQ(done[0].missing.size(), 1u);
  EXPECT_EQ(done[0].missing[0], "uav@12.000: not received (a later photo of 'uav' came)");
}

TEST(EpochPhotoCollector, TimeOutAndEndOfInputNameWhatDidNotCome) {
  EpochPhotoCollector c(EpochPhotosOptions());
  c.SetCamera("uav", EpochPhotosModel());
  c.AddPhoto(MakePhoto("uav", 10), 10);
  c.AddPhoto(MakePhoto("uav", 12), 12);
  EXPECT_TRUE(c.AddSolution(Solution(1, {10, 12, 14}), 20.0).empty());
  EXPECT_TRUE(c.Poll(79.9).empty());
  std::vector<PhotoEpoch> done = c.Poll(80.0);  // photo_wait 60 s after the solution
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].reason, "time-out after 60 s");
  EXPECT_EQ(done[0].input.images.size(), 2u);
  ASSERT_EQ(done[0].missing.size(), 1u);
  EXPECT_EQ(done[0].missing[0], "uav@14.000: not received (time-out after 60 s)");

  c.AddPhoto(MakePhoto("uav", 20), 90);
  EXPECT_TRUE(c.AddSolution(Solution(2, {20, 22}), 95.0).empty());
  done = c.Finish();
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].reason, "end of input");
  EXPECT_EQ(done[0].missing, std::vector<std::string>{"uav@22.000: not received (end of input)"});
  // One photo: nothing to measure, and it says why.
  EXPECT_EQ(done[0].no_surface, "epoch 2: no surface (1 UAV photo(s), no stereo pair configured)");
}

TEST(EpochPhotoCollector, OlderUnusedPhotosAreReleasedWithTheEpoch) {
  EpochPhotoCollector c(EpochPhotosOptions());
  c.SetCamera("uav", EpochPhotosModel());
  for (int t : {8, 10, 12, 30})
    c.AddPhoto(MakePhoto("uav", t), t);  // 8: a test shot; 30: next epoch
  ASSERT_EQ(c.AddSolution(Solution(1, {10, 12}), 31.0).size(), 1u);
  EXPECT_EQ(c.photos_held(), 1);  // uav@30 waits for its solution
  const std::vector<PhotoEpoch> next = c.AddSolution(Solution(2, {30}), 40.0);
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].input.images.size(), 1u);
  EXPECT_EQ(c.photos_held(), 0);
}

TEST(EpochPhotoCollector, MissingCameraInfoIsNamed) {
  EpochPhotoCollector c(EpochPhotosOptions());
  c.AddPhoto(MakePhoto("uav", 10), 10);
  c.AddPhoto(MakePhoto("uav", 12), 12);
  const std::vector<PhotoEpoch> done = c.AddSolution(Solution(1, {10, 12}), 20.0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_TRUE(done[0].input.images.empty());
  ASSERT_EQ(done[0].missing.size(), 2u);
  EXPECT_EQ(done[0].missing[0], "uav@10.000: no camera_info of 'uav' received");
}

TEST(EpochPhotoCollector, MemoryLimitDropsTheOldestUnnamedPhotoAndSaysSo) {
  PhotoCollectorOptions o = EpochPhotosOptions();
  o.max_photos = 3;
  EpochPhotoCollector c(o);
  c.SetCamera("uav", EpochPhotosModel());
  // A solution waits for photos 10 and 11: they are protected.
  EXPECT_TRUE(c.AddSolution(Solution(1, {10, 11, 13}), 1.0).empty());
  c.AddPhoto(MakePhoto("uav", 10), 10);
  c.AddPhoto(MakePhoto("uav", 11), 11);
  c.AddPhoto(MakePhoto("uav", 12), 12);
  EXPECT_TRUE(c.TakeDropped().empty());
  std::vector<PhotoEpoch> done = c.AddPhoto(MakePhoto("uav", 13), 13);  // 4 > 3
  const std::vector<std::string> dropped = c.TakeDropped();
  ASSERT_EQ(dropped.size(), 1u);
  EXPECT_EQ(dropped[0],
            "dropped photo uav@12.000 (0.0 MB): 4 photos / 0.0 MB held, limits max_photos 3, "
            "max_megabytes 1024");
  ASSERT_EQ(done.size(), 1u);  // 13 completed the epoch
  EXPECT_EQ(done[0].input.images.size(), 3u);
  EXPECT_EQ(c.photos_held(), 0);

  // Every photo named: the oldest goes, and the epoch names it.
  o.max_photos = 2;
  EpochPhotoCollector d(o);
  d.SetCamera("uav", EpochPhotosModel());
  d.AddSolution(Solution(1, {10, 11, 12}), 1.0);
  d.AddPhoto(MakePhoto("uav", 10), 10);
  d.AddPhoto(MakePhoto("uav", 11), 11);
  done = d.AddPhoto(MakePhoto("uav", 12), 12);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].missing, std::vector<std::string>{"uav@10.000: dropped at the memory limit"});
  EXPECT_EQ(d.TakeDropped().size(), 1u);

  // The megabyte limit: 9216 bytes a photo, 0.02 MB hold two.
  PhotoCollectorOptions m = EpochPhotosOptions();
  m.max_megabytes = 0.02;
  EpochPhotoCollector e(m);
  for (int t : {1, 2, 3}) e.AddPhoto(MakePhoto("uav", t), t);
  EXPECT_EQ(e.photos_held(), 2);
  EXPECT_NEAR(e.megabytes_held(), 2 * 9216e-6, 1e-12);
  EXPECT_EQ(e.TakeDropped().front().rfind("dropped photo uav@1.000", 0), 0u);
}

TEST(EpochPhotoCollector, StereoPairsMakeFixedCamerasSurfaceCameras) {
  PhotoCollectorOptions o = EpochPhotosOptions();
  o.uav_cameras = {};
  o.stereo_pairs = {{"fixed_cam_1", "fixed_cam_2"}};
  EpochPhotoCollector c(o);
  c.SetCamera("fixed_cam_1", EpochPhotosModel());
  c.SetCamera("fixed_cam_2", EpochPhotosModel());
  EXPECT_TRUE(c.Uses("fixed_cam_2"));
  EXPECT_FALSE(c.Uses("uav"));
  EpochOrientations s;
  s.epoch = 3;
  s.photos = {Oriented("fixed_cam_1", 5), Oriented("fixed_cam_2", 5), Oriented("uav", 6)};
  EXPECT_TRUE(c.AddSolution(s, 0.0).empty());
  c.AddPhoto(MakePhoto("fixed_cam_2", 5), 1);
  const std::vector<PhotoEpoch> done = c.AddPhoto(MakePhoto("fixed_cam_1", 5), 1);
  ASSERT_EQ(done.size(), 1u);
  ASSERT_EQ(done[0].input.images.size(), 2u);
  EXPECT_EQ(done[0].input.images[0].kind, ImageKind::kFixed);
  EXPECT_EQ(done[0].input.stereo_pairs.size(), 1u);
  EXPECT_TRUE(done[0].no_surface.empty());
}

TEST(EpochPhotoCollector, BadOptionsAndDistortionAreNamed) {
  PhotoCollectorOptions o;
  o.max_photos = 0;
  try {
    EpochPhotoCollector c(o);
    FAIL() << "max_photos 0 accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'max_photos'"), std::string::npos) << e.what();
  }
  PhotoOrientation bad = Oriented("uav", 7);
  bad.distortion.assign(camera::kNumInterior, 0.0);
  try {
    OrientPhoto(MakePhoto("uav", 7), EpochPhotosModel(), bad, ImageKind::kUav);
    FAIL() << "too many distortion terms accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_EQ(std::string(e.what()).rfind("uav@7.000: 10 distortion terms", 0), 0u) << e.what();
  }
}

}  // namespace
}  // namespace dense
}  // namespace slope_monitor
