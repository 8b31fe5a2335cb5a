// Bad input gets a clear error naming what is wrong; targets that cannot be
// measured are rejected with a reason (rendered with planar_target_renderer.h).
#include <fstream>
#include <map>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "planar_target_renderer.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/yaml_map.h"
#include "slope_monitor/core/targets/options_reader.h"
#include "slope_monitor/core/targets/target_centroider.h"

namespace slope_monitor {
namespace targets {
namespace {

template <typename E, typename F>
std::string ErrorOf(F f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "";
}

// A disc of `diameter` px centred at (cx, cy) on a ring, nadir view, no noise.
cv::Mat Disc(int w, int h, double cx, double cy, double diameter, double gain = 240.0) {
  const camera::CameraModel cam = testing::NadirCamera(w, h, 1000.0);
  camera::ExteriorOrientation pose;
  pose.position = Eigen::Vector3d(0, 0, 10.0);
  const double m_per_px = 10.0 / 1000.0;
  testing::Plate plate;
  plate.centre =
      Eigen::Vector3d((cx - 0.5 * (w - 1)) * m_per_px, -(cy - 0.5 * (h - 1)) * m_per_px, 0.0);
  testing::RenderOptions ro;
  ro.gain = gain;
  cv::Mat f = testing::Background(w, h, ro);
  testing::RenderPlate(&f, testing::PlaneToPixel(cam, pose, plate),
                       testing::CirclePattern(diameter * m_per_px), diameter * m_per_px, ro);
  return testing::ToMono8(f, ro);
}

Options BadInputCirclesOnly() {
  Options o;
  o.families.clear();
  return o;
}

TEST(BadInput, WrongEncodingIsNamed) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  const cv::Mat img(20, 20, CV_8UC1, cv::Scalar(0));
  const std::string msg = ErrorOf<InvalidArgument>([&] { c.Detect(img, "yuv422"); });
  EXPECT_NE(msg.find("'yuv422'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("mono8"), std::string::npos) << msg;  // lists what is supported
}

TEST(BadInput, EmptyImage) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  const std::string msg = ErrorOf<InvalidArgument>([&] { c.Detect(cv::Mat(), "mono8"); });
  EXPECT_NE(msg.find("empty"), std::string::npos) << msg;
}

TEST(BadInput, TypeNotMatchingEncoding) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  const cv::Mat img(20, 20, CV_8UC3, cv::Scalar(0, 0, 0));
  const std::string msg = ErrorOf<InvalidArgument>([&] { c.Detect(img, "mono16"); });
  EXPECT_NE(msg.find("mono16"), std::string::npos) << msg;
  EXPECT_NE(msg.find("3 channel"), std::string::npos) << msg;
}

TEST(BadInput, CameraInfoSizeMismatchNamesBothSizes) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  const cv::Mat img(48, 64, CV_8UC1, cv::Scalar(0));
  ViewGeometry view{testing::NadirCamera(640, 480, 500.0), camera::ExteriorOrientation()};
  const std::string msg = ErrorOf<InvalidArgument>([&] { c.Detect(img, "mono8", &view); });
  EXPECT_NE(msg.find("64x48"), std::string::npos) << msg;
  EXPECT_NE(msg.find("640x480"), std::string::npos) << msg;
}

TEST(BadInput, DuplicateIdInTargetListNamesFileAndId) {
  const std::string path = ::testing::TempDir() + "/dup_targets.yaml";
  std::ofstream(path) << "frame: site\ntargets:\n"
                         "  - {id: 3, family: tag36h11, size: 0.5, role: monitoring}\n"
                         "  - {id: 3, family: tag36h11, size: 0.5, role: monitoring}\n";
  const std::string msg = ErrorOf<ConfigError>([&] { io::TargetList::Load(path); });
  EXPECT_NE(msg.find("dup_targets.yaml"), std::string::npos) << msg;
  EXPECT_NE(msg.find("3"), std::string::npos) << msg;
}

// The nodelet's first check of every image message (before cv_bridge).
TEST(BadInput, ImageMessageChecksNameTheTopic) {
  const std::string topic = "/cam_1/image_raw";
  EXPECT_NO_THROW(CheckImageInput(topic, 640, 480, "mono8", 640, 480));
  std::string msg =
      ErrorOf<InvalidArgument>([&] { CheckImageInput(topic, 640, 480, "yuv422", 640, 480); });
  EXPECT_NE(msg.find(topic), std::string::npos) << msg;
  EXPECT_NE(msg.find("'yuv422'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("bayer_rggb8"), std::string::npos) << msg;  // lists what is supported
  msg = ErrorOf<InvalidArgument>([&] { CheckImageInput(topic, 0, 0, "mono8", 640, 480); });
  EXPECT_NE(msg.find(topic), std::string::npos) << msg;
  EXPECT_NE(msg.find("empty"), std::string::npos) << msg;
  msg = ErrorOf<InvalidArgument>([&] { CheckImageInput(topic, 640, 480, "mono8", 1280, 720); });
  EXPECT_NE(msg.find(topic), std::string::npos) << msg;
  EXPECT_NE(msg.find("640x480"), std::string::npos) << msg;
  EXPECT_NE(msg.find("1280x720"), std::string::npos) << msg;
  EXPECT_NE(msg.find("camera_info"), std::string::npos) << msg;
}

// A bad image does not break the centroider: the next good one is measured.
TEST(BadInput, GoodImageAfterBadOnesIsMeasured) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  EXPECT_THROW(c.Detect(cv::Mat(), "mono8"), InvalidArgument);
  EXPECT_THROW(c.Detect(cv::Mat(30, 30, CV_8UC1, cv::Scalar(0)), "32FC1"), InvalidArgument);
  ViewGeometry view{testing::NadirCamera(640, 480, 500.0), camera::ExteriorOrientation()};
  EXPECT_THROW(c.Detect(cv::Mat(48, 64, CV_8UC1, cv::Scalar(0)), "mono8", &view), InvalidArgument);
  const Result r = c.Detect(Disc(120, 100, 60.3, 50.7, 24.0), "mono8");
  ASSERT_EQ(r.observations.size(), 1u);
  EXPECT_NEAR(r.observations[0].centre.x(), 60.3, 0.01);
  EXPECT_NEAR(r.observations[0].centre.y(), 50.7, 0.01);
}

TEST(BadInput, MonoImageOfWrongTypeIsNamed) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  MonoImage m;
  m.mono8 = cv::Mat(20, 20, CV_16UC1, cv::Scalar(0));
  EXPECT_NE(ErrorOf<InvalidArgument>([&] { c.DetectMono(m); }).find("mono8"), std::string::npos);
  m = MonoImage();
  EXPECT_NE(ErrorOf<InvalidArgument>([&] { c.DetectMono(m); }).find("empty"), std::string::npos);
}

TEST(BadInput, DuplicateIdAddedInCodeIsNamed) {
  io::TargetList list;
  io::TargetSpec spec;
  spec.id = 12;
  spec.family = "circle";
  spec.size = 0.3;
  list.Add(spec);
  const std::string msg = ErrorOf<InvalidArgument>([&] { list.Add(spec); });
  EXPECT_NE(msg.find("12"), std::string::npos) << msg;
}

// One options reader for the nodelet (ParamReader) and the tool (YamlMap):
// the shipped defaults file reads completely and equals the in-class defaults.
TEST(OptionsReader, ShippedDefaultsEqualTheInClassDefaults) {
  io::YamlMap m =
      io::YamlMap::Load(std::string(SM_SOURCE_DIR) + "/config/defaults/target_centroider.yaml");
  const Options o = ReadOptions(m);
  const NodeOptions n = ReadNodeOptions(m);
  EXPECT_NO_THROW(m.CheckNoUnknownKeys());
  const Options d;
  EXPECT_EQ(o.families, d.families);
  EXPECT_EQ(o.quad_decimate, d.quad_decimate);
  EXPECT_EQ(o.quad_sigma, d.quad_sigma);
  EXPECT_EQ(o.refine_edges, d.refine_edges);
  EXPECT_EQ(o.decode_sharpening, d.decode_sharpening);
  EXPECT_EQ(o.threads, d.threads);
  EXPECT_EQ(o.max_hamming, d.max_hamming);
  EXPECT_EQ(o.min_decision_margin, d.min_decision_margin);
  EXPECT_EQ(o.refine_tags, d.refine_tags);
  EXPECT_EQ(o.tag_refine_max_residual, d.tag_refine_max_residual);
  EXPECT_EQ(o.tag_refine_max_sigma, d.tag_refine_max_sigma);
  EXPECT_EQ(o.circle_ring_ratio, d.circle_ring_ratio);
  EXPECT_EQ(o.circle_ring_ratio_tolerance, d.circle_ring_ratio_tolerance);
  EXPECT_EQ(o.circle_max_residual, d.circle_max_residual);
  EXPECT_EQ(o.circle_size_tolerance, d.circle_size_tolerance);
  EXPECT_EQ(o.detect_circles, d.detect_circles);
  EXPECT_EQ(o.circle_min_diameter, d.circle_min_diameter);
  EXPECT_EQ(o.circle_max_diameter, d.circle_max_diameter);
  EXPECT_EQ(o.circle_max_eccentricity, d.circle_max_eccentricity);
  EXPECT_EQ(o.circle_id_gate, d.circle_id_gate);
  EXPECT_EQ(o.refine_circles, d.refine_circles);
  EXPECT_EQ(o.correct_perspective, d.correct_perspective);
  EXPECT_EQ(o.min_contrast, d.min_contrast);
  EXPECT_EQ(o.border_margin, d.border_margin);
  EXPECT_EQ(o.saturation_level, d.saturation_level);
  EXPECT_EQ(o.max_saturated_fraction, d.max_saturated_fraction);
  EXPECT_EQ(o.max_edge_blur, d.max_edge_blur);
  EXPECT_EQ(o.max_residual, d.max_residual);
  EXPECT_EQ(o.max_dark_surround, d.max_dark_surround);
  EXPECT_EQ(o.noise_floor, d.noise_floor);
  const NodeOptions nd;
  EXPECT_EQ(n.target_list, nd.target_list);
  EXPECT_EQ(n.site_frame, nd.site_frame);
  EXPECT_EQ(n.queue_size, nd.queue_size);
  EXPECT_EQ(n.pixel_size, nd.pixel_size);
}

TEST(OptionsReader, BadKeysAreNamed) {
  {
    io::YamlMap m = io::YamlMap::Parse("quad_decimate: 9.0\n", "bad.yaml");
    const std::string msg = ErrorOf<ConfigError>([&] { ReadOptions(m); });
    EXPECT_NE(msg.find("quad_decimate"), std::string::npos) << msg;
  }
  {
    io::YamlMap m = io::YamlMap::Parse("quad_decimat: 2.0\n", "bad.yaml");
    ReadOptions(m);
    ReadNodeOptions(m);
    const std::string msg = ErrorOf<ConfigError>([&] { m.CheckNoUnknownKeys(); });
    EXPECT_NE(msg.find("quad_decimat"), std::string::npos) << msg;
    EXPECT_NE(msg.find("bad.yaml"), std::string::npos) << msg;
  }
}

TEST(BadInput, BadOptionsAreNamed) {
  Options o;
  o.families = {"tag99h1"};
  EXPECT_NE(ErrorOf<ConfigError>([&] { TargetCentroider c(o, io::TargetList()); }).find("tag99h1"),
            std::string::npos);
  o = Options();
  o.quad_decimate = 0.5;
  EXPECT_NE(ErrorOf<ConfigError>([&] { o.Check(); }).find("quad_decimate"), std::string::npos);
}

TEST(Encodings, AllSupportedEncodingsGiveTheSameCentre) {
  const cv::Mat mono = Disc(120, 100, 60.3, 50.7, 24.0);
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  const Result ref = c.Detect(mono, "mono8");
  ASSERT_EQ(ref.observations.size(), 1u);
  EXPECT_NEAR(ref.observations[0].centre.x(), 60.3, 0.01);
  EXPECT_NEAR(ref.observations[0].centre.y(), 50.7, 0.01);
  EXPECT_FALSE(
      ref.observations[0].role.has_value());  // not in the (empty) list: unknown, not dropped
  cv::Mat bgr, rgb, m16;
  cv::cvtColor(mono, bgr, cv::COLOR_GRAY2BGR);
  cv::cvtColor(mono, rgb, cv::COLOR_GRAY2RGB);
  mono.convertTo(m16, CV_16U, 257.0);
  // Bayer: a grey scene seen through an RGGB mosaic is the grey image itself.
  for (const auto& [img, enc] : std::vector<std::pair<cv::Mat, std::string>>{
           {bgr, "bgr8"}, {rgb, "rgb8"}, {m16, "mono16"}, {mono, "bayer_rggb8"}}) {
    const Result r = c.Detect(img, enc);
    ASSERT_EQ(r.observations.size(), 1u) << enc;
    EXPECT_NEAR((r.observations[0].centre - ref.observations[0].centre).norm(), 0.0,
                enc == "bayer_rggb8" ? 0.05 : 0.002)
        << enc;
  }
}

// The reasons given for circle candidates: an unlisted candidate that fails
// is "not a target" (Result::discarded, the debug output), a listed one a
// rejection; here the list is empty, so the reason is in either.
std::map<std::string, int> Reasons(const Result& r) {
  std::map<std::string, int> out;
  for (const auto& rj : r.rejections) out[RejectReasonName(rj.reason)]++;
  for (const auto& rj : r.discarded) out[RejectReasonName(rj.reason)]++;
  return out;
}

TEST(Rejections, BorderSaturatedBlurredPartial) {
  TargetCentroider c(BadInputCirclesOnly(), io::TargetList());
  // Truncated by the border.
  {
    const Result r = c.Detect(Disc(100, 100, 8.0, 50.0, 24.0), "mono8");
    EXPECT_TRUE(r.observations.empty());
    ASSERT_EQ(Reasons(r).count("border"), 1u) << "border";
  }
  // Saturated: gain so high the disc clips at 255.
  {
    const Result r = c.Detect(Disc(100, 100, 50.0, 50.0, 24.0, 400.0), "mono8");
    EXPECT_TRUE(r.observations.empty());
    EXPECT_EQ(Reasons(r).count("saturated"), 1u) << "saturated";
  }
  // Blurred: Gaussian blur sigma 3 px.
  {
    cv::Mat img = Disc(100, 100, 50.0, 50.0, 30.0), blurred;
    cv::GaussianBlur(img, blurred, cv::Size(0, 0), 3.0);
    const Result r = c.Detect(blurred, "mono8");
    EXPECT_TRUE(r.observations.empty());
    EXPECT_EQ(Reasons(r).count("blurred"), 1u) << "blurred";
  }
  // Partial: a bright bar over one side of the ring (occlusion).
  {
    cv::Mat img = Disc(100, 100, 50.0, 50.0, 24.0);
    cv::rectangle(img, cv::Rect(65, 30, 6, 40), cv::Scalar(200), cv::FILLED);
    const Result r = c.Detect(img, "mono8");
    EXPECT_TRUE(r.observations.empty());
    EXPECT_EQ(Reasons(r).count("partial"), 1u) << "partial";
  }
}

}  // namespace
}  // namespace targets
}  // namespace slope_monitor
