#include "slope_monitor/core/matching/sequence_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <utility>
#include <vector>

#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"

namespace slope_monitor {
namespace matching {
namespace {

constexpr double kMb = 1024.0 * 1024.0;

std::string Format(const char* format, double a, double b = 0.0) {
  char line[200];
  std::snprintf(line, sizeof(line), format, a, b);
  return line;
}

// "image 1700000000.500 (frame uav_optical)": how an image is named in messages.
std::string ImageName(std::int64_t stamp_ns, const std::string& frame) {
  char line[64];
  std::snprintf(line, sizeof(line), "%.3f", 1e-9 * static_cast<double>(stamp_ns));
  return "image at " + std::string(line) + " (frame '" + frame + "')";
}

// Grey copy (hex method): the image owns its pixels, 1 channel, 8 or 16 bit.
cv::Mat GreyCopy(const cv::Mat& image) {
  if (image.empty()) throw InvalidArgument("empty image");
  if (image.depth() != CV_8U && image.depth() != CV_16U)
    throw InvalidArgument(Message("unsupported depth ", image.depth(), " (8 or 16 bit)"));
  cv::Mat grey;
  if (image.channels() == 1)
    grey = image.clone();
  else if (image.channels() == 3)
    cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4)
    cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  else
    throw InvalidArgument(Message("unsupported channel count ", image.channels()));
  return grey;
}

}  // namespace

const char* SequencePairMethodName(SequencePairMethod method) {
  return method == SequencePairMethod::kPhoto ? "photo" : "shift_hex";
}

SequencePairMethod SequencePairMethodFromName(const std::string& name) {
  if (name == "photo") return SequencePairMethod::kPhoto;
  if (name == "shift_hex") return SequencePairMethod::kGlobalShiftHex;
  throw ConfigError("pair method '" + name + "' unknown (photo or shift_hex)");
}

void SequenceMatcherOptions::Check() const {
  const auto need = [](bool ok, const std::string& what) {
    if (!ok) throw ConfigError("SequenceMatcherOptions." + what);
  };
  need(max_gap >= 0.0 && std::isfinite(max_gap), Message("max_gap must be >= 0 s, got ", max_gap));
  need(position_prior_max_dt >= 0.0 && std::isfinite(position_prior_max_dt),
       Message("position_prior_max_dt must be >= 0 s, got ", position_prior_max_dt));
  need(prior_wait >= 0.0 && std::isfinite(prior_wait),
       Message("prior_wait must be >= 0 s, got ", prior_wait));
  need(max_images >= 1, Message("max_images must be >= 1, got ", max_images));
  need(max_memory_mb > 0.0 && std::isfinite(max_memory_mb),
       Message("max_memory_mb must be > 0, got ", max_memory_mb));
  need(border >= 0.0 && std::isfinite(border), Message("border must be >= 0 px, got ", border));
  need(threads >= 0 && threads <= 64, Message("threads must be in [0, 64], got ", threads));
  need(min_pair_tie_points >= 0 && min_pair_tie_points <= 100000,
       Message("min_pair_tie_points must be in [0, 100000], got ", min_pair_tie_points));
  pairing.Check();
  shift.Check();
  hex.Check();
  photo.Check();
  photo_pair.Check();
}

SequenceMatcher::SequenceMatcher(const SequenceMatcherOptions& options)
    : options_(options), hex_(options.hex) {
  options_.Check();
  // One knob for the photo's matching: its pairs at once, and a pair's
  // windows when the pairs do not already share the threads.
  options_.photo_pair.threads = options_.threads;
}

SequenceStep SequenceMatcher::AddImage(std::int64_t stamp_ns, const std::string& frame_id,
                                       const cv::Mat& image, double now) {
  // A copy that owns its pixels: the image may wait for its prior, and the
  // caller's (e.g. a view of a ROS message) may not outlive this call.
  pending_.push_back({stamp_ns, frame_id, image.clone(), now});
  SequenceStep step;
  Drain(&step);
  return step;
}

SequenceStep SequenceMatcher::AddPrior(std::int64_t stamp_ns, const SequencePrior& prior) {
  const double t = 1e-9 * static_cast<double>(stamp_ns);
  priors_.emplace_back(t, prior);
  latest_prior_ = std::max(latest_prior_, t);
  SequenceStep step;
  Drain(&step);
  return step;
}

SequenceStep SequenceMatcher::Poll(double now) {
  SequenceStep step;
  while (!pending_.empty() && !FrontReady() &&
         now - pending_.front().received >= options_.prior_wait) {
    const Pending& p = pending_.front();
    step.log.push_back("gave up waiting for the position prior of the " +
                       ImageName(p.stamp_ns, p.frame_id) +
                       Format(" after %.1f s (prior_wait %.1f s): matched without it",
                              now - p.received, options_.prior_wait));
    ++summary_.prior_timeouts;
    ProcessFront(&step);
    Drain(&step);
  }
  return step;
}

SequenceStep SequenceMatcher::Finish() {
  SequenceStep step;
  Drain(&step);
  while (!pending_.empty()) {
    if (priors_expected_)
      step.log.push_back("end of input: the " +
                         ImageName(pending_.front().stamp_ns, pending_.front().frame_id) +
                         " is matched with the position priors that are in");
    ProcessFront(&step);
  }
  return step;
}

bool SequenceMatcher::FrontReady() const {
  if (pending_.empty()) return false;
  if (!priors_expected_) return true;
  const double t = 1e-9 * static_cast<double>(pending_.front().stamp_ns);
  if (latest_prior_ > t + options_.position_prior_max_dt) return true;
  for (const auto& p : priors_)
    if (std::fabs(p.first - t) <= options_.position_prior_max_dt) return true;
  return false;
}

void SequenceMatcher::Drain(SequenceStep* step) {
  while (FrontReady()) ProcessFront(step);
}

// The prior nearest to t within position_prior_max_dt; priors older than
// that are done (images come in time order).
std::optional<SequencePrior> SequenceMatcher::TakePrior(double t) {
  std::optional<SequencePrior> best;
  double best_dt = options_.position_prior_max_dt;
  for (const auto& p : priors_) {
    const double dt = std::fabs(p.first - t);
    if (dt <= best_dt) {
      best_dt = dt;
      best = p.second;
    }
  }
  while (!priors_.empty() && priors_.front().first < t - options_.position_prior_max_dt)
    priors_.pop_front();
  return best;
}

void SequenceMatcher::ProcessFront(SequenceStep* step) {
  Pending next = std::move(pending_.front());
  pending_.pop_front();
  const double t = 1e-9 * static_cast<double>(next.stamp_ns);
  Earlier b;
  b.info.serial = ++serial_;
  b.info.stamp = t;
  b.stamp_ns = next.stamp_ns;
  b.frame_id = next.frame_id;
  if (const std::optional<SequencePrior> prior = TakePrior(t)) {
    b.info.has_position = true;
    b.info.position = prior->position;
    if (prior->site_from_optical) {
      // Where the image's top (-y of the optical frame) points on the ground.
      const Eigen::Vector3d up = prior->site_from_optical->normalized() * Eigen::Vector3d(0, -1, 0);
      b.info.has_heading = up.head<2>().norm() > 0.1;
      b.info.heading_deg = std::atan2(up.x(), up.y()) * kDegPerRad;
    }
  }
  // A new epoch (flight) after a gap, or when the stamps run backwards.
  if (summary_.epoch == 0 || t - last_stamp_ > options_.max_gap || t < last_stamp_) {
    if (summary_.epoch > 0)
      step->log.push_back(
          Format("new sequence epoch at %.3f (previous image at %.3f)", t, last_stamp_));
    while (!history_.empty()) Release(history_.size() - 1);
    ++summary_.epoch;
    ground_pixel_ = 0.0;
    epoch_images_ = 0;
  }
  last_stamp_ = t;
  // The image's features (or grey copy), once.
  std::string error;
  try {
    const auto start = std::chrono::steady_clock::now();
    // One camera's photos of a flight have one size (one camera model in the
    // adjustment): another size is a wrong image.
    if (!history_.empty() && !next.image.empty() && history_.front().size != next.image.size())
      throw InvalidArgument(
          Message("the image and the epoch's images differ in size: ", next.image.cols, " x ",
                  next.image.rows, ", not ", history_.front().size.width, " x ",
                  history_.front().size.height));
    if (options_.method == SequencePairMethod::kPhoto) {
      b.features = std::make_shared<PhotoFeatures>(next.image, ImageName(b.stamp_ns, b.frame_id),
                                                   options_.photo);
      b.bytes = b.features->MemoryBytes();
    } else {
      b.image = GreyCopy(next.image);
      if (!history_.empty() && history_.front().image.type() != b.image.type())
        throw InvalidArgument("the image and the epoch's images differ in depth");
      b.bytes = b.image.total() * b.image.elemSize();
    }
    b.size = next.image.size();
    b.info.width = b.size.width;
    b.info.height = b.size.height;
    b.info.ground_pixel = ground_pixel_;  // this photo's own when its pairs are matched
    summary_.feature_seconds += SecondsSince(start);
  } catch (const std::exception& e) {
    error = ImageName(b.stamp_ns, b.frame_id) + ": " + e.what();
    ++summary_.errors;
    summary_.last_error = error;
  }
  next.image.release();

  std::vector<SequenceImage> infos;
  for (const Earlier& e : history_) infos.push_back(e.info);
  ++epoch_images_;
  const bool exhaustive = PlansExhaustively(epoch_images_, options_.pairing);
  const std::vector<size_t> plan =
      PlanSequencePairs(infos, b.info, options_.pairing, epoch_images_);
  ++summary_.images;
  if (!exhaustive && PlansByFootprint(infos, b.info)) ++summary_.footprint_planned;
  if (plan.empty()) {
    SequencePair out;
    out.epoch = summary_.epoch;
    out.stamp_b = b.stamp_ns;
    out.frame_b = b.frame_id;
    out.reason = error.empty() ? "" : "error";
    out.message = error.empty() ? ImageName(b.stamp_ns, b.frame_id) + ": no partner" : error;
    step->pairs.push_back(out);
    ++summary_.unpaired;
  }
  std::vector<SequencePair> matched(plan.size());
  if (error.empty()) {
    // OpenCV's thread pool, in at most `threads` stripes (0: as many as it
    // has threads); each pair's result goes to its own slot.
    const int n = static_cast<int>(plan.size());
    const double stripes = options_.threads > 0 ? std::min(options_.threads, n) : -1.0;
    cv::parallel_for_(
        cv::Range(0, n),
        [&](const cv::Range& range) {
          for (int k = range.start; k < range.end; ++k) {
            matched[k] = MatchPair(history_[plan[k]], b,
                                   !exhaustive || ExpectedToOverlap(history_[plan[k]], b));
          }
        },
        stripes);
    MeasureGroundPixel(plan, matched, &b);
  }
  for (size_t k = 0; k < plan.size(); ++k) {
    SequencePair out;
    if (error.empty()) {
      out = std::move(matched[k]);
    } else {
      out.reason = "error";
      out.message = error;
    }
    out.epoch = summary_.epoch;
    out.stamp_b = b.stamp_ns;
    out.frame_b = b.frame_id;
    out.has_a = true;
    out.stamp_a = history_[plan[k]].stamp_ns;
    out.frame_a = history_[plan[k]].frame_id;
    out.pairs_b = static_cast<std::uint32_t>(plan.size());
    out.index = static_cast<std::uint32_t>(k + 1);
    ++summary_.pairs;
    summary_.tie_points += static_cast<int>(out.points.size());
    summary_.pair_seconds += out.seconds;
    if (!out.reason.empty()) ++summary_.failed_pairs[out.reason];
    step->pairs.push_back(std::move(out));
  }
  if (error.empty()) Keep(std::move(b), step);
}

// b's ground pixel size: the median of its matched pairs'
// (GroundPixelFromTies), else the one it was planned with; an earlier image
// without one (the epoch's first) takes its pair's. The next photo starts
// from b's.
void SequenceMatcher::MeasureGroundPixel(const std::vector<size_t>& plan,
                                         const std::vector<SequencePair>& pairs, Earlier* b) {
  if (!b->info.has_position) return;
  std::vector<double> measured;
  for (size_t k = 0; k < plan.size(); ++k) {
    Earlier& a = history_[plan[k]];
    if (!a.info.has_position || pairs[k].points.empty()) continue;
    std::vector<Eigen::Vector2d> xa, xb;
    for (const SequenceTie& t : pairs[k].points) {
      xa.push_back(t.xa);
      xb.push_back(t.xb);
    }
    const auto centre = [](const cv::Size& s) {
      return Eigen::Vector2d(0.5 * (s.width - 1), 0.5 * (s.height - 1));
    };
    const double g = GroundPixelFromTies(xa, xb, centre(a.size), centre(b->size),
                                         (a.info.position - b->info.position).norm());
    if (g <= 0.0) continue;
    measured.push_back(g);
    if (a.info.ground_pixel <= 0.0) a.info.ground_pixel = g;
  }
  if (!measured.empty()) summary_.ground_pixel = b->info.ground_pixel = UpperMedian(measured);
  if (b->info.ground_pixel > 0.0) ground_pixel_ = b->info.ground_pixel;
}

bool SequenceMatcher::ExpectedToOverlap(const Earlier& a, const Earlier& b) const {
  const PhotoFootprint fa = FootprintOf(a.info), fb = FootprintOf(b.info);
  return fa.has_position && fb.has_position &&
         FootprintOverlap(fa, fb) >= options_.pairing.min_overlap;
}

SequencePair SequenceMatcher::MatchPair(const Earlier& a, const Earlier& b,
                                        bool expected_to_overlap) const {
  SequencePair out;
  const std::string names = Format("pair %.3f / %.3f: ", a.info.stamp, b.info.stamp);
  const auto start = std::chrono::steady_clock::now();
  try {
    if (options_.method == SequencePairMethod::kGlobalShiftHex) {
      MatchShiftHex(a.image, b.image, a.info.serial, &out);
    } else {
      MatchPhotos(a, b, &out);
      // No SIFT relation (weak texture): the global shift of nadir photos of one size.
      if (out.reason == "no_relation" && options_.fallback_shift_hex && expected_to_overlap &&
          a.features->size() == b.features->size()) {
        SequencePair shift_hex;
        MatchShiftHex(a.features->grey(), b.features->grey(), a.info.serial, &shift_hex);
        shift_hex.message = out.message + "; global shift + hex matcher: " + shift_hex.message;
        out = std::move(shift_hex);
      }
    }
  } catch (const std::exception& e) {
    out.points.clear();
    out.reason = "error";
    out.message = e.what();
  }
  if (out.reason.empty() && static_cast<int>(out.points.size()) < options_.min_pair_tie_points) {
    out.reason = "too_few_tie_points";
    out.message += Message(" (fewer than min_pair_tie_points = ", options_.min_pair_tie_points,
                           ": none used)");
    out.points.clear();
  }
  out.message = names + out.message;
  out.seconds = SecondsSince(start);
  out.expected_to_overlap = expected_to_overlap;
  if (out.reason.empty()) out.message += Format(" in %.2f s", out.seconds);
  return out;
}

void SequenceMatcher::MatchPhotos(const Earlier& a, const Earlier& b, SequencePair* out) const {
  const PhotoPairResult r = MatchPhotoPair(*a.features, *b.features, options_.photo_pair);
  const PhotoPairSummary& s = r.summary;
  if (!s.IsSolutionUsable()) {
    out->reason = "no_relation";
    out->message = "no tie points: " + s.message;
    return;
  }
  for (const PhotoTiePoint& m : r.tie_points) {
    SequenceTie t;
    t.id = SequenceTrackId(a.info.serial, m.xa, a.features->size().width);
    t.xa = m.xa;
    t.xb = m.xb;
    t.covariance = m.covariance;
    t.correlation = m.quality;
    t.quality = m.quality;
    out->points.push_back(t);
  }
  out->message = Format("rotation %.1f deg, scale %.3f, ", s.rotation_deg, s.scale) +
                 Message(s.coarse_inliers, " coarse inliers, ", out->points.size(),
                         " tie points of ", s.candidates, " candidates, epipolar RMS ") +
                 Format("%.2f px", s.epipolar_rms);
}

void SequenceMatcher::MatchShiftHex(const cv::Mat& a, const cv::Mat& b, std::uint32_t serial_a,
                                    SequencePair* out) const {
  const GlobalShiftResult gs = EstimateGlobalShift(a, b, options_.shift);
  if (!gs.usable) {
    out->reason = "shift_unusable";
    out->message = "global shift not usable: " + gs.reason;
    return;
  }
  MatchPrior prior = options_.hex_prior;
  prior.shift = gs.shift;
  const cv::Size size = b.size();
  const double border = options_.border;
  const Eigen::Vector2d shift = gs.shift;
  // Only the points of a that the shift puts inside b.
  prior.within = [size, border, shift](const Eigen::Vector2d& x) {
    const Eigen::Vector2d y = x + shift;
    return y.x() >= border && y.y() >= border && y.x() <= size.width - 1 - border &&
           y.y() <= size.height - 1 - border;
  };
  const HexMatchResult r = hex_.Match(a, b, prior);
  for (const HexMatch& m : r.matches) {
    SequenceTie t;
    t.id = SequenceTrackId(serial_a, m.xa, a.cols);
    t.xa = m.xa;
    t.xb = m.xb;
    t.covariance = m.covariance;
    t.correlation = m.correlation;
    t.quality = m.quality;
    out->points.push_back(t);
  }
  out->message = Format("shift (%.1f, %.1f) px", gs.shift.x(), gs.shift.y()) +
                 Format(" (NCC %.2f), ", gs.overlap_correlation) +
                 Message(r.matches.size(), " tie points (", r.summary.low_quality,
                         " low quality) of ", r.summary.candidates, " candidates");
}

// b becomes a partner of later images; those no later image can pair with are released.
void SequenceMatcher::Keep(Earlier b, SequenceStep* step) {
  history_.push_back(std::move(b));
  summary_.memory_bytes += history_.back().bytes;
  const int depth = options_.pairing.sequence_depth;
  // Outside the last sequence_depth images, only an image with a position
  // prior can still be chosen (by distance), and only when priors come.
  // While the epoch is planned exhaustively, the next image pairs with all.
  const bool all_partners = PlansExhaustively(epoch_images_ + 1, options_.pairing);
  for (size_t i = 0; !all_partners && i + depth < history_.size();) {
    if (!priors_expected_ || !history_[i].info.has_position) {
      Release(i);
      ++summary_.released;
    } else {
      ++i;
    }
  }
  while (history_.size() > 1 && (static_cast<int>(history_.size()) > options_.max_images ||
                                 summary_.memory_bytes > options_.max_memory_mb * kMb)) {
    step->log.push_back(Format("released the oldest photo (%.3f) of the epoch: its photos exceed ",
                               history_.front().info.stamp) +
                        Message(options_.max_images, " images or ", options_.max_memory_mb, " MB (",
                                Format("%.1f MB", summary_.memory_bytes / kMb), ")"));
    Release(0);
    ++summary_.released;
  }
  summary_.images_in_memory = static_cast<int>(history_.size());
  summary_.peak_memory_bytes = std::max(summary_.peak_memory_bytes, summary_.memory_bytes);
}

void SequenceMatcher::Release(std::size_t index) {
  summary_.memory_bytes -= history_[index].bytes;
  history_.erase(history_.begin() + static_cast<std::ptrdiff_t>(index));
  summary_.images_in_memory = static_cast<int>(history_.size());
}

}  // namespace matching
}  // namespace slope_monitor
