// Generates the tiny simulated site into a temp dir with the same code as
// make_survey_bag (core + ros_adapters::WriteSurveyBag), reads the bag back
// with rosbag::View and checks topics, counts, stamps, encodings, camera_info
// and that the truth and target list load.
#include <cstdlib>
#include <map>
#include <set>
#include <string>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/NavSatFix.h>
#include <tf2_msgs/TFMessage.h>

#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/io/geotiff.h"
#include "slope_monitor/core/io/target_list.h"
#include "slope_monitor/core/sim/survey.h"
#include "slope_monitor/ros/sim_bag_writer.h"

namespace slope_monitor {
namespace {

std::string TempDir() {
  char tmpl[] = "/tmp/sim_bag_test_XXXXXX";
  const char* d = mkdtemp(tmpl);
  return d ? std::string(d) : std::string("/tmp");
}

TEST(SimBagTest, BagHasTheDocumentedTopicsAndTruthLoads) {
  const std::string dir = TempDir();
  const std::string stem = dir + "/tiny";
  sim::SurveyConfig config =
      sim::SurveyConfig::Load(std::string(SM_TEST_DATA_DIR) + "/sim/tiny_site.yaml");
  sim::Survey survey = sim::SurveyGenerator(config).Generate();
  sim::WriteSurveyFiles(&survey, stem);
  const auto summary = ros_adapters::WriteSurveyBag(survey, stem + ".bag", "bz2");

  const sim::SurveyTruth truth = sim::SurveyTruth::Load(stem + ".truth.yaml");
  ASSERT_EQ(truth.cameras.size(), 2u);
  const size_t fixed_images = truth.FindCamera("fixed_cam_1")->images.size();
  const size_t uav_images = truth.FindCamera("uav")->images.size();
  EXPECT_EQ(fixed_images, 3u);  // one per epoch
  EXPECT_GE(uav_images, 6u);
  ASSERT_EQ(truth.surfaces.size(), 3u);
  const io::GeoRaster surface = io::ReadGeoTiff(dir + "/" + truth.surfaces[0].geotiff);
  EXPECT_GT(surface.width, 100);
  const io::TargetList targets = io::TargetList::Load(stem + ".targets.yaml");
  EXPECT_EQ(targets.targets().size(), truth.targets.size());
  for (const auto& t : targets.targets()) {
    EXPECT_EQ(t.position.has_value(), t.role != io::TargetRole::kMonitoring) << t.Key();
  }

  rosbag::Bag bag;
  bag.open(stem + ".bag", rosbag::bagmode::Read);
  rosbag::View view(bag);
  std::map<std::string, int> count;
  std::map<std::string, std::string> type;
  double last = 0.0;
  bool ordered = true;
  std::set<double> image_stamps, info_stamps;
  for (const rosbag::MessageInstance& m : view) {
    ++count[m.getTopic()];
    type[m.getTopic()] = m.getDataType();
    ordered = ordered && m.getTime().toSec() >= last;
    last = m.getTime().toSec();
    if (auto img = m.instantiate<sensor_msgs::Image>()) {
      const bool uav = m.getTopic() == "/uav/camera/image_raw";
      EXPECT_EQ(img->encoding, uav ? "bgr8" : "mono8");
      EXPECT_EQ(img->header.frame_id, uav ? "uav_optical" : "fixed_cam_1_optical");
      EXPECT_EQ(img->width, 320u);
      EXPECT_EQ(img->height, 240u);
      EXPECT_EQ(img->step, img->width * (uav ? 3u : 1u));
      EXPECT_EQ(img->data.size(), img->step * img->height);
      EXPECT_DOUBLE_EQ(img->header.stamp.toSec(), m.getTime().toSec());
      image_stamps.insert(img->header.stamp.toSec());
    }
    if (auto info = m.instantiate<sensor_msgs::CameraInfo>()) {
      info_stamps.insert(info->header.stamp.toSec());
      const bool uav = m.getTopic() == "/uav/camera/camera_info";
      const sim::CameraTruth* cam = truth.FindCamera(uav ? "uav" : "fixed_cam_1");
      // Nominal intrinsics: fx = c / pixel_size of the nominal model, not the truth's principal
      // point.
      EXPECT_NEAR(info->K[0], cam->nominal.principal_distance() / cam->nominal.sensor().pixel_size,
                  1e-6);
      EXPECT_NEAR(info->K[2], 0.5 * (info->width - 1), 1e-9);
      EXPECT_EQ(info->width, 320u);
    }
    if (auto fix = m.instantiate<sensor_msgs::NavSatFix>()) {
      EXPECT_NEAR(fix->latitude, 46.5, 0.01);
      EXPECT_NEAR(fix->longitude, 8.0, 0.01);
    }
    if (auto marker = m.instantiate<slope_monitor::EpochMarker>()) {
      EXPECT_LT(marker->epoch, 3u);
      if (marker->end) EXPECT_GT(marker->count, 0u);
    }
    if (auto block = m.instantiate<slope_monitor::RadioSampleBlock>()) {
      EXPECT_EQ(block->i.size(), 256u);
      EXPECT_EQ(block->q.size(), 256u);
      EXPECT_EQ("/radio/" + block->receiver_id + "/samples", m.getTopic());
    }
    if (auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
      EXPECT_EQ(m.getTopic(), "/tf_static");
      EXPECT_EQ(tf->transforms.size(), 1u + 3u);  // fixed_cam_1_optical + 3 antennas
      // Latched, so rosbag play republishes it latched (rviz started late sees `site`).
      ASSERT_NE(m.getConnectionHeader(), nullptr);
      const auto latching = m.getConnectionHeader()->find("latching");
      ASSERT_NE(latching, m.getConnectionHeader()->end());
      EXPECT_EQ(latching->second, "1");
    }
  }
  bag.close();
  EXPECT_TRUE(ordered);
  EXPECT_EQ(info_stamps, image_stamps);  // every camera_info has the stamp of its image
  EXPECT_EQ(count["/fixed_cam_1/camera/image_raw"], static_cast<int>(fixed_images));
  EXPECT_EQ(count["/fixed_cam_1/camera/camera_info"], static_cast<int>(fixed_images));
  EXPECT_EQ(count["/uav/camera/image_raw"], static_cast<int>(uav_images));
  EXPECT_EQ(count["/uav/camera/camera_info"], static_cast<int>(uav_images));
  EXPECT_EQ(count["/uav/gnss/fix"], static_cast<int>(uav_images));
  EXPECT_EQ(count["/uav/camera/position_prior"], static_cast<int>(uav_images));
  EXPECT_EQ(count["/fixed_cam_1/camera/epoch"], 6);  // start + end per epoch
  EXPECT_EQ(count["/uav/camera/epoch"], 6);
  EXPECT_EQ(count["/tf_static"], 1);
  EXPECT_EQ(type["/uav/camera/position_prior"], "geometry_msgs/PoseWithCovarianceStamped");
  EXPECT_EQ(type["/radio/rx1/samples"], "slope_monitor/RadioSampleBlock");
  // Radio: blocks every 1200 s from the start to 1200 s after the last epoch: 8 starts x 3
  // receivers.
  EXPECT_EQ(count["/radio/rx1/samples"] + count["/radio/rx2/samples"] + count["/radio/rx3/samples"],
            24);
  EXPECT_EQ(summary.radio_blocks, 24);
  EXPECT_EQ(summary.images, static_cast<int>(fixed_images + uav_images));
  // Epochs hours apart: the bag spans the survey.
  EXPECT_NEAR(last - config.start_time, 7200.0 + 1200.0, 1.0);
}

}  // namespace
}  // namespace slope_monitor
