// Target centroider: AprilTags and circular targets (a bright disc in a dark
// ring, a light dot on a dark ground, a dark ring with a light centre,
// concentric or coded rings: Options::circle_design) to sub-pixel centres with a covariance, a
// quality and, for targets that cannot be measured, a rejection reason.
//
//   targets::TargetCentroider centroider(options, target_list);
//   targets::Result r = centroider.Detect(image, "mono8");            // no pose known
//   targets::Result r = centroider.Detect(image, "bgr8", &view);      // with camera + approximate
//   pose
//
// Pixel convention (everywhere in this module): OpenCV's, column right, row
// down, (0, 0) the centre of the top-left pixel. libapriltag uses a
// convention shifted by half a pixel ((0.5, 0.5) is the centre of the
// top-left pixel, checked on rendered tags in
// test/core/targets/apriltag_test.cpp); its corners and centre are converted
// by subtracting 0.5 px.
//
// AprilTags: libapriltag finds and decodes the quads; then each of the four
// outer edges of the black border is re-measured by fitting a blurred-step
// intensity model to the pixels around it (line angle, offset, the two
// grey levels, blur), the corners are the intersections of adjacent edges,
// and the centre is the intersection of the diagonals (the image of the tag
// centre under the tag's homography, not the corner mean). The covariance of
// the centre is propagated from the covariances of the four line fits. Per
// tag, these corners replace libapriltag's only where the edge model explains
// the pixels (residual, covariance: Options::tag_refine_max_residual,
// tag_refine_max_sigma); otherwise libapriltag's corners are published
// (Observation::method says which; doc/targets_real_photos.md).
//
// Circles: blobs of a locally thresholded image with a dark surround (the
// light centre of every design); the design is told by 32 rays from the
// blob's centre (where the dark part around the light centre ends); then
// the gray-weighted centroid of doc/design.md (automatic threshold halfway
// between the disc and ring levels, pixels under it set to 0,
// intensity-weighted mean); then a least-squares fit of a blurred elliptical
// disc intensity model (centre, ellipse shape, the two grey levels, blur) to
// the pixels around the edge, started from the centroid. The centre of the
// imaged ellipse is not the image of the circle's centre under perspective;
// when the camera model, an approximate pose and the target's position and
// plane normal are known the bias (ellipse centre minus projected centre,
// computed from the model) is removed.
//
// Covariances come from the image noise (the fit's residual, floored at the
// quantisation noise of the input) and the geometry of the fit (target
// size, edge contrast, blur): sigma^2 (J^T J)^-1 of the fitted centre.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/camera/camera_model.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace targets {

// Circular target designs. Every design has a light centre (a disc) with
// something dark around it; they differ in where the dark part ends, seen
// along 32 rays from the centre (in radii of the light centre):
//   kDiscInRing  the dark ring ends at circle_ring_ratio (the simulator's plates);
//   kDot         a light dot on a dark ground: dark out to 2.5 radii at least
//                (retro-reflective dots on a black plate);
//   kRing        a dark ring with a light centre: the ring's outer edge at one
//                ratio (1.2..4) on most rays, light beyond;
//   kConcentric  two or more dark rings (or a coded ring, e.g. ringgrid's
//                markers): light between them on a quarter of the rays at
//                least; the outermost edge at one ratio on most rays.
// One target per marker: its centre is the centre of the light centre
// (common to all rings); a smaller candidate inside an accepted marker's
// outer edge is dropped. kAuto (the default) accepts any of them, trying
// kDiscInRing first.
enum class CircleDesign { kAuto, kDiscInRing, kDot, kRing, kConcentric };
std::string CircleDesignName(
    CircleDesign design);  // "auto", "disc_in_ring", "dot", "ring", "concentric"
// Throws ConfigError naming `key` and the allowed names.
CircleDesign ParseCircleDesign(const std::string& name, const std::string& key = "circle_design");

// How to find and measure targets. Units in the comments; Check() throws
// ConfigError naming the field.
struct Options {
  // --- AprilTags (libapriltag) ---
  // Chosen on the real photographs of test/data/apriltag_real/ and on the
  // renders together (doc/targets_real_photos.md): full-resolution quad
  // detection (decimation 2 loses tags under ~25 px), 2 corrected bits (the
  // library's own default for tag36h11, minimum distance 11).
  std::vector<std::string> families{"tag36h11"};  // tag36h11 tag25h9 tag16h5 tagStandard41h12 ...
  double quad_decimate = 1.0;  // [-] >= 1: quad detection on an image decimated by this factor
  double quad_sigma = 0.0;     // [px] Gaussian blur before quad detection (0 = none)
  bool refine_edges =
      false;  // libapriltag's own edge refinement of the quads (on: 1 of 37 real tags lost)
  double decode_sharpening = 0.25;    // [-] libapriltag's decode sharpening
  int threads = 1;                    // [-] libapriltag worker threads, 1..64
  int max_hamming = 2;                // [bits] error bits corrected at most, 0..3
  double min_decision_margin = 25.0;  // [-] weaker decodes are rejected ("weak_decode")
  bool refine_tags = true;            // our edge-model refinement of corners and centre
  // The refined corners replace the detector's only where the edge model
  // explains the pixels: every edge's fit residual RMS / contrast at most
  // this; otherwise (JPEG blocks, texture, a print that is not a step) the
  // detector's corners are kept (Observation::method "detector").
  double tag_refine_max_residual = 0.03;  // [-]
  // ... and where the refined centre is this precise at least (sqrt of the
  // largest eigenvalue of its covariance).
  double tag_refine_max_sigma = 0.1;  // [px]
  // --- circular targets ---
  bool detect_circles = true;
  // [px] apparent diameter range of the light centre (major axis; a measured
  // diameter 20 % under the minimum or 5 % over the maximum still counts).
  double circle_min_diameter = 8.0;      // [px]
  double circle_max_diameter = 150.0;    // [px]
  double circle_max_eccentricity = 0.9;  // [-] 1 - minor/major; 0.9 ~ 84 deg obliquity
  // [-] max distance to a projected listed circle, in its radii. Monitoring
  // circles are listed at approximate positions and move between epochs;
  // listed circles stand metres (hundreds of px) apart. Measured on the
  // replay surveys (process_bag): 2.0 names every listed circle, 0.5 left 4
  // per epoch (full_graph_replay) and 4 (uav_graph_replay) to the adjuster's
  // naming, with the same displacement errors.
  double circle_id_gate = 2.0;
  // Which designs are circles (see CircleDesign); auto: any.
  CircleDesign circle_design = CircleDesign::kAuto;
  // Design kDiscInRing: outer diameter of the dark ring / diameter of the
  // bright disc. Such a candidate is a circle only when the ring's outer edge
  // is seen at this ratio (within the tolerance) on most rays from the centre.
  double circle_ring_ratio = 2.0;             // [-] > 1
  double circle_ring_ratio_tolerance = 0.15;  // [-] relative
  double circle_max_residual = 0.08;  // [-] ellipse fit residual RMS / contrast; more is "residual"
  double circle_size_tolerance =
      0.25;  // [-] relative; with a pose: measured vs projected listed diameter ("size")
  bool refine_circles = true;       // intensity-model ellipse fit after the centroid
  bool correct_perspective = true;  // remove the perspective bias when the geometry is known
  // --- acceptance ---
  double min_contrast = 20.0;            // [DN, 8-bit scale] disc/ring or white/black difference
  double border_margin = 2.0;            // [px] targets closer to the image border are "border"
  double saturation_level = 250.0;       // [DN, 8-bit scale] pixels at or above are saturated
  double max_saturated_fraction = 0.10;  // [-] of the bright part; more is "saturated"
  double max_edge_blur =
      1.6;  // [px] fitted edge blur sigma; more is "blurred" (tags: the detector's corners)
  double max_residual =
      0.25;  // [-] fit residual RMS / contrast; more is "partial" (tags: the detector's corners)
  double max_dark_surround = 0.03;  // [-] tags: share of the white surround darker than mid-grey;
                                    // more is "partial" (occluded)
  double noise_floor =
      0.0;  // [DN] minimum image noise; 0: quantisation of the input (1/sqrt(12) LSB)

  void Check() const;
};

// Why a target was seen but not measured.
// The last four are circle candidates that are not targets of the design
// (Result::discarded).
enum class RejectReason {
  kBorder,
  kSaturated,
  kBlurred,
  kPartial,
  kLowContrast,
  kWeakDecode,
  kFitFailed,
  kNotDisc,
  kDesign,
  kResidual,
  kSize
};
std::string RejectReasonName(
    RejectReason reason);  // "border", "saturated", ..., "not_disc", "design", "residual", "size"
constexpr int kNumRejectReasons = 11;

// Which measurement gave an observation's centre.
// kRingCentre: a marker of three or more rings, the image of the rings'
// common centre from their ellipses (no pose needed).
enum class CentreMethod { kEdgeModel, kDetector, kEllipseModel, kGrayCentroid, kRingCentre };
std::string CentreMethodName(CentreMethod method);  // "edge_model", "detector", "ellipse_model",
                                                    // "gray_centroid", "ring_centre"

struct Observation {
  int id = -1;         // tag ID; circle: list ID (ring markers: read), -1 when not identified
  std::string family;  // "tag36h11", ..., "circle"
  std::optional<io::TargetRole> role;  // nullopt: unknown (not in the target list)
  Eigen::Vector2d centre{0, 0};        // [px] OpenCV convention
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2]
  bool has_corners = false;
  std::array<Eigen::Vector2d, 4> corners{};  // [px] libapriltag order (bottom-left, bottom-right,
                                             // top-right, top-left of the tag)
  double size_px = 0.0;                      // [px] tag edge / disc diameter (mean)
  double quality = 0.0;                      // [0..1]
  double contrast = 0.0;                     // [DN, 8-bit scale]
  double edge_blur = 0.0;                    // [px] fitted blur sigma
  double decision_margin = 0.0;              // tags: libapriltag decision margin
  int hamming = 0;                           // tags: corrected bits
  Eigen::Vector2d gray_centroid{0, 0};       // circles: the plain gray-weighted centroid [px]
  Eigen::Vector2d detector_centre{
      0, 0};  // tags: libapriltag's centre, converted to OpenCV convention [px]
  bool perspective_corrected = false;  // circles: the perspective bias was removed
  Eigen::Vector2d perspective_correction{
      0, 0};  // circles: what was subtracted [px] (0 when not corrected)
  CentreMethod method = CentreMethod::kDetector;  // what gave the centre (and corners)
  double fit_residual = 0.0;  // [-] tags: worst edge, circles: ellipse fit residual RMS / contrast
  double ring_ratio = 0.0;    // circles: measured ring outer / disc diameter (dot: 0)
  CircleDesign design = CircleDesign::kAuto;  // circles: the design seen (never kAuto)
  int rings = 0;  // circles measured as ring markers (method ring_centre): dark rings counted
  // ... and their edges' radii over the outer edge's, inner to outer, free of
  // perspective (empty when an edge was not refined); the ID is read from them.
  std::vector<double> ring_radii;
  std::string Key() const { return family + "/" + std::to_string(id); }
};

struct Rejection {
  std::string family;  // "tag36h11", "circle"
  int id = -1;
  Eigen::Vector2d where{0, 0};  // [px]
  RejectReason reason = RejectReason::kFitFailed;
  std::string detail;      // e.g. "23% of the disc saturated"
  double radius_px = 0.0;  // circles of a design: the marker's outer radius [px] (0: unknown)
};

struct Summary {
  int num_tags = 0;
  int num_circles = 0;
  int num_unknown = 0;
  std::map<std::string, int> rejects_by_reason;
  double noise_estimate = 0.0;  // [DN, 8-bit scale] median fit residual used for covariances
  bool IsSolutionUsable() const { return num_tags + num_circles > 0; }
};

struct Result {
  int width = 0;
  int height = 0;
  std::vector<Observation> observations;
  // Targets seen but not measured: listed targets, and circle candidates that
  // show a design's evidence (a marker) but cannot be measured (blurred,
  // partial, residual, ...).
  std::vector<Rejection> rejections;
  // Circle candidates (bright disc-sized blobs with a darker surround) that
  // are not targets of the configured design, each with its reason: the
  // debug output (centroid_targets --explain). Not counted in the summary.
  std::vector<Rejection> discarded;
  Summary summary;
};

// Camera model and approximate pose of the image: identifies circles by their
// listed positions and corrects the perspective bias of circle centres.
struct ViewGeometry {
  camera::CameraModel camera;
  camera::ExteriorOrientation pose;
};

// An image converted for measurement: 8-bit mono for libapriltag and, for
// inputs deeper than 8 bit only, a float intensity image on the 8-bit scale
// (mono16 keeps its precision: /257). An 8-bit input is measured on mono8
// directly: mono8 input is not copied (mono8 shares its data), colour and
// bayer inputs are converted once, and no float image is made.
struct MonoImage {
  cv::Mat mono8;              // CV_8UC1
  cv::Mat intensity;          // CV_32FC1, 0..255; empty for 8-bit inputs (then mono8 is measured)
  double quantisation = 1.0;  // [DN, 8-bit scale] size of one input level
};

// The encodings Detect() accepts.
const std::vector<std::string>& SupportedEncodings();
// Throws InvalidArgument naming the encoding when it is not supported, when
// the image is empty, or when its type does not match the encoding.
MonoImage ToMono(const cv::Mat& image, const std::string& encoding);
// Checks an incoming image message before any conversion: its size is not
// empty, its encoding is supported and its size equals the camera_info's.
// Throws InvalidArgument naming `topic` and what is wrong (the encoding, both
// sizes).
void CheckImageInput(const std::string& topic, int width, int height, const std::string& encoding,
                     int info_width, int info_height);

class TargetCentroider {
 public:
  // Throws ConfigError (options) or InvalidArgument (unknown family).
  TargetCentroider(const Options& options, const io::TargetList& targets);
  ~TargetCentroider();
  TargetCentroider(const TargetCentroider&) = delete;
  TargetCentroider& operator=(const TargetCentroider&) = delete;

  // Finds and measures all targets. Throws InvalidArgument for an empty
  // image, an unsupported encoding, or a view whose sensor size differs from
  // the image size (naming both sizes).
  Result Detect(const cv::Mat& image, const std::string& encoding,
                const ViewGeometry* view = nullptr) const;
  // The same on a converted image.
  Result DetectMono(const MonoImage& mono, const ViewGeometry* view = nullptr) const;

  const Options& options() const { return options_; }
  const io::TargetList& targets() const { return targets_; }

  // The plain gray-weighted centroid (doc/design.md) of the bright blob around
  // `seed` within a square window of half size `radius` [px] of a CV_8UC1 or
  // CV_32FC1 image: threshold
  // halfway between the window's dark and bright levels (automatic), pixels
  // under it set to 0, intensity-weighted mean. Returns false when the window
  // leaves the image or has no contrast.
  static bool GrayWeightedCentroid(const cv::Mat& intensity, const Eigen::Vector2d& seed,
                                   double radius, Eigen::Vector2d* centroid);

 private:
  struct Detector;
  Options options_;
  io::TargetList targets_;
  Detector* detector_ = nullptr;  // libapriltag state (owned)
};

// Perspective bias of a circle's centre: the centre of the imaged ellipse
// minus the image of the circle's centre [px], from the camera model and pose.
// diameter [m], centre and unit normal in site.
Eigen::Vector2d CirclePerspectiveBias(const ViewGeometry& view,
                                      const Eigen::Vector3d& centre_in_site,
                                      const Eigen::Vector3d& normal_in_site, double diameter);

// An annotated copy of the image (bgr8): observations (green: known, yellow:
// unknown) with their IDs, rejections in red with their reason.
cv::Mat DrawResult(const cv::Mat& mono8, const Result& result);

}  // namespace targets
}  // namespace slope_monitor
