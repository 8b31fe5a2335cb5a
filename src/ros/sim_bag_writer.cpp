#include "slope_monitor/ros/sim_bag_writer.h"

#include <algorithm>
#include <cstring>
#include <map>
#include <memory>
#include <tuple>

#include <geometry_msgs/PoseWithCovarianceStamped.h>
#include <geometry_msgs/TransformStamped.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/NavSatFix.h>
#include <tf2_msgs/TFMessage.h>
#include <boost/make_shared.hpp>

#include "slope_monitor/EpochMarker.h"
#include "slope_monitor/RadioSampleBlock.h"
#include "slope_monitor/core/capture/geodesy.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/conversions.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

ros::Time Stamp(double t) { return ros::Time(t); }

sensor_msgs::Image ImageMsg(const cv::Mat& pixels, const std::string& encoding,
                            const std::string& frame, double t) {
  sensor_msgs::Image m;
  m.header.stamp = Stamp(t);
  m.header.frame_id = frame;
  m.height = pixels.rows;
  m.width = pixels.cols;
  m.encoding = encoding;
  m.is_bigendian = 0;
  m.step = static_cast<uint32_t>(pixels.cols * pixels.elemSize());
  m.data.resize(static_cast<size_t>(m.step) * m.height);
  for (int r = 0; r < pixels.rows; ++r)
    std::memcpy(&m.data[static_cast<size_t>(r) * m.step], pixels.ptr(r), m.step);
  return m;
}

slope_monitor::RadioSampleBlock RadioMsg(const radio::SampleBlock& b) {
  slope_monitor::RadioSampleBlock m;
  m.header.stamp = Stamp(b.stamp);
  m.header.frame_id = b.frame_id;
  m.receiver_id = b.receiver_id;
  m.sequence = b.sequence;
  m.sample_rate = b.sample_rate;
  m.center_frequency = b.center_frequency;
  m.full_scale = b.full_scale;
  m.i = b.i;
  m.q = b.q;
  return m;
}

std::string ReceiverFrame(const sim::RadioSimReceiver& r) {
  return r.frame_id.empty() ? r.id + "_antenna" : r.frame_id;
}

// /tf_static, latched: site -> each fixed camera's optical frame (its
// nominal pose) and site -> each radio receiver's antenna.
void WriteStaticTransforms(const sim::Survey& survey, double t0, rosbag::Bag* bag_out,
                           SurveyBagSummary* summary_out) {
  const sim::SurveyTruth& truth = survey.truth;
  rosbag::Bag& bag = *bag_out;
  SurveyBagSummary& summary = *summary_out;
  tf2_msgs::TFMessage tf;
  auto add = [&](const std::string& child, const Rigid3& parent_from_child) {
    geometry_msgs::TransformStamped ts;
    ts.header.stamp = Stamp(t0);
    ts.header.frame_id = "site";
    ts.child_frame_id = child;
    ts.transform = ToTransform(parent_from_child);
    tf.transforms.push_back(ts);
  };
  for (const auto& c : truth.cameras) {
    if (c.nominal_pose) add(c.name + "_optical", c.nominal_pose->SiteFromOptical());
  }
  if (survey.radio) {
    for (const auto& r : survey.radio->config().receivers) {
      add(ReceiverFrame(r), Rigid3(Eigen::Quaterniond::Identity(), r.position));
    }
  }
  if (!tf.transforms.empty()) {
    // Latched as tf2_ros' static broadcaster publishes it, so rosbag play
    // republishes it latched and a tf listener (rviz, tf_echo) started
    // after playback begins still sees `site`.
    auto header = boost::make_shared<ros::M_string>();
    (*header)["callerid"] = "/make_survey_bag";
    (*header)["latching"] = "1";
    (*header)["type"] = ros::message_traits::datatype(tf);
    (*header)["md5sum"] = ros::message_traits::md5sum(tf);
    (*header)["message_definition"] = ros::message_traits::definition(tf);
    bag.write("/tf_static", Stamp(t0), tf, header);
    ++summary.tf_static;
  }
}

// What the bag holds, in time order (ties by kind, then index): kind 0 an
// epoch's start marker, 1 an image (with its camera_info and GNSS), 2 an
// epoch's end marker, 3 a radio block.
struct SurveyEvent {
  double t;
  int kind;
  int a;  // camera / block index
  int b;  // epoch / image index into survey.images
};

std::vector<SurveyEvent> SurveyEvents(const sim::Survey& survey) {
  const sim::SurveyTruth& truth = survey.truth;
  std::vector<SurveyEvent> events;
  for (size_t ci = 0; ci < truth.cameras.size(); ++ci) {
    std::map<int, std::pair<double, double>> span;  // epoch -> first, last stamp
    for (const auto& im : truth.cameras[ci].images) {
      auto it = span.find(im.epoch);
      if (it == span.end())
        span[im.epoch] = {im.stamp, im.stamp};
      else
        it->second = {std::min(it->second.first, im.stamp), std::max(it->second.second, im.stamp)};
    }
    for (const auto& [epoch, s] : span) {
      events.push_back({s.first - 0.5, 0, static_cast<int>(ci), epoch});
      events.push_back({s.second + 0.5, 2, static_cast<int>(ci), epoch});
    }
  }
  for (size_t k = 0; k < survey.images.size(); ++k) {
    events.push_back({survey.images[k].stamp, 1, survey.images[k].camera, static_cast<int>(k)});
  }
  for (size_t k = 0; k < survey.radio_block_starts.size(); ++k) {
    events.push_back({survey.radio_block_starts[k], 3, static_cast<int>(k), 0});
  }
  std::stable_sort(events.begin(), events.end(), [](const SurveyEvent& x, const SurveyEvent& y) {
    return std::tie(x.t, x.kind, x.a, x.b) < std::tie(y.t, y.kind, y.a, y.b);
  });
  return events;
}

// An image's GNSS fix (NavSatFix) and the position prior in `site` (with
// the flight log's attitude when the camera has an IMU).
void WriteGnss(const sim::Survey& survey, const sim::SurveyImage& img,
               const capture::LocalTangentPlane& ltp_ref, rosbag::Bag* bag_out,
               SurveyBagSummary* summary_out) {
  rosbag::Bag& bag = *bag_out;
  SurveyBagSummary& summary = *summary_out;
  const sim::CameraTruth& cam = survey.truth.cameras[img.camera];
  const sim::ImageTruth& it = cam.images[img.image];
  const std::string ns = "/" + cam.name + "/camera/";
  const capture::LocalTangentPlane* ltp = &ltp_ref;
  const sim::CameraSpec& spec = survey.config.cameras[img.camera];
  const capture::Geodetic g = ltp->ToGeodetic(*it.gnss);
  sensor_msgs::NavSatFix fix;
  fix.header.stamp = Stamp(img.stamp);
  fix.header.frame_id = cam.name + "_gnss";
  fix.status.status = sensor_msgs::NavSatStatus::STATUS_GBAS_FIX;
  fix.status.service = sensor_msgs::NavSatStatus::SERVICE_GPS;
  fix.latitude = g.latitude_deg;
  fix.longitude = g.longitude_deg;
  fix.altitude = g.height_m;
  const double h2 = spec.gnss_sigma.x() * spec.gnss_sigma.x(),
               v2 = spec.gnss_sigma.y() * spec.gnss_sigma.y();
  fix.position_covariance = {h2, 0, 0, 0, h2, 0, 0, 0, v2};
  fix.position_covariance_type = sensor_msgs::NavSatFix::COVARIANCE_TYPE_DIAGONAL_KNOWN;
  bag.write("/" + cam.name + "/gnss/fix", Stamp(img.stamp), fix);
  geometry_msgs::PoseWithCovarianceStamped prior;
  prior.header.stamp = Stamp(img.stamp);
  prior.header.frame_id = "site";
  prior.pose.pose.position.x = it.gnss->x();
  prior.pose.pose.position.y = it.gnss->y();
  prior.pose.pose.position.z = it.gnss->z();
  prior.pose.pose.orientation.w = 1.0;
  prior.pose.covariance.fill(0.0);
  prior.pose.covariance[0] = h2;
  prior.pose.covariance[7] = h2;
  prior.pose.covariance[14] = v2;
  prior.pose.covariance[21] = prior.pose.covariance[28] = prior.pose.covariance[35] = 1e6;
  if (spec.imu_sigma > 0.0) {
    const Eigen::Quaterniond q = sim::FlightLogAttitude(it.exterior, spec.imu_sigma,
                                                        survey.config.seed, img.camera, img.image);
    prior.pose.pose.orientation.w = q.w();
    prior.pose.pose.orientation.x = q.x();
    prior.pose.pose.orientation.y = q.y();
    prior.pose.pose.orientation.z = q.z();
    prior.pose.covariance[21] = prior.pose.covariance[28] = prior.pose.covariance[35] =
        spec.imu_sigma * spec.imu_sigma;
  }
  bag.write(ns + "position_prior", Stamp(img.stamp), prior);
  ++summary.gnss_fixes;
}

}  // namespace

SurveyBagSummary WriteSurveyBag(const sim::Survey& survey, const std::string& path,
                                const std::string& compression) {
  rosbag::CompressionType ct;
  if (compression == "bz2") {
    ct = rosbag::compression::BZ2;
  } else if (compression == "lz4") {
    ct = rosbag::compression::LZ4;
  } else if (compression == "none") {
    ct = rosbag::compression::Uncompressed;
  } else {
    throw InvalidArgument(
        Message("bag compression '", compression, "' is not one of: bz2, lz4, none"));
  }
  const sim::SurveyTruth& truth = survey.truth;
  SurveyBagSummary summary;
  rosbag::Bag bag;
  try {
    bag.open(path, rosbag::bagmode::Write);
    bag.setCompression(ct);
    bag.setChunkThreshold(4 * 1024 * 1024);

    const double t0 = truth.epochs.empty() ? survey.config.start_time : truth.epochs.front().stamp;

    // ---- /tf_static: site -> receiver antennas, site -> fixed cameras' optical frames (nominal)
    // ----
    WriteStaticTransforms(survey, t0, &bag, &summary);

    // ---- events in time order ----
    const std::vector<SurveyEvent> events = SurveyEvents(survey);

    std::unique_ptr<capture::LocalTangentPlane> ltp;
    ltp = std::make_unique<capture::LocalTangentPlane>(
        capture::Geodetic{truth.origin.x(), truth.origin.y(), truth.origin.z()});

    for (const SurveyEvent& e : events) {
      if (e.kind == 0 || e.kind == 2) {
        const auto& cam = truth.cameras[e.a];
        slope_monitor::EpochMarker m;
        m.header.stamp = Stamp(e.t);
        m.header.frame_id = cam.name + "_optical";
        m.epoch = static_cast<uint32_t>(e.b);
        m.end = e.kind == 2;
        m.source = cam.name;
        uint32_t count = 0;
        for (const auto& im : cam.images) count += im.epoch == e.b ? 1 : 0;
        m.count = m.end ? count : 0;
        bag.write("/" + cam.name + "/camera/epoch", Stamp(e.t), m);
        ++summary.epoch_markers;
      } else if (e.kind == 1) {
        const sim::SurveyImage& img = survey.images[e.b];
        const sim::CameraTruth& cam = truth.cameras[img.camera];
        const sim::ImageTruth& it = cam.images[img.image];
        const std::string ns = "/" + cam.name + "/camera/";
        const sensor_msgs::Image msg =
            ImageMsg(img.pixels, cam.encoding, cam.name + "_optical", img.stamp);
        sensor_msgs::CameraInfo info = ToMsg(cam.nominal.ToCameraInfo());
        info.header = msg.header;
        bag.write(ns + "image_raw", Stamp(img.stamp), msg);
        bag.write(ns + "camera_info", Stamp(img.stamp), info);
        ++summary.images;
        ++summary.camera_infos;
        if (it.gnss) WriteGnss(survey, img, *ltp, &bag, &summary);
      } else if (e.kind == 3 && survey.radio) {
        for (const radio::SampleBlock& b :
             survey.radio->SynthesizeAll(e.t, static_cast<uint32_t>(e.a))) {
          bag.write("/radio/" + b.receiver_id + "/samples", Stamp(b.stamp), RadioMsg(b));
          ++summary.radio_blocks;
        }
      }
    }
    bag.close();
  } catch (const rosbag::BagException& ex) {
    throw IoError(Message("cannot write bag '", path, "': ", ex.what()));
  }
  return summary;
}

}  // namespace ros_adapters
}  // namespace slope_monitor
