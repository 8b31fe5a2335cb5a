#include "slope_monitor/core/targets/target_centroider.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <mutex>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h10.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagCircle49h12.h>
#include <apriltag/tagCustom48h12.h>
#include <apriltag/tagStandard41h12.h>
#include <apriltag/tagStandard52h13.h>

#include "centroider_stages.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace targets {
namespace {

struct FamilyFactory {
  apriltag_family_t* (*create)();
  void (*destroy)(apriltag_family_t*);
};

const std::map<std::string, FamilyFactory>& Factories() {
  static const std::map<std::string, FamilyFactory> f = {
      {"tag36h11", {tag36h11_create, tag36h11_destroy}},
      {"tag36h10", {tag36h10_create, tag36h10_destroy}},
      {"tag25h9", {tag25h9_create, tag25h9_destroy}},
      {"tag16h5", {tag16h5_create, tag16h5_destroy}},
      {"tagStandard41h12", {tagStandard41h12_create, tagStandard41h12_destroy}},
      {"tagStandard52h13", {tagStandard52h13_create, tagStandard52h13_destroy}},
      {"tagCircle21h7", {tagCircle21h7_create, tagCircle21h7_destroy}},
      {"tagCircle49h12", {tagCircle49h12_create, tagCircle49h12_destroy}},
      {"tagCustom48h12", {tagCustom48h12_create, tagCustom48h12_destroy}},
  };
  return f;
}

}  // namespace

// ---------------------------------------------------------------------------
void Options::Check() const {
  auto fail = [](const std::string& key, const std::string& what) {
    throw ConfigError(Message("targets option '", key, "' ", what));
  };
  if (families.empty() && !detect_circles)
    fail("families", "is empty and detect_circles is false: nothing to detect");
  for (const auto& f : families) {
    if (!Factories().count(f)) fail("families", "has unknown tag family '" + f + "'");
  }
  if (!(quad_decimate >= 1.0 && quad_decimate <= 8.0))
    fail("quad_decimate", Message("= ", quad_decimate, " is outside [1, 8]"));
  if (!(quad_sigma >= 0.0 && quad_sigma <= 10.0))
    fail("quad_sigma", Message("= ", quad_sigma, " px is outside [0, 10]"));
  if (!(decode_sharpening >= 0.0 && decode_sharpening <= 10.0))
    fail("decode_sharpening", Message("= ", decode_sharpening, " is outside [0, 10]"));
  if (threads < 1 || threads > 64) fail("threads", Message("= ", threads, " is outside [1, 64]"));
  if (max_hamming < 0 || max_hamming > 3)
    fail("max_hamming", Message("= ", max_hamming, " is outside [0, 3]"));
  if (!(min_decision_margin >= 0.0)) fail("min_decision_margin", "must be >= 0");
  if (!(circle_min_diameter >= 4.0 && circle_min_diameter <= circle_max_diameter))
    fail("circle_min_diameter",
         Message("= ", circle_min_diameter, " px must be in [4, circle_max_diameter]"));
  if (!(circle_max_diameter <= 2000.0))
    fail("circle_max_diameter", Message("= ", circle_max_diameter, " px is over 2000"));
  if (!(circle_max_eccentricity > 0.0 && circle_max_eccentricity < 1.0))
    fail("circle_max_eccentricity", "must be in (0, 1)");
  if (!(circle_id_gate > 0.0 && circle_id_gate <= 5.0)) fail("circle_id_gate", "must be in (0, 5]");
  if (!(min_contrast > 0.0 && min_contrast < 255.0))
    fail("min_contrast", Message("= ", min_contrast, " DN is outside (0, 255)"));
  if (!(border_margin >= 0.0 && border_margin <= 100.0))
    fail("border_margin", "must be in [0, 100] px");
  if (!(saturation_level > 0.0 && saturation_level <= 255.0))
    fail("saturation_level", "must be in (0, 255] DN");
  if (!(max_saturated_fraction >= 0.0 && max_saturated_fraction <= 1.0))
    fail("max_saturated_fraction", "must be in [0, 1]");
  if (!(max_edge_blur > 0.0 && max_edge_blur <= 20.0))
    fail("max_edge_blur", "must be in (0, 20] px");
  if (!(max_residual > 0.0 && max_residual <= 1.0)) fail("max_residual", "must be in (0, 1]");
  if (!(max_dark_surround > 0.0 && max_dark_surround <= 1.0))
    fail("max_dark_surround", "must be in (0, 1]");
  if (!(noise_floor >= 0.0 && noise_floor <= 50.0)) fail("noise_floor", "must be in [0, 50] DN");
  if (!(tag_refine_max_residual > 0.0 && tag_refine_max_residual <= 1.0))
    fail("tag_refine_max_residual", "must be in (0, 1]");
  if (!(tag_refine_max_sigma > 0.0 && tag_refine_max_sigma <= 10.0))
    fail("tag_refine_max_sigma", "must be in (0, 10] px");
  if (!(circle_ring_ratio > 1.0 && circle_ring_ratio <= 10.0))
    fail("circle_ring_ratio", Message("= ", circle_ring_ratio, " is outside (1, 10]"));
  if (!(circle_ring_ratio_tolerance > 0.0 && circle_ring_ratio_tolerance <= 1.0))
    fail("circle_ring_ratio_tolerance", "must be in (0, 1]");
  if (!(circle_max_residual > 0.0 && circle_max_residual <= 1.0))
    fail("circle_max_residual", "must be in (0, 1]");
  if (!(circle_size_tolerance > 0.0 && circle_size_tolerance <= 1.0))
    fail("circle_size_tolerance", "must be in (0, 1]");
}

std::string CircleDesignName(CircleDesign design) {
  switch (design) {
    case CircleDesign::kAuto:
      return "auto";
    case CircleDesign::kDiscInRing:
      return "disc_in_ring";
    case CircleDesign::kDot:
      return "dot";
    case CircleDesign::kRing:
      return "ring";
    case CircleDesign::kConcentric:
      return "concentric";
  }
  return "unknown";
}

CircleDesign ParseCircleDesign(const std::string& name, const std::string& key) {
  for (CircleDesign d : {CircleDesign::kAuto, CircleDesign::kDiscInRing, CircleDesign::kDot,
                         CircleDesign::kRing, CircleDesign::kConcentric}) {
    if (CircleDesignName(d) == name) return d;
  }
  throw ConfigError(
      Message("targets option '", key, "' = '", name,
              "' is not a circle design (auto, disc_in_ring, dot, ring, concentric)"));
}

std::string RejectReasonName(RejectReason reason) {
  switch (reason) {
    case RejectReason::kBorder:
      return "border";
    case RejectReason::kSaturated:
      return "saturated";
    case RejectReason::kBlurred:
      return "blurred";
    case RejectReason::kPartial:
      return "partial";
    case RejectReason::kLowContrast:
      return "low_contrast";
    case RejectReason::kWeakDecode:
      return "weak_decode";
    case RejectReason::kFitFailed:
      return "fit_failed";
    case RejectReason::kNotDisc:
      return "not_disc";
    case RejectReason::kDesign:
      return "design";
    case RejectReason::kResidual:
      return "residual";
    case RejectReason::kSize:
      return "size";
  }
  return "unknown";
}

std::string CentreMethodName(CentreMethod method) {
  switch (method) {
    case CentreMethod::kEdgeModel:
      return "edge_model";
    case CentreMethod::kDetector:
      return "detector";
    case CentreMethod::kEllipseModel:
      return "ellipse_model";
    case CentreMethod::kGrayCentroid:
      return "gray_centroid";
    case CentreMethod::kRingCentre:
      return "ring_centre";
  }
  return "unknown";
}

const std::vector<std::string>& SupportedEncodings() {
  static const std::vector<std::string> e = {
      "mono8",        "mono16",       "bgr8",         "rgb8",        "bgra8",
      "rgba8",        "bayer_rggb8",  "bayer_bggr8",  "bayer_gbrg8", "bayer_grbg8",
      "bayer_rggb16", "bayer_bggr16", "bayer_gbrg16", "bayer_grbg16"};
  return e;
}

MonoImage ToMono(const cv::Mat& image, const std::string& encoding) {
  const auto& enc = SupportedEncodings();
  if (std::find(enc.begin(), enc.end(), encoding) == enc.end()) {
    std::string list;
    for (const auto& e : enc) list += (list.empty() ? "" : ", ") + e;
    throw InvalidArgument(
        Message("image encoding '", encoding, "' is not supported (supported: ", list, ")"));
  }
  if (image.empty() || image.cols < 2 || image.rows < 2) {
    throw InvalidArgument(
        Message("image is empty (", image.cols, "x", image.rows, ", encoding '", encoding, "')"));
  }
  auto need = [&](int type) {
    if (image.type() != type) {
      throw InvalidArgument(Message("image of encoding '", encoding, "' has ", image.channels(),
                                    " channel(s) of depth ", image.depth(),
                                    ", which does not match the encoding"));
    }
  };
  MonoImage out;
  cv::Mat gray;  // 8U or 16U
  const bool is16 =
      encoding == "mono16" || (encoding.size() > 2 && encoding.substr(encoding.size() - 2) == "16");
  if (encoding == "mono8" || encoding == "mono16") {
    need(is16 ? CV_16UC1 : CV_8UC1);
    gray = image;  // no copy
  } else if (encoding == "bgr8" || encoding == "rgb8") {
    need(CV_8UC3);
    cv::cvtColor(image, gray, encoding == "bgr8" ? cv::COLOR_BGR2GRAY : cv::COLOR_RGB2GRAY);
  } else if (encoding == "bgra8" || encoding == "rgba8") {
    need(CV_8UC4);
    cv::cvtColor(image, gray, encoding == "bgra8" ? cv::COLOR_BGRA2GRAY : cv::COLOR_RGBA2GRAY);
  } else {
    need(is16 ? CV_16UC1 : CV_8UC1);
    // ROS bayer names give the pattern of the top-left 2x2; OpenCV names it by
    // the second row's middle pair (cv_bridge uses the same mapping).
    const std::string pattern = encoding.substr(6, 4);
    int code = cv::COLOR_BayerBG2BGR;
    if (pattern == "rggb") code = cv::COLOR_BayerBG2BGR;
    if (pattern == "bggr") code = cv::COLOR_BayerRG2BGR;
    if (pattern == "gbrg") code = cv::COLOR_BayerGR2BGR;
    if (pattern == "grbg") code = cv::COLOR_BayerGB2BGR;
    cv::Mat bgr;
    cv::cvtColor(image, bgr, code);
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  }
  if (gray.depth() == CV_16U) {
    gray.convertTo(out.intensity, CV_32F, 1.0 / 257.0);
    gray.convertTo(out.mono8, CV_8U, 1.0 / 257.0);
    out.quantisation = 1.0 / 257.0;
  } else {
    out.mono8 = gray;  // measured directly: no float copy
    out.quantisation = 1.0;
  }
  return out;
}

void CheckImageInput(const std::string& topic, int width, int height, const std::string& encoding,
                     int info_width, int info_height) {
  if (width <= 0 || height <= 0) {
    throw InvalidArgument(Message("image on '", topic, "' is empty (", width, "x", height,
                                  ", encoding '", encoding, "')"));
  }
  const auto& enc = SupportedEncodings();
  if (std::find(enc.begin(), enc.end(), encoding) == enc.end()) {
    std::string list;
    for (const auto& e : enc) list += (list.empty() ? "" : ", ") + e;
    throw InvalidArgument(Message("image on '", topic, "' has encoding '", encoding,
                                  "', which is not supported (supported: ", list, ")"));
  }
  if (width != info_width || height != info_height) {
    throw InvalidArgument(Message("image on '", topic, "' is ", width, "x", height,
                                  " px but its camera_info is ", info_width, "x", info_height,
                                  " px"));
  }
}

// ---------------------------------------------------------------------------
// libapriltag state and the per-frame work buffers (kept between frames so a
// frame allocates no large buffers once the image size is steady).
struct TargetCentroider::Detector {
  apriltag_detector_t* td = nullptr;
  std::vector<std::pair<apriltag_family_t*, void (*)(apriltag_family_t*)>> families;
  std::mutex mutex;  // libapriltag's detector is not re-entrant; guards the buffers too
  detail::CandidateBuffers candidates;  // circle candidates (one pyramid level)
  detail::Pixels px;                    // fit pixels
};

TargetCentroider::TargetCentroider(const Options& options, const io::TargetList& targets)
    : options_(options), targets_(targets) {
  options_.Check();
  detector_ = new Detector;
  detector_->td = apriltag_detector_create();
  detector_->td->quad_decimate = static_cast<float>(options_.quad_decimate);
  detector_->td->quad_sigma = static_cast<float>(options_.quad_sigma);
  detector_->td->refine_edges = options_.refine_edges;
  detector_->td->decode_sharpening = options_.decode_sharpening;
  detector_->td->nthreads = options_.threads;
  for (const auto& name : options_.families) {
    const FamilyFactory& f = Factories().at(name);
    apriltag_family_t* fam = f.create();
    detector_->families.emplace_back(fam, f.destroy);
    apriltag_detector_add_family_bits(detector_->td, fam, options_.max_hamming);
  }
}

TargetCentroider::~TargetCentroider() {
  if (!detector_) return;
  apriltag_detector_destroy(detector_->td);
  for (auto& f : detector_->families) f.second(f.first);
  delete detector_;
}

Result TargetCentroider::Detect(const cv::Mat& image, const std::string& encoding,
                                const ViewGeometry* view) const {
  return DetectMono(ToMono(image, encoding), view);
}

bool TargetCentroider::GrayWeightedCentroid(const cv::Mat& intensity, const Eigen::Vector2d& seed,
                                            double radius, Eigen::Vector2d* centroid) {
  if (intensity.channels() != 1 || (intensity.depth() != CV_8U && intensity.depth() != CV_32F))
    return false;
  const detail::ImageView im(intensity);
  const int x0 = static_cast<int>(std::floor(seed.x() - radius)),
            x1 = static_cast<int>(std::ceil(seed.x() + radius));
  const int y0 = static_cast<int>(std::floor(seed.y() - radius)),
            y1 = static_cast<int>(std::ceil(seed.y() + radius));
  if (x0 < 0 || y0 < 0 || x1 >= intensity.cols || y1 >= intensity.rows) return false;
  std::vector<float> sorted;
  sorted.reserve(static_cast<size_t>(x1 - x0 + 1) * (y1 - y0 + 1));
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) sorted.push_back(im.At(x, y));
  std::sort(sorted.begin(), sorted.end());
  const double dark = sorted[sorted.size() / 10], bright = sorted[sorted.size() * 9 / 10];
  if (bright - dark <= 1e-6) return false;
  const double threshold = 0.5 * (dark + bright);
  double sq = 0, sx = 0, sy = 0;
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const double v = im.At(x, y);
      const double q = v >= threshold ? v : 0.0;
      sq += q;
      sx += q * x;
      sy += q * y;
    }
  }
  if (sq <= 0) return false;
  *centroid = Eigen::Vector2d(sx / sq, sy / sq);
  return true;
}

Result TargetCentroider::DetectMono(const MonoImage& mono, const ViewGeometry* view) const {
  if (mono.mono8.empty() && mono.intensity.empty()) throw InvalidArgument("image is empty");
  if (!mono.intensity.empty() && mono.intensity.type() != CV_32FC1) {
    throw InvalidArgument(
        Message("MonoImage.intensity must be CV_32FC1, got type ", mono.intensity.type()));
  }
  if (!mono.mono8.empty() && mono.mono8.type() != CV_8UC1) {
    throw InvalidArgument(Message("MonoImage.mono8 must be CV_8UC1, got type ", mono.mono8.type()));
  }
  // What is measured: the float intensity of deep inputs, else mono8 itself.
  cv::Mat mono8 = mono.mono8;
  if (mono8.empty()) mono.intensity.convertTo(mono8, CV_8U);
  const cv::Mat& meas = mono.intensity.empty() ? mono8 : mono.intensity;
  if (meas.cols < 2 || meas.rows < 2) {
    throw InvalidArgument(Message("image is empty (", meas.cols, "x", meas.rows, ")"));
  }
  if (!mono.intensity.empty() && mono.intensity.size() != mono8.size()) {
    throw InvalidArgument(Message("MonoImage.mono8 is ", mono8.cols, "x", mono8.rows,
                                  " but intensity is ", mono.intensity.cols, "x",
                                  mono.intensity.rows));
  }
  if (view) {
    const auto& s = view->camera.sensor();
    if (s.width != meas.cols || s.height != meas.rows) {
      throw InvalidArgument(Message("image is ", meas.cols, "x", meas.rows,
                                    " px but the camera model (camera_info) is ", s.width, "x",
                                    s.height, " px"));
    }
  }
  Detector& D = *detector_;
  std::lock_guard<std::mutex> lock(D.mutex);
  const double noise_floor =
      options_.noise_floor > 0 ? options_.noise_floor : mono.quantisation / std::sqrt(12.0);
  detail::Frame frame(meas, options_, noise_floor);
  for (const auto& t : targets_.targets())
    frame.listed_circles = frame.listed_circles || t.family == "circle";
  // The stages (centroider_stages.h).
  if (!options_.families.empty()) detail::DetectTags(D.td, mono8, targets_, &D.px, &frame);
  if (options_.detect_circles) {
    // Markers of three or more rings first; the other designs' candidates
    // inside one are parts of it.
    std::vector<detail::RingMarker> rings;
    if (options_.circle_design == CircleDesign::kAuto ||
        options_.circle_design == CircleDesign::kConcentric)
      detail::AddRingMarkers(mono8, targets_, &frame, &rings);
    detail::FindBrightComponents(mono8, &D.candidates, &frame);
    const std::vector<detail::ExpectedCircle> expected =
        detail::ProjectListedCircles(view, targets_);
    for (int label = 1; label < D.candidates.n; ++label) {
      detail::Blob blob;
      if (!detail::CandidateBlob(D.candidates, label, &frame, &blob)) continue;
      if (detail::InsideRingMarker(rings, blob.centre)) {
        frame.Discard(blob.centre, RejectReason::kDesign, "inside a ring marker");
        continue;
      }
      detail::MeasureCircle(blob, detail::IdentifyCircle(expected, blob, options_), view, &D.px,
                            &frame);
    }
    detail::DropNestedCircles(&frame.res);
  }
  if (!frame.residuals.empty())
    frame.res.summary.noise_estimate = detail::Percentile(frame.residuals, 0.5);
  return std::move(frame.res);
}

cv::Mat DrawResult(const cv::Mat& mono8, const Result& result) {
  cv::Mat out;
  if (mono8.channels() == 1) {
    cv::cvtColor(mono8, out, cv::COLOR_GRAY2BGR);
  } else {
    out = mono8.clone();
  }
  auto pt = [](const Eigen::Vector2d& p) {
    return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  };
  for (const auto& o : result.observations) {
    const cv::Scalar colour = o.role ? cv::Scalar(0, 220, 0) : cv::Scalar(0, 220, 220);
    if (o.has_corners) {
      for (int k = 0; k < 4; ++k)
        cv::line(out, pt(o.corners[k]), pt(o.corners[(k + 1) % 4]), colour, 1);
    } else {
      cv::circle(out, pt(o.centre), static_cast<int>(std::lround(0.5 * o.size_px)), colour, 1);
    }
    cv::drawMarker(out, pt(o.centre), colour, cv::MARKER_CROSS, 7, 1);
    cv::putText(out, o.Key(), pt(o.centre + Eigen::Vector2d(4, -4)), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                colour, 1);
  }
  for (const auto& r : result.rejections) {
    cv::drawMarker(out, pt(r.where), cv::Scalar(0, 0, 255), cv::MARKER_TILTED_CROSS, 9, 1);
    cv::putText(out, RejectReasonName(r.reason), pt(r.where + Eigen::Vector2d(4, 10)),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 255), 1);
  }
  return out;
}

}  // namespace targets
}  // namespace slope_monitor
