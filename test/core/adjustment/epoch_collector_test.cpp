// EpochCollector driven by hand-made message sequences: when an epoch is
// complete (end markers with counts, tie-point counts), which images belong
// to it, what it gives up on and names, and that a bad observation is dropped
// by name while the rest of its epoch is solved (BuildScene + AdjustEpoch on
// a synthetic scene with known truth).
#include "slope_monitor/core/adjustment/epoch_collector.h"

#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/epoch_adjustment.h"
#include "slope_monitor/core/common/error.h"
#include "synthetic_scene.h"

namespace slope_monitor {
namespace adjustment {
namespace {

constexpr int64_t kT0 = 1700000000;  // [s] start of the hand-made sequences

StampNs At(double seconds) {
  return MakeStamp(kT0, 0) + static_cast<StampNs>(std::llround(seconds * 1e9));
}

ImageTargets Shot(const std::string& camera, double t, int n_targets = 3) {
  ImageTargets im;
  im.camera = camera;
  im.stamp = At(t);
  for (int k = 0; k < n_targets; ++k)
    im.targets.push_back(
        {k, "tag36h11", Eigen::Vector2d(100.0 + 10 * k, 200.0), Eigen::Matrix2d::Zero()});
  return im;
}

EpochEnd End(const std::string& source, double t, uint32_t count, uint32_t epoch = 1) {
  return {source, At(t), epoch, count};
}

EpochCollectorOptions TwoCameras() {
  EpochCollectorOptions o;
  o.cameras = {"fixed_cam_1", "fixed_cam_2"};
  return o;
}

bool Mentions(const std::vector<std::string>& lines, const std::string& text) {
  for (const std::string& l : lines)
    if (l.find(text) != std::string::npos) return true;
  return false;
}

TEST(EpochCollector, InterleavedCamerasMakeOneEpochWhenBothEnded) {
  EpochCollector c(TwoCameras(), nullptr);
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_1", 0), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_2", 1), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_1", 2), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_2", 3), 0).empty());
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_1", 2.5, 2), 0).empty());  // fixed_cam_2 has not ended
  const std::vector<CollectedEpoch> done = c.AddEnd(End("fixed_cam_2", 3.5, 2), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].epoch, 1u);
  EXPECT_EQ(done[0].images.size(), 4u);
  EXPECT_EQ(done[0].observations.size(), 12u);
  EXPECT_TRUE(done[0].incomplete.empty());
  EXPECT_EQ(done[0].latest_stamp, At(3));
  EXPECT_EQ(c.num_images(), 0u);
}

// Two cameras in one optical frame (camera_capture.launch's default frame
// for both): the adjuster publishes one transform per frame, so
// the second camera's images are refused, the line naming both cameras.
TEST(EpochCollector, ASecondCameraInAFrameInUseIsRefusedNamingBoth) {
  EpochCollector c(EpochCollectorOptions(), nullptr);
  ImageTargets north = Shot("north_ridge", 0), drone = Shot("drone", 1);
  north.frame_id = drone.frame_id = "camera_optical";
  c.AddTargets(north, 0);
  c.AddTargets(drone, 0);
  c.AddTargets(drone, 0);
  EXPECT_EQ(c.num_images(), 1u);
  EXPECT_EQ(c.num_observations(), 3u);
  ASSERT_EQ(c.ignored().size(), 1u);  // said once
  EXPECT_NE(c.ignored()[0].find("camera 'drone' sends its images in frame 'camera_optical', "
                                "the frame of camera 'north_ridge'"),
            std::string::npos)
      << c.ignored()[0];
  // Each camera its own frame: both taken.
  EpochCollector d(EpochCollectorOptions(), nullptr);
  d.AddTargets(Shot("north_ridge", 0), 0);
  d.AddTargets(Shot("drone", 1), 0);
  EXPECT_EQ(d.num_images(), 2u);
  EXPECT_TRUE(d.ignored().empty());
}

TEST(EpochCollector, EndMarkerBeforeItsImagesWaitsForTheAnnouncedCount) {
  EpochCollector c(TwoCameras(), nullptr);
  // The markers come straight from the cameras; the centroider lags.
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_1", 2.5, 2), 0).empty());
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_2", 3.5, 2), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_1", 0), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_2", 1), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_1", 2), 0).empty());
  const std::vector<CollectedEpoch> done = c.AddTargets(Shot("fixed_cam_2", 3), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].images.size(), 4u);
  EXPECT_TRUE(done[0].incomplete.empty());
}

TEST(EpochCollector, NextEpochImagesStayForTheNextEpoch) {
  EpochCollector c(TwoCameras(), nullptr);
  c.AddTargets(Shot("fixed_cam_1", 0), 0);
  c.AddEnd(End("fixed_cam_1", 0.5, 1), 0);
  c.AddEnd(End("fixed_cam_2", 1.5, 1), 0);
  // fixed_cam_1's next epoch arrives before fixed_cam_2's late image.
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_1", 3600), 0).empty());
  const std::vector<CollectedEpoch> done = c.AddTargets(Shot("fixed_cam_2", 1), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].images.size(), 2u);
  EXPECT_FALSE(done[0].images.count(ImageKey("fixed_cam_1", At(3600))));
  EXPECT_EQ(c.num_images(), 1u);  // the next epoch's image
}

// Any arrival order a graph can produce (each camera's stream in order, its
// end marker anywhere among its epoch's images since the centroider lags the
// camera, the markers in stamp order, the two cameras' streams interleaved at
// random) gives the same epochs.
TEST(EpochCollector, ArrivalOrderDoesNotChangeTheEpochs) {
  struct Input {
    bool end = false;
    ImageTargets image;
    EpochEnd marker;
  };
  std::mt19937 rng(42);
  for (int trial = 0; trial < 50; ++trial) {
    std::vector<std::vector<Input>> streams;
    for (const std::string camera : {"fixed_cam_1", "fixed_cam_2"}) {
      std::vector<Input> stream;
      for (uint32_t epoch = 1; epoch <= 2; ++epoch) {
        const double t0 = 10800.0 * (epoch - 1) + (camera == "fixed_cam_1" ? 0.0 : 0.5);
        std::vector<Input> part;
        for (int k = 0; k < 3; ++k) part.push_back({false, Shot(camera, t0 + k), {}});
        const size_t at = std::uniform_int_distribution<size_t>(0, part.size())(rng);
        part.insert(part.begin() + static_cast<long>(at),
                    Input{true, {}, End(camera, t0 + 2.9, 3, epoch)});
        stream.insert(stream.end(), part.begin(), part.end());
      }
      streams.push_back(stream);
    }
    EpochCollector c(TwoCameras(), nullptr);
    std::vector<CollectedEpoch> done;
    size_t next[2] = {0, 0};
    while (next[0] < streams[0].size() || next[1] < streams[1].size()) {
      int s = std::uniform_int_distribution<int>(0, 1)(rng);
      if (next[s] == streams[s].size()) s = 1 - s;
      // The markers come straight from the cameras: in stamp order across
      // cameras (only the centroider's output lags).
      const int o = 1 - s;
      if (streams[s][next[s]].end && next[o] < streams[o].size() &&
          (!streams[o][next[o]].end ||
           streams[o][next[o]].marker.stamp < streams[s][next[s]].marker.stamp)) {
        bool earlier_marker_pending = false;
        for (size_t k = next[o]; k < streams[o].size(); ++k)
          if (streams[o][k].end) {
            earlier_marker_pending = streams[o][k].marker.stamp < streams[s][next[s]].marker.stamp;
            break;
          }
        if (earlier_marker_pending) s = o;
      }
      const Input& in = streams[s][next[s]++];
      for (CollectedEpoch& e : in.end ? c.AddEnd(in.marker, 0) : c.AddTargets(in.image, 0))
        done.push_back(std::move(e));
    }
    ASSERT_EQ(done.size(), 2u) << "trial " << trial;
    for (uint32_t k = 0; k < 2; ++k) {
      EXPECT_EQ(done[k].epoch, k + 1);
      ASSERT_EQ(done[k].images.size(), 6u) << "trial " << trial;
      for (const auto& [key, im] : done[k].images)
        EXPECT_EQ(static_cast<int>(StampSeconds(im.stamp - At(0)) / 10800.0), static_cast<int>(k))
            << key;
      EXPECT_EQ(done[k].observations.size(), 18u);
      EXPECT_TRUE(done[k].incomplete.empty());
    }
  }
}

TEST(EpochCollector, MissingImageIsGivenUpWhenTheCamerasNextImageComes) {
  EpochCollector c(TwoCameras(), nullptr);
  c.AddTargets(Shot("fixed_cam_1", 0), 0);
  c.AddTargets(Shot("fixed_cam_2", 1), 0);
  c.AddEnd(End("fixed_cam_1", 2.5, 2), 0);  // announces 2, its second image never comes
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_2", 3.5, 1), 0).empty());
  // fixed_cam_1's images arrive in order: its next epoch's image means the
  // missing one is not coming.
  const std::vector<CollectedEpoch> done = c.AddTargets(Shot("fixed_cam_1", 3600), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].images.size(), 2u);
  ASSERT_EQ(done[0].incomplete.size(), 1u);
  EXPECT_EQ(done[0].incomplete[0], "fixed_cam_1: 1 of 2 announced images");
  EXPECT_EQ(c.num_images(), 1u);
}

TEST(EpochCollector, MissingImageAtTheEndOfInputIsNamed) {
  EpochCollector c(TwoCameras(), nullptr);
  c.AddTargets(Shot("fixed_cam_1", 0), 0);
  c.AddTargets(Shot("fixed_cam_2", 1), 0);
  c.AddEnd(End("fixed_cam_1", 2.5, 2), 0);
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_2", 3.5, 1), 0).empty());
  const std::optional<CollectedEpoch> last = c.Finish();
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->images.size(), 2u);
  EXPECT_EQ(last->reason, "end of input");
  EXPECT_TRUE(Mentions(last->incomplete, "fixed_cam_1: 1 of 2 announced images"));
  EXPECT_FALSE(c.Finish().has_value());  // nothing left
}

TEST(EpochCollector, DuplicatedAndStaleMarkersAreIgnoredAndNamed) {
  EpochCollector c(TwoCameras(), nullptr);
  c.AddTargets(Shot("fixed_cam_1", 0), 0);
  c.AddTargets(Shot("fixed_cam_2", 1), 0);
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_1", 0.5, 1), 0).empty());
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_1", 0.5, 1), 0).empty());  // duplicate
  EXPECT_EQ(c.AddEnd(End("fixed_cam_2", 1.5, 1), 0).size(), 1u);
  // The same marker again, after its epoch was solved (a re-sent latched topic).
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_2", 1.5, 1), 0).empty());
  // An out-of-order marker older than the one being collected.
  c.AddTargets(Shot("fixed_cam_1", 3600), 0);
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_1", 3600.5, 1, 2), 0).empty());
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_1", 3000, 1, 2), 0).empty());
  ASSERT_EQ(c.ignored().size(), 3u);
  EXPECT_NE(c.ignored()[0].find("'fixed_cam_1'"), std::string::npos);
  EXPECT_NE(c.ignored()[0].find("duplicate"), std::string::npos);
  EXPECT_NE(c.ignored()[1].find("already solved"), std::string::npos);
  EXPECT_NE(c.ignored()[2].find("older than"), std::string::npos);
  EXPECT_EQ(c.num_images(), 1u);  // epoch 2 still collecting, untouched
  EXPECT_EQ(c.current_epoch(), 2u);
}

TEST(EpochCollector, IncompleteUavFlightDoesNotBlockTheFixedCameras) {
  EpochCollectorOptions o = TwoCameras();
  o.cameras.push_back("uav");
  EpochCollector c(o, nullptr);
  c.AddTargets(Shot("fixed_cam_1", 0), 0);
  c.AddTargets(Shot("fixed_cam_2", 1), 0);
  c.AddTargets(Shot("uav", 2), 0);
  c.AddTargets(Shot("uav", 3), 0);  // the flight is cut short: no end marker
  c.AddEnd(End("fixed_cam_1", 10, 1), 0);
  EXPECT_TRUE(c.AddEnd(End("fixed_cam_2", 11, 1), 0).empty());  // waits for the UAV
  // The fixed cameras' next epoch: the UAV will not end epoch 1 any more.
  c.AddTargets(Shot("fixed_cam_1", 3600), 0);
  const std::vector<CollectedEpoch> done = c.AddEnd(End("fixed_cam_1", 3600.5, 1, 2), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].epoch, 1u);
  EXPECT_EQ(done[0].images.size(), 2u);
  for (const auto& [key, im] : done[0].images) EXPECT_NE(im.camera, "uav");
  ASSERT_EQ(done[0].incomplete.size(), 1u);
  EXPECT_EQ(done[0].incomplete[0], "uav: no end marker (2 images left out)");
  // The deferred marker now belongs to epoch 2, which waits for its cameras.
  EXPECT_EQ(c.current_epoch(), 2u);
  EXPECT_EQ(c.num_images(), 1u);
}

TEST(EpochCollector, UavEpochWaitsForItsTiePoints) {
  EpochCollectorOptions o;
  o.cameras = {"uav"};
  o.tie_point_cameras = {"uav"};
  EpochCollector c(o, nullptr);
  c.AddTargets(Shot("uav", 0), 0);
  c.AddTargets(Shot("uav", 1), 0);
  EXPECT_TRUE(c.AddEnd(End("uav", 1.5, 2), 0).empty());
  ImageTies first;  // image 0: no partner, one message
  first.camera_b = "uav";
  first.stamp_b = At(0);
  first.pairs_b = 1;
  EXPECT_TRUE(c.AddTies(first, 0).empty());
  ImageTies second;  // image 1: tied to image 0, announced in two messages
  second.camera_a = "uav";
  second.camera_b = "uav";
  second.stamp_a = At(0);
  second.stamp_b = At(1);
  second.pairs_b = 2;
  second.points.push_back(
      {7, 0.9, Eigen::Vector2d(10, 10), Eigen::Vector2d(12, 10), Eigen::Matrix2d::Zero()});
  EXPECT_TRUE(c.AddTies(second, 0).empty());
  const std::vector<CollectedEpoch> done = c.AddTies(second, 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].observations.size(),
            2u * 3u + 2u * 2u);  // 3 targets per image, tie 7 twice in both
  EXPECT_EQ(c.tie_points_used(), 2u);
}

TEST(EpochCollector, TiePointsAreNotAwaitedWhenNoMatcherPublishes) {
  EpochCollectorOptions o;
  o.cameras = {"uav"};
  o.tie_point_cameras = {"uav"};
  EpochCollector c(o, nullptr);
  c.SetTiePointsExpected(false);
  c.AddTargets(Shot("uav", 0), 0);
  EXPECT_EQ(c.AddEnd(End("uav", 0.5, 1), 0).size(), 1u);
}

TEST(EpochCollector, LiveTimeOutNamesTheInputItGaveUpOn) {
  EpochCollectorOptions o = TwoCameras();
  o.epoch_wait = 30.0;
  EpochCollector c(o, nullptr);
  c.AddTargets(Shot("fixed_cam_1", 0), 100.0);
  c.AddEnd(End("fixed_cam_1", 0.5, 1), 100.0);
  c.AddEnd(End("fixed_cam_2", 1.5, 1), 100.0);  // its image never comes
  EXPECT_TRUE(c.Poll(129.0).empty());
  const std::vector<CollectedEpoch> done = c.Poll(131.0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_NE(done[0].reason.find("time-out 31 s"), std::string::npos) << done[0].reason;
  ASSERT_EQ(done[0].incomplete.size(), 1u);
  EXPECT_EQ(done[0].incomplete[0], "fixed_cam_2: 0 of 1 announced images");
}

TEST(EpochCollector, WithoutMarkersAGapInTheImageStampsEndsTheEpoch) {
  EpochCollectorOptions o;
  o.epoch_gap = 600.0;
  EpochCollector c(o, nullptr);
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_1", 0), 0).empty());
  EXPECT_TRUE(c.AddTargets(Shot("fixed_cam_2", 599), 0).empty());
  const std::vector<CollectedEpoch> done = c.AddTargets(Shot("fixed_cam_1", 1200), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].images.size(), 2u);
  EXPECT_EQ(c.num_images(), 1u);
}

TEST(EpochCollector, BadObservationsAreDroppedAndNamed) {
  EpochCollector c(TwoCameras(), nullptr);
  ImageTargets im = Shot("fixed_cam_1", 0, 5);
  im.targets[1].pixel.x() = std::numeric_limits<double>::quiet_NaN();
  im.targets[2].covariance << -1.0, 0.0, 0.0, 1.0;
  im.targets[3].covariance = Eigen::Matrix2d::Identity() * 1e8;  // 10000 px sigma
  im.targets[4].covariance(0, 1) = std::numeric_limits<double>::infinity();
  c.AddTargets(im, 0);
  c.AddTargets(Shot("fixed_cam_2", 1), 0);
  c.AddEnd(End("fixed_cam_1", 0.5, 1), 0);
  const std::vector<CollectedEpoch> done = c.AddEnd(End("fixed_cam_2", 1.5, 1), 0);
  ASSERT_EQ(done.size(), 1u);
  EXPECT_EQ(done[0].observations.size(), 1u + 3u);
  ASSERT_EQ(done[0].dropped.size(), 4u);
  const std::string key = ImageKey("fixed_cam_1", At(0));
  EXPECT_EQ(done[0].dropped[0], key + ": tag36h11/1: pixel not finite (dropped)");
  EXPECT_NE(done[0].dropped[1].find("tag36h11/2: covariance not positive definite"),
            std::string::npos);
  EXPECT_NE(done[0].dropped[2].find("tag36h11/3: sigma 10000 px above max_pixel_sigma"),
            std::string::npos);
  EXPECT_NE(done[0].dropped[3].find("tag36h11/4: covariance not finite"), std::string::npos);
  EXPECT_EQ(c.observations_dropped(), 4u);
}

TEST(EpochCollector, ImageKeyAndStampsAreExact) {
  EXPECT_EQ(ImageKey("fixed_cam_1", MakeStamp(1700000000, 500000000)),
            "fixed_cam_1@1700000000.500000000");
  EXPECT_EQ(ImageKey("c", MakeStamp(12, 5)), "c@12.5");
  EXPECT_DOUBLE_EQ(StampSeconds(MakeStamp(12, 500000000)), 12.5);
}

TEST(EpochCollector, OptionsNameTheBadField) {
  EpochCollectorOptions o;
  o.max_pixel_sigma = 0.0;
  try {
    EpochCollector c(o, nullptr);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("max_pixel_sigma"), std::string::npos);
  }
}

// A target list of one surveyed control point, tag36h11/0 at the origin.
io::TargetList OneControlTarget() {
  return io::TargetList::FromYaml(
      "frame: site\ntargets:\n  - {id: 0, family: tag36h11, size: 0.6, role: control, position: "
      "[0, 0, 0]}\n",
      "scene order test");
}

// Two scenes built from the same messages in another order: the same points
// and the same observations, in the same order.
void ExpectSameScene(const Scene& s0, const Scene& s1) {
  ASSERT_EQ(s0.points.size(), s1.points.size());
  for (size_t j = 0; j < s0.points.size(); ++j) EXPECT_EQ(s0.points[j].id, s1.points[j].id) << j;
  ASSERT_EQ(s0.observations.size(), s1.observations.size());
  for (size_t k = 0; k < s0.observations.size(); ++k) {
    EXPECT_EQ(s0.observations[k].image, s1.observations[k].image) << k;
    EXPECT_EQ(s0.observations[k].point, s1.observations[k].point) << k;
    EXPECT_EQ(s0.observations[k].pixel, s1.observations[k].pixel) << k;
  }
}

// The scene of an epoch does not depend on which camera's messages came
// first (two centroiders run in parallel): same points, same observations in
// the same order.
TEST(EpochCollector, SceneDoesNotDependOnTheCamerasArrivalOrder) {
  const io::TargetList targets = OneControlTarget();
  std::map<std::string, camera::CameraModel> models;
  models["fixed_cam_1"] = models["fixed_cam_2"] = camera::CameraModel();
  std::vector<BuiltScene> scenes;
  for (const bool first_camera_first : {true, false}) {
    EpochCollector c(TwoCameras(), &targets);
    ImageTargets a = Shot("fixed_cam_1", 0, 3), b = Shot("fixed_cam_2", 1, 4);
    b.targets[0].id = 9;  // a point only fixed_cam_2 sees, listed first there
    c.AddTargets(first_camera_first ? a : b, 0);
    c.AddTargets(first_camera_first ? b : a, 0);
    c.AddEnd(End("fixed_cam_1", 0.5, 1), 0);
    const std::vector<CollectedEpoch> done = c.AddEnd(End("fixed_cam_2", 1.5, 1), 0);
    EXPECT_EQ(done.size(), 1u);
    if (done.size() == 1u)
      scenes.push_back(BuildScene(done[0], models, EpochStore(), targets, BuildSceneOptions()));
  }
  ASSERT_EQ(scenes.size(), 2u);
  const Scene &s0 = scenes[0].scene, &s1 = scenes[1].scene;
  ASSERT_EQ(s0.observations.size(), 7u);
  ExpectSameScene(s0, s1);
  EXPECT_EQ(s0.points[0].id, "tag36h11/0");
  ASSERT_TRUE(s0.points[0].surveyed.has_value());  // the control point's survey from the list
}

// A UAV photo's targets (centroider) and its tie points (hex_matcher) come
// from different nodes, in either order: the scene is the same, observation
// by observation (found on a renamed bag whose equal stamps came in another
// order: the screening adjustment flagged 8 or 761 tie observations).
TEST(EpochCollector, SceneDoesNotDependOnWhetherTargetsOrTiePointsComeFirst) {
  const io::TargetList targets = OneControlTarget();
  std::map<std::string, camera::CameraModel> models;
  models["uav"] = camera::CameraModel();
  EpochCollectorOptions o;
  o.cameras = {"uav"};
  o.tie_point_cameras = {"uav"};
  ImageTies first;  // photo 0: no partner
  first.camera_b = "uav";
  first.stamp_b = At(0);
  first.pairs_b = 1;
  ImageTies second;  // photo 1: tied to photo 0
  second.camera_a = second.camera_b = "uav";
  second.stamp_a = At(0);
  second.stamp_b = At(1);
  second.pairs_b = 1;
  for (int k = 0; k < 4; ++k)
    second.points.push_back({20 - k, 0.9, Eigen::Vector2d(10 + k, 10), Eigen::Vector2d(12 + k, 10),
                             Eigen::Matrix2d::Zero()});
  std::vector<Scene> scenes;
  for (const bool targets_first : {true, false}) {
    EpochCollector c(o, &targets);
    for (int i = 0; i < 2; ++i) {
      const ImageTargets shot = Shot("uav", i);
      const ImageTies& ties = i == 0 ? first : second;
      if (targets_first) {
        c.AddTargets(shot, 0);
        c.AddTies(ties, 0);
      } else {
        c.AddTies(ties, 0);
        c.AddTargets(shot, 0);
      }
    }
    const std::vector<CollectedEpoch> done = c.AddEnd(End("uav", 1.5, 2), 0);
    ASSERT_EQ(done.size(), 1u);
    scenes.push_back(BuildScene(done[0], models, EpochStore(), targets, BuildSceneOptions()).scene);
  }
  ASSERT_EQ(scenes[0].points.size(), 3u + 4u);
  ASSERT_EQ(scenes[0].observations.size(), 2u * 3u + 2u * 4u);
  ExpectSameScene(scenes[0], scenes[1]);
}

// ----------------------------------------------------------------------------
// The whole path of the bundle_adjuster for one epoch of three fixed cameras
// with one bad observation: collected, built, adjusted against the truth.

struct FixedEpoch {
  testing::TruthScene scene;
  io::TargetList targets;
  std::map<std::string, camera::CameraModel> models;
};

FixedEpoch MakeFixedEpoch() {
  testing::SceneSpec spec;
  spec.num_tie = 0;
  spec.seed = 5;
  FixedEpoch f;
  f.scene = testing::MakeScene(spec);
  std::string yaml = "frame: site\ntargets:\n";
  for (const ObjectPoint& p : f.scene.truth.points) {
    const int id = std::stoi(p.id.substr(p.id.find('/') + 1));
    const bool surveyed = p.role == PointRole::kControl || p.role == PointRole::kCheck;
    const Eigen::Vector3d x = surveyed ? *p.surveyed : p.position;
    yaml += Message(
        "  - {id: ", id, ", family: tag36h11, size: 0.6, role: ",
        p.role == PointRole::kControl ? "control"
                                      : (p.role == PointRole::kCheck ? "check" : "monitoring"),
        surveyed
            ? Message(", position: [", x.x(), ", ", x.y(), ", ", x.z(), "], sigma: [0.003, 0.003]")
            : "",
        "}\n");
  }
  f.targets = io::TargetList::FromYaml(yaml, "epoch_collector_test targets");
  for (const Camera& cam : f.scene.observed.cameras) f.models[cam.name] = cam.model;
  return f;
}

TEST(EpochCollector, BadObservationIsDroppedAndTheRestOfTheEpochIsSolved) {
  const FixedEpoch f = MakeFixedEpoch();
  const Scene& observed = f.scene.observed;
  EpochCollectorOptions o;
  for (const Camera& cam : observed.cameras) o.cameras.push_back(cam.name);
  EpochCollector c(o, &f.targets);
  std::string bad;
  std::vector<CollectedEpoch> done;
  for (size_t i = 0; i < observed.images.size(); ++i) {
    ImageTargets im;
    im.camera = observed.cameras[observed.images[i].camera].name;
    im.stamp = At(static_cast<double>(i));
    for (const Observation& ob : observed.observations) {
      if (ob.image != static_cast<int>(i)) continue;
      const std::string& id = observed.points[ob.point].id;
      TargetInput t{std::stoi(id.substr(id.find('/') + 1)), "tag36h11", ob.pixel, ob.covariance};
      // One monitoring target in the first image has a NaN covariance.
      if (i == 0 && bad.empty() && observed.points[ob.point].role == PointRole::kMonitoring) {
        t.covariance(1, 1) = std::numeric_limits<double>::quiet_NaN();
        bad = id;
      }
      im.targets.push_back(t);
    }
    c.AddTargets(im, 0);
  }
  for (size_t i = 0; i < observed.images.size(); ++i) {
    for (CollectedEpoch& e : c.AddEnd(
             End(observed.cameras[observed.images[i].camera].name, static_cast<double>(i) + 0.5, 1),
             0))
      done.push_back(std::move(e));
  }
  ASSERT_EQ(done.size(), 1u);
  ASSERT_EQ(done[0].dropped.size(), 1u);
  EXPECT_NE(done[0].dropped[0].find(bad + ": covariance not finite (dropped)"), std::string::npos)
      << done[0].dropped[0];
  EXPECT_EQ(done[0].observations.size(), observed.observations.size() - 1);

  EpochStore store;
  const BuiltScene built = BuildScene(done[0], f.models, store, f.targets, BuildSceneOptions());
  EXPECT_EQ(built.scene.images.size(), 3u);
  EpochAdjustmentOptions options;
  const EpochAdjustmentResult result =
      AdjustEpoch(built.scene, built.unidentified, ListedTargets(f.targets), options);
  ASSERT_TRUE(result.summary.IsSolutionUsable()) << result.summary.reason;
  // Every monitoring point (the bad one still seen by the other cameras)
  // within 1 cm of the truth (0.1 px noise at 100-200 m: a few mm).
  int checked = 0;
  for (const ObjectPoint& p : result.scene.points) {
    if (p.role != PointRole::kMonitoring) continue;
    const int t = f.scene.truth.FindPoint(p.id);
    ASSERT_GE(t, 0);
    EXPECT_LT((p.position - f.scene.truth.points[t].position).norm(), 0.01) << p.id;
    ++checked;
  }
  EXPECT_GE(checked, 15);
  EXPECT_GE(result.scene.FindPoint(bad), 0);

  // Accepted: the store remembers the poses; the first epoch is the reference.
  const EpochPoints ep = store.Accept(result.scene, result.summary, 1, 0.0, true);
  EXPECT_EQ(store.reference_epoch(), 1);
  EXPECT_FALSE(store.CompareWithReference(ep, DisplacementOptions()).has_value());
  ASSERT_NE(store.LastPose("fixed_cam_1"), nullptr);
  int chosen = -1;
  EXPECT_EQ(store.SetReference(false, 7, &chosen), "epoch 7 has no accepted solution");
  EXPECT_EQ(store.SetReference(true, 0, &chosen), "");
  EXPECT_EQ(chosen, 1);
  // The next epoch of the fixed cameras starts from the accepted poses.
  const BuiltScene next = BuildScene(done[0], f.models, store, f.targets, BuildSceneOptions());
  for (const Image& im : next.scene.images) EXPECT_TRUE(im.exterior_known) << im.name;
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
