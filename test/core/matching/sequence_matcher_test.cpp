// SequenceMatcher driven by hand-made sequences: crops of one texture, each
// photo 24 px further along the texture (so the true tie point relation is
// xb = xa - (0, 24) px per photo step), with stamps, priors, gaps and faults
// chosen by hand.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/sequence_matcher.h"

namespace slope_monitor {
namespace matching {
namespace {

constexpr int kSeqW = 320, kSeqH = 240, kStep = 24;  // [px] photo size and advance per photo
constexpr std::int64_t kSecond = 1000000000;

// A blurred random texture (fixed seed), wide enough for 8 photos.
const cv::Mat& Texture() {
  static const cv::Mat texture = [] {
    cv::Mat noise(kSeqH + 8 * kStep, kSeqW, CV_32F);
    cv::RNG rng(7);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
    cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.5);
    cv::Mat coarse(noise.rows / 8, noise.cols / 8, CV_32F);
    rng.fill(coarse, cv::RNG::NORMAL, 0.0, 1.0);
    cv::resize(coarse, coarse, noise.size(), 0, 0, cv::INTER_CUBIC);
    cv::Mat grey;
    cv::normalize(noise + 0.5 * coarse, grey, 20, 235, cv::NORM_MINMAX, CV_8U);
    return grey;
  }();
  return texture;
}

// Photo i: rows i * kStep ... of the texture.
cv::Mat Photo(int i) { return Texture()(cv::Rect(0, i * kStep, kSeqW, kSeqH)).clone(); }

SequenceMatcherOptions Options(SequencePairMethod method) {
  SequenceMatcherOptions o;
  o.method = method;
  return o;
}

// The pair rules of a flight beyond exhaustive_max_photos photos (priors,
// footprints, the previous images), tested on a few photos.
SequenceMatcherOptions RulesOptions(SequencePairMethod method) {
  SequenceMatcherOptions o = Options(method);
  o.pairing.exhaustive_max_photos = 0;
  return o;
}

TEST(SequenceMatcher, TiePointsOfShiftedPhotosAgainstTheHandCheckedRelation) {
  for (const SequencePairMethod method :
       {SequencePairMethod::kPhoto, SequencePairMethod::kGlobalShiftHex}) {
    SCOPED_TRACE(SequencePairMethodName(method));
    SequenceMatcher m(Options(method));
    m.SetPriorsExpected(false);
    std::vector<SequencePair> pairs;
    for (int i = 0; i < 3; ++i)
      for (const SequencePair& p : m.AddImage(i * kSecond, "cam", Photo(i)).pairs)
        pairs.push_back(p);
    // Photo 0 alone, photo 1 with 0, photo 2 with 1 and 0 (the previous two, latest first).
    ASSERT_EQ(pairs.size(), 4u);
    EXPECT_FALSE(pairs[0].has_a);
    EXPECT_EQ(pairs[1].stamp_a, 0);
    EXPECT_EQ(pairs[2].stamp_a, 1 * kSecond);
    EXPECT_EQ(pairs[3].stamp_a, 0);
    EXPECT_EQ(pairs[3].pairs_b, 2u);
    EXPECT_EQ(pairs[3].index, 2u);
    for (size_t k = 1; k < pairs.size(); ++k) {
      const SequencePair& p = pairs[k];
      EXPECT_EQ(p.reason, "") << p.message;
      EXPECT_GT(p.points.size(), 50u) << p.message;
      const double steps = static_cast<double>(p.stamp_b - p.stamp_a) / kSecond;
      int far = 0;
      for (const SequenceTie& t : p.points) {
        const Eigen::Vector2d truth = t.xa - Eigen::Vector2d(0, kStep * steps);
        if ((t.xb - truth).norm() > 0.1) ++far;
        EXPECT_EQ(t.id >> 32, static_cast<std::uint64_t>(p.stamp_a / kSecond + 1));  // serial of a
      }
      EXPECT_LE(far, static_cast<int>(p.points.size() / 100)) << p.message;
    }
    // Tracks: photo 0's points matched into photos 1 and 2 carry the same IDs.
    int shared = 0;
    for (const SequenceTie& t : pairs[3].points)
      for (const SequenceTie& u : pairs[1].points) shared += t.id == u.id && t.xa == u.xa ? 1 : 0;
    EXPECT_GT(shared, 20);
  }
}

// A photo's pairs are matched on several threads; the tie points are the
// same, bit for bit and in the same order, as on one thread, and the same
// again in a second run (FLANN's random trees are seeded per pair).
TEST(SequenceMatcher, TiePointsDoNotDependOnTheThreads) {
  std::vector<std::vector<SequencePair>> runs;
  for (const int threads : {1, 3, 3}) {
    SequenceMatcherOptions o = Options(SequencePairMethod::kPhoto);
    o.threads = threads;
    o.pairing.sequence_depth = 4;
    SequenceMatcher m(o);
    m.SetPriorsExpected(false);
    std::vector<SequencePair> pairs;
    for (int i = 0; i < 5; ++i)
      for (const SequencePair& p : m.AddImage(i * kSecond, "cam", Photo(i)).pairs)
        pairs.push_back(p);
    runs.push_back(pairs);
  }
  ASSERT_EQ(runs[0].size(), 11u);  // photo 0 alone, then 1 + 2 + 3 + 4 pairs
  int points = 0;
  for (size_t r = 1; r < runs.size(); ++r) {
    ASSERT_EQ(runs[r].size(), runs[0].size());
    for (size_t k = 0; k < runs[0].size(); ++k) {
      const SequencePair &a = runs[0][k], &b = runs[r][k];
      EXPECT_EQ(a.stamp_a, b.stamp_a);
      EXPECT_EQ(a.reason, b.reason);
      ASSERT_EQ(a.points.size(), b.points.size()) << a.message << " / " << b.message;
      for (size_t i = 0; i < a.points.size(); ++i) {
        EXPECT_EQ(a.points[i].id, b.points[i].id);
        EXPECT_EQ(a.points[i].xb, b.points[i].xb);
        EXPECT_EQ(a.points[i].covariance, b.points[i].covariance);
      }
      points += static_cast<int>(a.points.size());
    }
  }
  EXPECT_GT(points, 500);
}

// The strip flown the other way: photo 1 turned by 180 deg. The photo method
// finds the rotation; the global shift cannot (it says so).
TEST(SequenceMatcher, PhotoMethodMatchesAPhotoTurnedBy180Degrees) {
  cv::Mat turned;
  cv::rotate(Photo(1), turned, cv::ROTATE_180);
  SequenceMatcherOptions o = Options(SequencePairMethod::kPhoto);
  o.fallback_shift_hex = false;
  SequenceMatcher m(o);
  m.SetPriorsExpected(false);
  m.AddImage(0, "cam", Photo(0));
  const SequenceStep s = m.AddImage(kSecond, "cam", turned);
  ASSERT_EQ(s.pairs.size(), 1u);
  const SequencePair& p = s.pairs[0];
  EXPECT_EQ(p.reason, "") << p.message;
  EXPECT_GT(p.points.size(), 50u) << p.message;
  int far = 0;
  for (const SequenceTie& t : p.points) {
    const Eigen::Vector2d truth(kSeqW - 1 - t.xa.x(), kSeqH - 1 - (t.xa.y() - kStep));
    if ((t.xb - truth).norm() > 0.1) ++far;
  }
  EXPECT_LE(far, static_cast<int>(p.points.size() / 100)) << p.message;

  SequenceMatcher hex(Options(SequencePairMethod::kGlobalShiftHex));
  hex.SetPriorsExpected(false);
  hex.AddImage(0, "cam", Photo(0));
  const SequencePair q = hex.AddImage(kSecond, "cam", turned).pairs.at(0);
  EXPECT_TRUE(q.points.empty() || q.reason != "") << q.message;
}

TEST(SequenceMatcher, GapStartsANewEpoch) {
  SequenceMatcher m(Options(SequencePairMethod::kGlobalShiftHex));
  m.SetPriorsExpected(false);
  m.AddImage(0, "cam", Photo(0));
  EXPECT_EQ(m.AddImage(1 * kSecond, "cam", Photo(1)).pairs.at(0).epoch, 1u);
  // 200 s later: beyond max_gap (120 s): alone in epoch 2.
  const SequenceStep s = m.AddImage(201 * kSecond, "cam", Photo(2));
  ASSERT_EQ(s.pairs.size(), 1u);
  EXPECT_FALSE(s.pairs[0].has_a);
  EXPECT_EQ(s.pairs[0].epoch, 2u);
  ASSERT_EQ(s.log.size(), 1u);
  EXPECT_NE(s.log[0].find("new sequence epoch at 201.000"), std::string::npos) << s.log[0];
  EXPECT_EQ(m.summary().images_in_memory, 1);  // epoch 1's photos released
}

TEST(SequenceMatcher, StampsRunningBackwardsStartANewEpoch) {
  SequenceMatcher m(Options(SequencePairMethod::kGlobalShiftHex));
  m.SetPriorsExpected(false);
  m.AddImage(10 * kSecond, "cam", Photo(0));
  m.AddImage(11 * kSecond, "cam", Photo(1));
  const SequenceStep s = m.AddImage(5 * kSecond, "cam", Photo(2));  // the bag replayed again
  ASSERT_EQ(s.pairs.size(), 1u);
  EXPECT_FALSE(s.pairs[0].has_a);
  EXPECT_EQ(s.pairs[0].epoch, 2u);
}

TEST(SequenceMatcher, ImageWaitsForItsPriorThatComesAfterIt) {
  SequenceMatcher m(RulesOptions(SequencePairMethod::kGlobalShiftHex));
  EXPECT_TRUE(m.AddImage(1 * kSecond, "cam", Photo(0)).pairs.empty());  // its prior not in yet
  const SequenceStep s0 = m.AddPrior(1 * kSecond, Eigen::Vector2d(0, 0));
  ASSERT_EQ(s0.pairs.size(), 1u);
  EXPECT_FALSE(s0.pairs[0].has_a);
  // Prior first, then the image: matched at once. 5 m away: a partner.
  m.AddPrior(2 * kSecond, Eigen::Vector2d(0, 5));
  const SequenceStep s1 = m.AddImage(2 * kSecond, "cam", Photo(1));
  ASSERT_EQ(s1.pairs.size(), 1u);
  EXPECT_EQ(s1.pairs[0].stamp_a, 1 * kSecond);
  // 100 m away from both (max_pair_distance 30 m): no partner.
  m.AddPrior(3 * kSecond, Eigen::Vector2d(100, 0));
  const SequenceStep s2 = m.AddImage(3 * kSecond, "cam", Photo(2));
  ASSERT_EQ(s2.pairs.size(), 1u);
  EXPECT_FALSE(s2.pairs[0].has_a);
}

// An image waiting for its prior is the matcher's copy: the caller's buffer
// (e.g. a ROS message's pixels) may be gone or reused by then.
TEST(SequenceMatcher, WaitingImageIsCopied) {
  SequenceMatcher m(Options(SequencePairMethod::kGlobalShiftHex));
  m.AddPrior(1 * kSecond, Eigen::Vector2d(0, 0));
  m.AddImage(1 * kSecond, "cam", Photo(0));
  cv::Mat buffer = Photo(1);
  EXPECT_TRUE(m.AddImage(2 * kSecond, "cam", buffer).pairs.empty());
  buffer.setTo(0);
  const SequenceStep s = m.AddPrior(2 * kSecond, Eigen::Vector2d(0, 5));
  ASSERT_EQ(s.pairs.size(), 1u);
  EXPECT_EQ(s.pairs[0].reason, "") << s.pairs[0].message;
  EXPECT_GT(s.pairs[0].points.size(), 50u) << s.pairs[0].message;
}

TEST(SequenceMatcher, MissingPriorIsGivenUpWhenThePriorsMovePastIt) {
  SequenceMatcher m(RulesOptions(SequencePairMethod::kGlobalShiftHex));
  m.AddPrior(1 * kSecond, Eigen::Vector2d(0, 0));
  m.AddImage(1 * kSecond, "cam", Photo(0));
  // Image 2 has no prior; it waits until a later prior shows its own is not coming.
  EXPECT_TRUE(m.AddImage(2 * kSecond, "cam", Photo(1)).pairs.empty());
  EXPECT_TRUE(m.AddImage(3 * kSecond, "cam", Photo(2)).pairs.empty());  // behind image 2
  const SequenceStep s = m.AddPrior(3 * kSecond, Eigen::Vector2d(0, 10));
  ASSERT_EQ(s.pairs.size(), 2u + 0u) << "image 2 (1 pair: previous image), image 3";
  EXPECT_EQ(s.pairs[0].stamp_b, 2 * kSecond);
  EXPECT_EQ(s.pairs[0].stamp_a, 1 * kSecond);  // without a prior: the previous images
  EXPECT_EQ(s.pairs[1].stamp_b, 3 * kSecond);
  EXPECT_EQ(s.pairs[1].stamp_a,
            1 * kSecond);  // with a prior: the earlier image with one, 10 m away
  EXPECT_EQ(m.summary().prior_timeouts, 0);
}

TEST(SequenceMatcher, PollGivesUpOnAPriorAfterPriorWaitAndSaysSo) {
  SequenceMatcher m(Options(SequencePairMethod::kGlobalShiftHex));  // prior_wait 2 s
  EXPECT_TRUE(m.AddImage(1 * kSecond, "cam", Photo(0), 100.0).pairs.empty());
  EXPECT_TRUE(m.Poll(101.0).pairs.empty());
  const SequenceStep s = m.Poll(102.5);
  ASSERT_EQ(s.pairs.size(), 1u);
  ASSERT_EQ(s.log.size(), 1u);
  EXPECT_NE(s.log[0].find("position prior of the image at 1.000 (frame 'cam') after 2.5 s"),
            std::string::npos)
      << s.log[0];
  EXPECT_EQ(m.summary().prior_timeouts, 1);
}

TEST(SequenceMatcher, FinishMatchesWhatWaits) {
  SequenceMatcher m(Options(SequencePairMethod::kGlobalShiftHex));
  m.AddImage(1 * kSecond, "cam", Photo(0));
  m.AddImage(2 * kSecond, "cam", Photo(1));
  const SequenceStep s = m.Finish();
  ASSERT_EQ(s.pairs.size(), 2u);
  EXPECT_EQ(s.pairs[1].stamp_a, 1 * kSecond);
  EXPECT_GT(s.pairs[1].points.size(), 50u);
}

TEST(SequenceMatcher, BadImageIsNamedAndNeverAPartner) {
  for (const SequencePairMethod method :
       {SequencePairMethod::kPhoto, SequencePairMethod::kGlobalShiftHex}) {
    SCOPED_TRACE(SequencePairMethodName(method));
    SequenceMatcher m(Options(method));
    m.SetPriorsExpected(false);
    m.AddImage(1 * kSecond, "cam", Photo(0));
    const SequenceStep bad = m.AddImage(2 * kSecond, "cam_optical", cv::Mat());
    ASSERT_EQ(bad.pairs.size(), 1u);
    EXPECT_EQ(bad.pairs[0].reason, "error");
    EXPECT_TRUE(bad.pairs[0].points.empty());
    EXPECT_NE(bad.pairs[0].message.find("image at 2.000 (frame 'cam_optical')"), std::string::npos)
        << bad.pairs[0].message;
    EXPECT_EQ(m.summary().errors, 1);
    // The next image pairs with the good one only.
    const SequenceStep next = m.AddImage(3 * kSecond, "cam", Photo(2));
    ASSERT_EQ(next.pairs.size(), 1u);
    EXPECT_EQ(next.pairs[0].stamp_a, 1 * kSecond);
    EXPECT_EQ(next.pairs[0].reason, "") << next.pairs[0].message;
  }
}

// One camera's photos of a flight share one camera model: another size is named.
TEST(SequenceMatcher, ImageOfAnotherSizeIsNamed) {
  for (const SequencePairMethod method :
       {SequencePairMethod::kPhoto, SequencePairMethod::kGlobalShiftHex}) {
    SCOPED_TRACE(SequencePairMethodName(method));
    SequenceMatcher m(Options(method));
    m.SetPriorsExpected(false);
    m.AddImage(1 * kSecond, "cam", Photo(0));
    const SequenceStep s =
        m.AddImage(2 * kSecond, "cam", Photo(1)(cv::Rect(0, 0, 200, 100)).clone());
    ASSERT_EQ(s.pairs.size(), 1u);
    EXPECT_EQ(s.pairs[0].reason, "error");
    EXPECT_NE(s.pairs[0].message.find(
                  "image at 2.000 (frame 'cam'): the image and the epoch's images differ in "
                  "size: 200 x 100, not 320 x 240"),
              std::string::npos)
        << s.pairs[0].message;
  }
}

// While the epoch has at most exhaustive_max_photos photos, every photo is
// kept and every later one pairs with all of them (process_flight's pairs).
TEST(SequenceMatcher, SmallFlightPairsEveryPhotoWithEveryEarlierOne) {
  SequenceMatcher m(Options(SequencePairMethod::kPhoto));
  m.SetPriorsExpected(false);
  std::vector<SequencePair> last;
  for (int i = 0; i < 5; ++i) last = m.AddImage(i * kSecond, "cam", Photo(i)).pairs;
  EXPECT_EQ(m.summary().images_in_memory, 5);
  EXPECT_EQ(m.summary().released, 0);
  EXPECT_EQ(m.summary().pairs, 1 + 2 + 3 + 4);
  ASSERT_EQ(last.size(), 4u);
  for (size_t k = 0; k < last.size(); ++k)
    EXPECT_EQ(last[k].stamp_a, static_cast<std::int64_t>(3 - k) * kSecond);  // latest first
}

TEST(SequenceMatcher, PhotosNoLaterImageCanPairWithAreReleased) {
  // Without priors only the previous sequence_depth (2) photos can be partners.
  SequenceMatcher m(RulesOptions(SequencePairMethod::kPhoto));
  m.SetPriorsExpected(false);
  for (int i = 0; i < 5; ++i) m.AddImage(i * kSecond, "cam", Photo(i));
  EXPECT_EQ(m.summary().images_in_memory, 2);
  EXPECT_EQ(m.summary().released, 3);
  EXPECT_GT(m.summary().memory_bytes, 2u * kSeqW * kSeqH);  // grey images + features of two photos
  EXPECT_LT(m.summary().memory_bytes, m.summary().peak_memory_bytes);  // three before the release
}

TEST(SequenceMatcher, MemoryLimitReleasesTheOldestPhotos) {
  SequenceMatcherOptions o = Options(SequencePairMethod::kGlobalShiftHex);
  o.max_memory_mb = 2.5 * kSeqW * kSeqH / (1024.0 * 1024.0);  // room for two grey photos
  SequenceMatcher m(o);
  std::vector<std::string> log;
  for (int i = 0; i < 4; ++i) {
    m.AddPrior(i * kSecond, Eigen::Vector2d(0, i));  // all within reach of each other
    for (const std::string& line : m.AddImage(i * kSecond, "cam", Photo(i)).log)
      log.push_back(line);
  }
  EXPECT_EQ(m.summary().images_in_memory, 2);
  EXPECT_EQ(m.summary().memory_bytes, 2u * kSeqW * kSeqH);
  ASSERT_EQ(log.size(), 2u);
  EXPECT_NE(log[0].find("released the oldest photo (0.000)"), std::string::npos) << log[0];
}

TEST(SequenceMatcher, OptionsNameTheBadField) {
  SequenceMatcherOptions o;
  o.max_memory_mb = 0;
  try {
    o.Check();
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("max_memory_mb"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SequencePairMethodFromName("sift"), ConfigError);
  EXPECT_EQ(SequencePairMethodFromName("shift_hex"), SequencePairMethod::kGlobalShiftHex);
}

}  // namespace
}  // namespace matching
}  // namespace slope_monitor
