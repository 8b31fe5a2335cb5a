// Tie points between two real survey photos, whatever the flight gives
// (rotation up to 180 deg between photos, crab, scale changes, illumination):
//
//   1. per photo, once (PhotoFeatures, reused for every pair): the grey image
//      (8 bit, full resolution), a copy reduced to coarse_max_side pixels,
//      OpenCV SIFT keypoints and descriptors on it or on a smaller copy
//      (coarse_sift_max_side; the coarse relation only), and the package's
//      interest points (MLSC rule, interest_points.h) on the reduced copy;
//   2. coarse relation of the pair: SIFT descriptors matched with FLANN and
//      Lowe's ratio test; of these, the matches whose keypoint rotation
//      (orientation in b minus in a) and scale ratio agree with the pair's
//      rotation and scale: from the prior (PhotoPairPrior, e.g. the heading
//      difference of the autopilot) when given, else the peak of a vote over
//      (rotation, log2 scale) (a Hough transform, as Lowe's object
//      recognition). Repetitive texture (grass, crops) gives many wrong
//      ratio-test matches in random directions; the consistent ones alone
//      hold the relation. A RANSAC homography b_from_a (full-resolution
//      pixels) of them and its inliers are the coarse matches;
//   3. for each interest point xa of a that the homography puts inside b:
//      the predicted xb0 = H xa plus the median residual (coarse match minus
//      H) of the `neighbours` nearest coarse inliers (relief), and the local
//      linear map J = dH/dx at xa. The window of b is warped into a's frame
//      (xb = xb0 + J (x - xa)), i.e. the same orientation and scale as a;
//   4. modified LSC (lsc.h: integer NCC search within lsc.search_radius, then
//      affine LSC with its covariance) of a's window against the warped
//      window on the reduced copies; the solution is mapped back into b
//      (xb = xb0 + J d, covariance J C J^T);
//   5. photos larger than the reduced copy: the same at full resolution
//      (refine_lsc), starting from the scaled level-4 match and warping with
//      its local affine map (J composed with LSC's affine part);
//   6. blunders: a RANSAC fundamental matrix of the tie points
//      (cv::findFundamentalMat, screen_threshold px) drops those off their
//      epipolar line.
// Pixels are full-resolution OpenCV pixels (centre of the top-left pixel at
// (0, 0)). Memory per photo: one 8-bit grey image plus the features
// (PhotoFeatures::MemoryBytes()); images of b are only read, never copied.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "slope_monitor/core/matching/interest_points.h"
#include "slope_monitor/core/matching/lsc.h"

namespace slope_monitor {
namespace matching {

struct PhotoFeatureOptions {
  int coarse_max_side = 1200;  // [px] long side of the reduced copy, [200, 10000]
  // [px] long side of the copy SIFT runs on, [100, 10000]; SIFT uses the
  // reduced copy itself when that is not larger.
  int coarse_sift_max_side = 1200;
  int coarse_max_features = 4000;  // SIFT features on that copy, >= 10
  // SIFT's contrast threshold, (0, 1). OpenCV's 0.04 found 82-264 keypoints
  // on the simulated UAV photos' ground (contrast 0.35, 1200 px copy) and a
  // fifth of the strip pairs got no relation; 0.01 fills coarse_max_features
  // (the strongest are kept, so well-textured photos keep the same ones):
  // 43-403 homography inliers on those pairs with 1000 features.
  double coarse_contrast_threshold = 0.01;
  // Interest points on the reduced copy (more than the matcher's default:
  // the overlap is a part of the photo).
  InterestPointOptions interest = [] {
    InterestPointOptions o;
    o.max_points = 8000;
    return o;
  }();
  void Check() const;  // throws ConfigError naming the field
};

// The features and the pair rules of a block of photos (a flight): one place
// for process_flight (flight/flight_matching.h) and the graph's sequence
// matcher (sequence_matcher.h), so both tie a flight's photos alike.
// SIFT: 2000 features on a 640 px copy (the pair's relation: compared by
// every pair; on the real snowpeak pairs flown in opposite directions the
// 1200 px copy found no relation where 640 px found 56 and 20 tie points;
// caliterra through process_flight: 8 of 8 photos, 5455 points, 0.493 px
// mean reprojection error, against 5497 and 0.497 px with 1200 px, 29 Nov
// 2026); 2000 interest points spread over 8 x 8 cells (the tie points:
// COLMAP kept 20 202 points for 50 real photos of a fixed-wing block; the
// pair default 8000 only costs time).
PhotoFeatureOptions BlockPhotoFeatureOptions();
// A pair with fewer tie points is not used (too few to tell a relation from
// chance agreement).
inline constexpr int kBlockMinPairTiePoints = 15;
// Every pair of photos up to this many photos in a flight (as COLMAP's
// exhaustive matcher); beyond, pairs by GNSS footprint overlap.
inline constexpr int kBlockExhaustiveMaxPhotos = 60;

// What one photo contributes to every pair it is in (computed once).
class PhotoFeatures {
 public:
  // image: 8- or 16-bit, 1, 3 or 4 channels (BGR as cv::imread gives).
  // Throws InvalidArgument naming `name` for an empty or unsupported image.
  PhotoFeatures(const cv::Mat& image, const std::string& name, const PhotoFeatureOptions& options);

  const std::string& name() const { return name_; }
  const cv::Mat& grey() const { return grey_; }  // CV_8U, full resolution
  // The reduced copy (coarse_max_side; the grey image itself when smaller)
  // and its scale (reduced px / full px, <= 1).
  const cv::Mat& reduced() const { return reduced_; }
  double reduce() const { return reduce_; }
  cv::Size size() const { return grey_.size(); }
  // SIFT on the reduced copy; keypoint positions in full-resolution pixels.
  const std::vector<cv::Point2f>& coarse_points() const { return coarse_points_; }
  // Their orientation [deg, clockwise in the image: x towards y] and size
  // [full-resolution px].
  const std::vector<float>& coarse_angles() const { return coarse_angles_; }
  const std::vector<float>& coarse_sizes() const { return coarse_sizes_; }
  const cv::Mat& coarse_descriptors() const { return coarse_descriptors_; }
  // Interest points of the reduced copy (its pixels), strongest first.
  const std::vector<InterestPoint>& interest_points() const { return interest_points_; }
  size_t MemoryBytes() const;
  double seconds() const { return seconds_; }  // time taken to compute them

 private:
  void DetectSift(const PhotoFeatureOptions& options);  // the coarse_* members

  std::string name_;
  cv::Mat grey_;
  cv::Mat reduced_;
  double reduce_ = 1.0;
  std::vector<cv::Point2f> coarse_points_;
  std::vector<float> coarse_angles_;
  std::vector<float> coarse_sizes_;
  cv::Mat coarse_descriptors_;
  std::vector<InterestPoint> interest_points_;
  double seconds_ = 0.0;
};

struct PhotoPairOptions {
  // Lowe's ratio test of the SIFT matches, (0, 1]; looser than the usual 0.8:
  // the rotation/scale consistency below removes the wrong matches.
  double coarse_ratio = 0.9;
  // [deg] (0, 180]: matches kept within this of the pair's rotation (prior
  // or vote peak); the vote bins are this wide.
  double rotation_tolerance_deg = 15.0;
  // [-] > 0: |log2(size ratio) - pair's log2 scale| kept; vote bin width.
  double log2_scale_tolerance = 0.5;
  // [full-resolution px] RANSAC homography threshold; the ground is not a
  // plane, so it admits the relief parallax of the coarse matches, > 0.
  double coarse_ransac_threshold = 12.0;
  int min_coarse_inliers = 12;  // fewer: no relation found (no tie points), >= 8
  int neighbours = 8;           // coarse inliers for the local correction, >= 1
  int max_candidates = 8000;    // interest points of a tried (strongest), >= 1
  int border = 16;              // [px] predicted xb at least this far inside b, >= 0
  // Precise matching of a's window against the warped window of b. The
  // integer search radius covers the error of the coarse prediction.
  LscOptions lsc = [] {
    LscOptions o;
    o.search_radius = 6;
    o.search_half_window = 7;
    return o;
  }();
  // Refinement at full resolution (photos larger than coarse_max_side): from
  // the reduced level's match, scaled, within a few pixels. Shift model: the
  // window of b is already warped by the reduced level's affine map; a
  // second affine fit on the soft full-resolution texture of a compact
  // camera mostly fails to converge (measured on IMG_2213/2244: 33 tie
  // points with eq. 1, 258 with eq. 2).
  LscOptions refine_lsc = [] {
    LscOptions o;
    o.model = LscModel::kShift;
    o.search_radius = 2;
    o.half_window = 7;
    return o;
  }();
  // [px] RANSAC fundamental matrix of the tie points: those farther from
  // their epipolar line are blunders and dropped, > 0.
  double screen_threshold = 1.0;
  // The candidate windows are matched on this many threads (0: OpenCV's
  // pool, as many as the hardware's), each into its own slot taken in
  // candidate order: the tie points do not depend on it. Inside another
  // cv::parallel_for_ (pairs matched at once) the windows run serially.
  int threads = 0;     // [0, 64]
  void Check() const;  // throws ConfigError naming the field
};

// What is known about the pair before matching (optional).
struct PhotoPairPrior {
  bool has_rotation = false;
  // [deg] rotation of b's image relative to a's, clockwise in the image (x
  // towards y): for nadir photos, heading of a minus heading of b (the
  // ground turns the other way in the image when the aircraft turns).
  double rotation_deg = 0.0;
  bool has_scale = false;
  double scale = 1.0;  // [-] size in b / size in a (height of a / height of b above ground)
};

struct PhotoTiePoint {
  Eigen::Vector2d xa = Eigen::Vector2d::Zero();          // [px] in a
  Eigen::Vector2d xb = Eigen::Vector2d::Zero();          // [px] in b
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // [px^2] of xb (LSC, mapped into b)
  double quality = 0.0;                                  // [0, 1]: LSC correlation
};

struct PhotoPairSummary {
  int coarse_matches = 0;     // SIFT matches passing the ratio test
  int coarse_consistent = 0;  // of them, consistent with the rotation/scale (prior or vote)
  int coarse_inliers = 0;     // of the RANSAC homography
  Eigen::Matrix3d b_from_a = Eigen::Matrix3d::Identity();  // homography (full-resolution px)
  double rotation_deg = 0.0;           // of b relative to a at a's centre, (-180, 180]
  double scale = 1.0;                  // size in b / size in a at a's centre
  int candidates = 0;                  // interest points of a predicted inside b
  int matched = 0;                     // tie points returned
  std::map<std::string, int> rejects;  // "lsc_<status>", "epipolar"
  double epipolar_rms = 0.0;  // [px] of the returned tie points to their fundamental matrix
  double seconds = 0.0;       // this pair (features of the photos not included)
  std::string message;        // why no tie points ("" when usable)
  bool IsSolutionUsable() const { return matched > 0; }
};

struct PhotoPairResult {
  std::vector<PhotoTiePoint> tie_points;
  PhotoPairSummary summary;
};

// Tie points of the pair (a, b). Never throws on data: a pair without a
// relation gives no tie points and Summary::message says why.
PhotoPairResult MatchPhotoPair(const PhotoFeatures& a, const PhotoFeatures& b,
                               const PhotoPairOptions& options,
                               const PhotoPairPrior& prior = PhotoPairPrior());

// RMS [px] of the symmetric distances of the pairs to the epipolar lines of
// a RANSAC fundamental matrix (cv::findFundamentalMat, FM_RANSAC, threshold
// px, confidence 0.999) fitted to them; its inliers in *inliers (optional).
// Fewer than 8 pairs: 0 and no inliers. RMS over the inliers.
double EpipolarRms(const std::vector<cv::Point2f>& xa, const std::vector<cv::Point2f>& xb,
                   double threshold, std::vector<unsigned char>* inliers = nullptr);

// Pair selection. A photo's ground footprint from its GNSS position (local
// east/north [m]) and heading, a rectangle `width` across the flight
// direction and `length` along it. Pairs whose footprints overlap by at least
// min_overlap of the smaller footprint are matched; without a position every
// pair with that photo is; without a heading the footprint is taken as the
// disc inside the rectangle.
struct PhotoFootprint {
  bool has_position = false;
  Eigen::Vector2d east_north = Eigen::Vector2d::Zero();  // [m]
  bool has_heading = false;
  double heading_deg = 0.0;  // [deg] clockwise from north
  double width = 0.0;        // [m] > 0 when has_position
  double length = 0.0;       // [m] > 0 when has_position
};
struct PairSelectionOptions {
  double min_overlap = 0.05;  // [-] (0, 1]
  // [m] > 0: flying height above the ground for NadirFootprint when the
  // terrain is unknown (GNSS heights are above the ellipsoid or sea level).
  double height_above_ground = 150.0;
  void Check() const;  // throws ConfigError naming the field
};
// Footprint of a nadir photo: image width across the flight direction,
// height along it; ground size = pixels x pixel_size_mm / focal_mm x
// options.height_above_ground. Throws InvalidArgument when focal or pixel
// size is not > 0.
PhotoFootprint NadirFootprint(const Eigen::Vector2d& east_north, bool has_heading,
                              double heading_deg, const cv::Size& image, double focal_mm,
                              double pixel_size_mm, const PairSelectionOptions& options);
// Index pairs (i < j), sorted.
std::vector<std::pair<int, int>> SelectOverlappingPairs(const std::vector<PhotoFootprint>& photos,
                                                        const PairSelectionOptions& options);
// Overlap of two footprints / the smaller one's area, [0, 1] (both with position).
double FootprintOverlap(const PhotoFootprint& a, const PhotoFootprint& b);

}  // namespace matching
}  // namespace slope_monitor
