// config/defaults/hex_matcher.yaml read by ros_adapters::ReadHexMatcherParameters
// (the nodelet's and process_bag's reader): every key is known, and the
// file's values are the options' in-class defaults (the file documents them;
// the code holds them once). A misspelt key and a bad pair method are named.
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/ros/hex_matcher_parameters.h"
#include "slope_monitor/ros/param_files.h"

namespace slope_monitor {
namespace ros_adapters {
namespace {

XmlRpc::XmlRpcValue Defaults() {
  return LoadParamFile(std::string(SM_SOURCE_DIR) + "/config/defaults/hex_matcher.yaml");
}

TEST(HexMatcherParameters, DefaultsFileHoldsTheOptionsDefaults) {
  XmlRpc::XmlRpcValue file = Defaults();
  SetParam(&file, "mode", std::string("sequence"));
  ParamReader r(file, "/uav/hex_matcher");
  const HexMatcherParameters p = ReadHexMatcherParameters(r);
  const matching::SequenceMatcherOptions d;
  const matching::SequenceMatcherOptions& s = p.sequence;
  EXPECT_EQ(s.method, d.method);
  EXPECT_EQ(s.fallback_shift_hex, d.fallback_shift_hex);
  EXPECT_EQ(s.max_gap, d.max_gap);
  EXPECT_EQ(s.position_prior_max_dt, d.position_prior_max_dt);
  EXPECT_EQ(s.prior_wait, d.prior_wait);
  EXPECT_EQ(s.max_images, d.max_images);
  EXPECT_EQ(s.max_memory_mb, d.max_memory_mb);
  EXPECT_EQ(s.border, d.border);
  EXPECT_EQ(s.pairing.min_overlap, d.pairing.min_overlap);
  EXPECT_EQ(s.pairing.max_pair_distance, d.pairing.max_pair_distance);
  EXPECT_EQ(s.pairing.max_pairs_per_image, d.pairing.max_pairs_per_image);
  EXPECT_EQ(s.pairing.sequence_depth, d.pairing.sequence_depth);
  EXPECT_EQ(s.shift.min_overlap_correlation, d.shift.min_overlap_correlation);
  EXPECT_EQ(s.shift.candidates, d.shift.candidates);
  EXPECT_EQ(s.hex.interest.max_points, d.hex.interest.max_points);
  EXPECT_EQ(s.photo.coarse_max_side, d.photo.coarse_max_side);
  EXPECT_EQ(s.photo.coarse_max_features, d.photo.coarse_max_features);
  EXPECT_EQ(s.photo.coarse_sift_max_side, d.photo.coarse_sift_max_side);
  EXPECT_EQ(s.photo.coarse_contrast_threshold, d.photo.coarse_contrast_threshold);
  EXPECT_EQ(s.photo.interest.max_points, d.photo.interest.max_points);
  EXPECT_EQ(s.photo.interest.cells, d.photo.interest.cells);
  EXPECT_EQ(s.photo_pair.min_coarse_inliers, d.photo_pair.min_coarse_inliers);
  EXPECT_EQ(s.photo_pair.screen_threshold, d.photo_pair.screen_threshold);
  const matching::HexMatcherOptions h;
  EXPECT_EQ(p.hex.interest.max_points, h.interest.max_points);
  EXPECT_EQ(p.hex.min_score, h.min_score);
  EXPECT_EQ(p.hex.lsc.half_window, h.lsc.half_window);
  EXPECT_EQ(p.hex.lsc.min_correlation, h.lsc.min_correlation);
  EXPECT_EQ(p.hex.quality.two_way, h.quality.two_way);
  EXPECT_EQ(p.prior.radius, matching::MatchPrior().radius);
  EXPECT_EQ(p.camera, "uav");
}

TEST(HexMatcherParameters, BadKeysAreNamed) {
  XmlRpc::XmlRpcValue file = Defaults();
  SetParam(&file, "pair_methd", std::string("photo"));
  ParamReader r(file, "/uav/hex_matcher");
  try {
    ReadHexMatcherParameters(r);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("pair_methd"), std::string::npos) << e.what();
  }
  XmlRpc::XmlRpcValue bad = Defaults();
  SetParam(&bad, "pair_method", std::string("sift"));
  ParamReader r2(bad, "/uav/hex_matcher");
  try {
    ReadHexMatcherParameters(r2);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("pair_method"), std::string::npos) << e.what();
  }
}

// The launch's graph_ready flag (replay_start) sits among every node's
// parameters; it is not an unknown key, a misspelt one still is.
TEST(HexMatcherParameters, GraphReadyIsNotAnUnknownKey) {
  XmlRpc::XmlRpcValue file = Defaults();
  SetParam(&file, kGraphReadyParam, false);
  ParamReader r(file, "/uav/hex_matcher");
  EXPECT_NO_THROW(ReadHexMatcherParameters(r));
  XmlRpc::XmlRpcValue bad = Defaults();
  SetParam(&bad, "graph_redy", false);
  ParamReader r2(bad, "/uav/hex_matcher");
  EXPECT_THROW(ReadHexMatcherParameters(r2), ConfigError);
}

// The shipped defaults file leaves estimate_global_shift to the mode (issue
// 19: a track-mode user loading it got false, and its points landed on the
// moving slope): on in track mode, where a turned camera moves every point by
// the same shift, off in pair mode; a value in the file still wins.
TEST(HexMatcherParameters, DefaultsFileLeavesTheGlobalShiftToTheMode) {
  for (const std::string mode : {"track", "pair"}) {
    XmlRpc::XmlRpcValue file = Defaults();
    SetParam(&file, "mode", mode);
    ParamReader r(file, "/fixed_cam_1/hex_matcher");
    EXPECT_EQ(ReadHexMatcherParameters(r).prior.estimate_global_shift, mode == "track") << mode;
  }
  XmlRpc::XmlRpcValue file = Defaults();
  SetParam(&file, "mode", std::string("track"));
  SetParam(&file, "estimate_global_shift", false);
  ParamReader r(file, "/fixed_cam_1/hex_matcher");
  EXPECT_FALSE(ReadHexMatcherParameters(r).prior.estimate_global_shift);
}

}  // namespace
}  // namespace ros_adapters
}  // namespace slope_monitor
