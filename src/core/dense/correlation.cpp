#include "slope_monitor/core/dense/correlation.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <sstream>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#if defined(__GNUC__) && defined(__x86_64__)
#include <immintrin.h>
#endif

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/matching/filters.h"

namespace slope_monitor {
namespace dense {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

inline bool Finite(float v) { return v == v; }

// Result of one search direction on one level: dense per-pixel parallax.
struct DenseResult {
  cv::Mat disparity;    // CV_32F level px, NaN invalid
  cv::Mat correlation;  // CV_32F
};

inline int Reflect101(int i, int n) {
  if (n == 1) return 0;
  while (i < 0 || i >= n) i = i < 0 ? -i : 2 * n - 2 - i;
  return i;
}

// The row kernels below are compiled twice (AVX2 and the baseline) and picked
// at load time, so the inner loops use 8-wide vectors where the CPU has them.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
#define SM_DENSE_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define SM_DENSE_CLONES
#endif

// Adds image row (l, idx, rp) of the right image warped by offset k to the
// column sums of w, w^2 and l*w (AccumulateRow), or a row in and a row out
// (UpdateRows):  v(x) = rp[idx(x) - k].
SM_DENSE_CLONES void AccumulateRow(const float* __restrict l, const int* __restrict idx,
                                   const float* __restrict rp, int k, int w, float* __restrict cw,
                                   float* __restrict cww, float* __restrict clw) {
  for (int x = 0; x < w; ++x) {
    const float v = rp[idx[x] - k];
    cw[x] += v;
    cww[x] += v * v;
    clw[x] += l[x] * v;
  }
}

SM_DENSE_CLONES void UpdateRows(const float* __restrict la, const int* __restrict ia,
                                const float* __restrict ra, const float* __restrict ls,
                                const int* __restrict is, const float* __restrict rs, int k, int w,
                                float* __restrict cw, float* __restrict cww,
                                float* __restrict clw) {
  for (int x = 0; x < w; ++x) {
    const float va = ra[ia[x] - k], vs = rs[is[x] - k];
    cw[x] += va - vs;
    cww[x] += va * va - vs * vs;
    clw[x] += la[x] * va - ls[x] * vs;
  }
}

// out[x] = sum_{j = 0}^{len-1} in[x + j] for x in [0, n), by doubling:
// partial sums of 1, 2, 4, ... elements combined by the binary digits of len
// (about 2 log2(len) vector passes). tmp: 2 (n + len) floats.
// Short windows (3, 5, 7) directly: one pass with len loads and one store
// instead of about four passes.
template <int L>
SM_DENSE_CLONES void SlidingSumShort(const float* __restrict in, int n, float* __restrict out) {
  for (int x = 0; x < n; ++x) {
    float s = in[x];
    for (int j = 1; j < L; ++j) s += in[x + j];
    out[x] = s;
  }
}

SM_DENSE_CLONES void SlidingSum(const float* __restrict in, int n, int len, float* __restrict out,
                                float* __restrict tmp) {
  if (len == 3) return SlidingSumShort<3>(in, n, out);
  if (len == 5) return SlidingSumShort<5>(in, n, out);
  if (len == 7) return SlidingSumShort<7>(in, n, out);
  const int total = n + len - 1;  // elements of `in` used
  const float* p = in;            // sums of `span` consecutive elements
  float* q = tmp;
  float* q2 = tmp + total;
  int span = 1, done = 0;
  bool first = true;
  for (int bit = 0; (1 << bit) <= len; ++bit) {
    if (len & (1 << bit)) {
      const float* src = p + done;
      if (first) {
        for (int x = 0; x < n; ++x) out[x] = src[x];
        first = false;
      } else {
        for (int x = 0; x < n; ++x) out[x] += src[x];
      }
      done += span;
    }
    if ((2 << bit) > len) break;
    // Only the part still needed: positions done .. done + n + (len - done - 2 span) of the new
    // sums.
    const int valid = total - 2 * span + 1;
    const float* __restrict pp = p;
    float* __restrict qq = q;
    for (int x = 0; x < valid; ++x) qq[x] = pp[x] + pp[x + span];
    p = q;
    std::swap(q, q2);
    span *= 2;
  }
}

// Without a right mask: score = -2 where the warped centre leaves [lo, hi)
// or the left window is unusable (branch-free, vectorised).
SM_DENSE_CLONES void ValidRange(const int* __restrict idx, int k, int lo, int hi,
                                const float* __restrict il, int w, float* __restrict score) {
  for (int x = 0; x < w; ++x) {
    const int i = idx[x] - k;
    const bool ok = (i >= lo) & (i < hi) & (il[x] > 0.0f);
    score[x] = ok ? score[x] : -2.0f;
  }
}

// ZNCC of one row for one offset from the window sums. A window is usable
// when the left window has content and variance (il > 0) and the right
// window around the warped centre lies on content (okr[idx(x) - k] = 1: the
// right mask eroded by the window, padded with 0).
void ScoreRowScalar(const float* bw, const float* bww, const float* blw, const float* ml,
                    const float* il, float inv_count, float min_var, int x0, int w, float* score) {
  for (int x = x0; x < w; ++x) {
    const float var_r = bww[x] - bw[x] * bw[x] * inv_count;
    const float cov = blw[x] - ml[x] * bw[x];
    score[x] = var_r > min_var ? cov * il[x] / std::sqrt(var_r) : -2.0f;
  }
}

#if defined(__GNUC__) && defined(__x86_64__)
#define SM_DENSE_HAVE_AVX2_PATH 1
__attribute__((target("avx2"))) void ScoreRowAvx2(const float* bw, const float* bww,
                                                  const float* blw, const float* ml,
                                                  const float* il, float inv_count, float min_var,
                                                  int w, float* score) {
  const __m256 vinv = _mm256_set1_ps(inv_count), vmin = _mm256_set1_ps(min_var),
               vbad = _mm256_set1_ps(-2.0f);
  int x = 0;
  for (; x + 8 <= w; x += 8) {
    const __m256 sw = _mm256_loadu_ps(bw + x);
    const __m256 var_r =
        _mm256_sub_ps(_mm256_loadu_ps(bww + x), _mm256_mul_ps(_mm256_mul_ps(sw, sw), vinv));
    const __m256 cov =
        _mm256_sub_ps(_mm256_loadu_ps(blw + x), _mm256_mul_ps(_mm256_loadu_ps(ml + x), sw));
    const __m256 ok = _mm256_cmp_ps(var_r, vmin, _CMP_GT_OQ);
    const __m256 s = _mm256_div_ps(_mm256_mul_ps(cov, _mm256_loadu_ps(il + x)),
                                   _mm256_sqrt_ps(_mm256_max_ps(var_r, vmin)));
    _mm256_storeu_ps(score + x, _mm256_blendv_ps(vbad, s, ok));
  }
  ScoreRowScalar(bw, bww, blw, ml, il, inv_count, min_var, x, w, score);
}
#endif

// ZNCC of one row for one offset from the window sums. A window is usable
// when the left window has content and variance (il > 0) and the right
// window around the warped centre lies on content (okr[idx(x) - k] = 1: the
// right mask eroded by the window, padded with 0).
// okr == nullptr: the right image has no mask; the right window is on
// content when the warped centre lies in [lo, hi) of the padded row.
void ScoreRow(const float* bw, const float* bww, const float* blw, const float* okr, const int* idx,
              int k, int lo, int hi, const float* ml, const float* il, float inv_count,
              float min_var, int w, float* score) {
#ifdef SM_DENSE_HAVE_AVX2_PATH
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2)
    ScoreRowAvx2(bw, bww, blw, ml, il, inv_count, min_var, w, score);
  else
#endif
    ScoreRowScalar(bw, bww, blw, ml, il, inv_count, min_var, 0, w, score);
  if (okr) {
    for (int x = 0; x < w; ++x)
      if (!(okr[idx[x] - k] > 0.5f) || !(il[x] > 0.0f)) score[x] = -2.0f;
  } else {
    ValidRange(idx, k, lo, hi, il, w, score);
  }
}

// Running arg-max over the offsets.
SM_DENSE_CLONES void ArgMaxRow(const float* __restrict score, int ki, int w,
                               float* __restrict best_s, int* __restrict best_k) {
  for (int x = 0; x < w; ++x) {
    const bool better = score[x] > best_s[x];
    best_s[x] = better ? score[x] : best_s[x];
    best_k[x] = better ? ki : best_k[x];
  }
}

// Per-thread working memory of Search, kept between calls (no allocation per
// pixel, and none per call once the sizes are reached).
struct SearchBuffers {
  std::vector<float> col;          // n offsets x 3 channels x (w + 2 r): column sums of w, w^2, l*w
  std::vector<float> box;          // 3 x w: window sums of the current row and offset
  std::vector<float> tmp;          // SlidingSum scratch
  std::vector<float> col_small;    // the same for the small window near depth edges
  std::vector<float> scores;       // n x w: ZNCC of the current row per offset
  std::vector<float> score_small;  // w: ZNCC of the small window
  std::vector<float> best_s;
  std::vector<int> best_k;
  std::vector<uint64_t>
      best_key;  // right-to-left from the volume: best (score, left pixel) per right pixel
  std::vector<uint32_t> best_key32, keys;
  std::vector<int> slots;
  std::vector<int> x0;
};

// Per-window quantities of a search (the main window, and the small window
// used near depth edges): left window mean and 1 / sqrt(variance) (0 =
// unusable), and the padded right "window on content" flags.
struct WindowStats {
  int window = 0;
  cv::Mat sum_l, sum_ll, ok_l, ok_r, mean_l, inv_sd_l, bp;
};

struct SearchWorkspace {
  WindowStats main, small;
  cv::Mat rp, idx;
};

// Per pyramid level, per thread: the search workspaces and results, reused by
// the next call (a surface is usually measured patch after patch of one size).
struct LevelWorkspace {
  SearchWorkspace ws_l, ws_r;
  DenseResult res_l, res_r;
  cv::Mat median_l, median_r;
  cv::Mat edge_l, edge_r, e16, ehi, elo;
  cv::Mat pred_l, pred_r;
  cv::Mat out_disp[2], out_corr[2];  // output buffers (see OutputBuffer)
  cv::Mat down_l, down_r, log_l, log_r, log_tmp, log_tmp_r, mask_l, mask_r, base_l, base_r;
};

constexpr int kInputSlot = 8;  // LevelCache slot of the float input images (levels are 0 .. 4)

int CountFinite(const cv::Mat& m) {
  int n = 0;
  for (int i = 0; i < m.rows; ++i) {
    const float* p = m.ptr<float>(i);
    for (int j = 0; j < m.cols; ++j) n += Finite(p[j]);
  }
  return n;
}

std::vector<LevelWorkspace>& LevelCacheVector() {
  static thread_local std::vector<LevelWorkspace> cache;
  return cache;
}

LevelWorkspace& LevelCache(int level) {
  std::vector<LevelWorkspace>& cache = LevelCacheVector();
  if (static_cast<int>(cache.size()) <= level) cache.resize(level + 1);
  return cache[level];
}

// Images larger than this do not keep their workspaces after the call (about
// 30 float images of this size would stay allocated per thread).
constexpr double kMaxCachedPixels = 2.0e6;

// left_all_valid / right_all_valid: the mask is all ones (no erosion needed;
// no right flags: the search checks the warped centre instead).
void ComputeWindowStats(const cv::Mat& left, const cv::Mat& mask_left, const cv::Mat& mask_right,
                        int window, int off, int wp, bool left_all_valid, bool right_all_valid,
                        WindowStats& st) {
  const int w = left.cols, h = left.rows, r = window / 2;
  const float count = static_cast<float>(window) * window, inv_count = 1.0f / count;
  const float min_var = 1e-12f * count;
  const cv::Size box(window, window);
  st.window = window;
  cv::boxFilter(left, st.sum_l, CV_32F, box, cv::Point(-1, -1), false, cv::BORDER_REFLECT_101);
  cv::sqrBoxFilter(left, st.sum_ll, CV_32F, box, cv::Point(-1, -1), false, cv::BORDER_REFLECT_101);
  // The whole window has content (pixels outside the image do not count).
  if (!left_all_valid)
    cv::erode(mask_left, st.ok_l, cv::getStructuringElement(cv::MORPH_RECT, box), cv::Point(-1, -1),
              1, cv::BORDER_CONSTANT, cv::Scalar(1));
  if (!right_all_valid) {
    cv::erode(mask_right, st.ok_r, cv::getStructuringElement(cv::MORPH_RECT, box),
              cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(1));
    st.bp.create(h, wp, CV_32F);
  }
  st.mean_l.create(h, w, CV_32F);
  st.inv_sd_l.create(h, w, CV_32F);
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const float* s = st.sum_l.ptr<float>(y);
      const float* ss = st.sum_ll.ptr<float>(y);
      const uchar* ok = left_all_valid ? nullptr : st.ok_l.ptr<uchar>(y);
      float* m = st.mean_l.ptr<float>(y);
      float* is = st.inv_sd_l.ptr<float>(y);
      for (int x = 0; x < w; ++x) {
        m[x] = s[x] * inv_count;
        const float var = ss[x] - s[x] * m[x];
        is[x] = ((!ok || ok[x]) && var > min_var) ? 1.0f / std::sqrt(var) : 0.0f;
      }
      if (right_all_valid) continue;
      float* pb = st.bp.ptr<float>(y);
      std::fill(pb, pb + wp, 0.0f);
      const uchar* okr = st.ok_r.ptr<uchar>(y);
      // Columns closer than r to the border: the window would leave the image.
      for (int x = 0; x < w; ++x) pb[off + x] = (okr[x] && x >= r && x < w - r) ? 1.0f : 0.0f;
    }
  });
}

// Running column sums (w, w^2, l*w of the warped right image) of one window
// height for one row and offset: set up at the first row of a stripe, then
// one row in and one out.
inline void ColumnSums(const cv::Mat& left, const cv::Mat& idx, const cv::Mat& rp, int y, int y0,
                       int h, int r, int k, int w, float* c0, float* c1, float* c2) {
  if (y == y0) {
    for (int j = -r; j <= r; ++j) {
      const int yy = Reflect101(y + j, h);
      AccumulateRow(left.ptr<float>(yy), idx.ptr<int>(yy), rp.ptr<float>(yy), k, w, c0, c1, c2);
    }
  } else {
    const int ya = Reflect101(y + r, h), ys = Reflect101(y - r - 1, h);
    UpdateRows(left.ptr<float>(ya), idx.ptr<int>(ya), rp.ptr<float>(ya), left.ptr<float>(ys),
               idx.ptr<int>(ys), rp.ptr<float>(ys), k, w, c0, c1, c2);
  }
}

// The right-to-left matches of one row from the left search's scores
// (scores[ki * w + x]: left pixel x, parallax base[x] + k_min + ki); see
// Search. The best candidate per right pixel is kept as one integer key (the
// score quantised to 19 bits above the left pixel's column, 13 bits; rows up
// to 8192 px, else a 64-bit key), so the scatter is a branch-free maximum;
// the winner's exact score is read back.

// Candidates outside the row go to one of these dummy slots after the row
// (by column, so that consecutive stores do not wait for each other).
constexpr int kDummySlots = 64;

// Keys and target slots of one offset for a whole row (vectorised).
SM_DENSE_CLONES void KeysOfOffset(const float* __restrict s, const int* __restrict x0, int ki,
                                  int w, uint32_t* __restrict key, int* __restrict slot) {
  for (int x = 0; x < w; ++x) {
    const int xr0 = x0[x] - ki;
    slot[x] =
        static_cast<unsigned>(xr0) < static_cast<unsigned>(w) ? xr0 : w + (x & (kDummySlots - 1));
    key[x] = (static_cast<uint32_t>((s[x] + 2.0f) * 131071.0f) << 13) | static_cast<uint32_t>(x);
  }
}

template <typename Key>
void ScatterBest(const float* sc, const int* x0, int n, int w, Key* best, SearchBuffers& buf) {
  std::fill(best, best + w + kDummySlots, Key(0));  // 0: nothing (score -2)
  if constexpr (sizeof(Key) == 4) {
    uint32_t* key = buf.keys.data();
    int* slot = buf.slots.data();
    for (int ki = 0; ki < n; ++ki) {
      KeysOfOffset(sc + static_cast<size_t>(ki) * w, x0, ki, w, key, slot);
      for (int x = 0; x < w; ++x) {
        const uint32_t k = key[x], old = best[slot[x]];
        best[slot[x]] = k > old ? k : old;
      }
    }
  } else {
    for (int ki = 0; ki < n; ++ki) {
      const float* __restrict s = sc + static_cast<size_t>(ki) * w;
      for (int x = 0; x < w; ++x) {
        const int xr0 = x0[x] - ki;
        const int xr = static_cast<unsigned>(xr0) < static_cast<unsigned>(w)
                           ? xr0
                           : w + (x & (kDummySlots - 1));
        const Key k = (static_cast<Key>((s[x] + 2.0f) * 1.0e9f) << 32) | static_cast<Key>(x);
        const Key old = best[xr];
        best[xr] = k > old ? k : old;
      }
    }
  }
}

void RightFromVolume(const float* sc, const int* b, int k_min, int n, int w, float min_corr,
                     SearchBuffers& buf, float* d, float* cc) {
  // x0[x] = x - base[x] - k_min is the right pixel of offset 0.
  int* x0 = buf.x0.data();
  for (int x = 0; x < w; ++x) x0[x] = x - (b ? b[x] : 0) - k_min;
  const bool narrow = w <= 8192;
  if (narrow)
    ScatterBest<uint32_t>(sc, x0, n, w, buf.best_key32.data(), buf);
  else
    ScatterBest<uint64_t>(sc, x0, n, w, buf.best_key.data(), buf);
  auto score_at = [&](int xl, int D) {
    if (xl < 0 || xl >= w) return -2.0f;
    const int ki = D - (b ? b[xl] : 0) - k_min;
    return (ki >= 0 && ki < n) ? sc[static_cast<size_t>(ki) * w + xl] : -2.0f;
  };
  for (int xr = 0; xr < w; ++xr) {
    const uint64_t k = narrow ? buf.best_key32[xr] : buf.best_key[xr];
    const int x = static_cast<int>(narrow ? (k & 8191u) : (k & 0xffffffffu));  // the left pixel
    const int ki = x0[x] - xr;
    if (k == 0 || ki <= 0 || ki >= n - 1) {
      d[xr] = kNaN;
      cc[xr] = kNaN;
      continue;
    }
    const float bs = sc[static_cast<size_t>(ki) * w + x];
    if (bs < min_corr) {
      d[xr] = kNaN;
      cc[xr] = kNaN;
      continue;
    }
    const int D = x - xr;
    const float sm = score_at(xr + D - 1, D - 1), sp = score_at(xr + D + 1, D + 1);
    float delta = 0.0f;
    const float curv = sm - 2.0f * bs + sp;
    if (sm > -2.0f && sp > -2.0f && curv < 0.0f)
      delta = std::clamp(0.5f * (sm - sp) / curv, -0.5f, 0.5f);
    d[xr] = static_cast<float>(D) + delta;
    cc[xr] = bs;
  }
}

// Search's padded right image (ws.rp: zero outside the mask and in the
// padding of `pad` columns each side, row offset 2 pad) and its index
// (ws.idx: x - direction base(y, x), clamped to the padding, plus the
// offset), so that v = rp[idx - k] needs no branch.
void PadRightImage(const cv::Mat& right, const cv::Mat& mask_right, const cv::Mat& base,
                   int direction, int pad, SearchWorkspace& ws) {
  const int w = right.cols, h = right.rows;
  const int off = 2 * pad, wp = w + 4 * pad;
  ws.rp.create(h, wp, CV_32F);
  ws.idx.create(h, w, CV_32S);
  cv::parallel_for_(cv::Range(0, h), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      std::fill(ws.rp.ptr<float>(y), ws.rp.ptr<float>(y) + wp, 0.0f);
      const float* rr = right.ptr<float>(y);
      const uchar* mr = mask_right.ptr<uchar>(y);
      float* o = ws.rp.ptr<float>(y) + off;
      for (int x = 0; x < w; ++x) o[x] = mr[x] ? rr[x] : 0.0f;
      const int* b = base.empty() ? nullptr : base.ptr<int>(y);
      int* id = ws.idx.ptr<int>(y);
      for (int x = 0; x < w; ++x)
        id[x] = std::clamp(x - direction * (b ? b[x] : 0), -pad, w - 1 + pad) + off;
    }
  });
}

// One row of Search's result from its scores `sc` (n rows of w, one per
// parallax step) and each pixel's best step: the parallax refined by the
// parabola through the best score and its neighbours (at most half a step),
// NaN where the best is at the border of the range or below min_corr.
void SubPixelRow(const float* sc, const float* best_s, const int* best_k, const int* b, int k_min,
                 int n, int w, float min_corr, float* d, float* cc) {
  for (int x = 0; x < w; ++x) {
    const int best = best_k[x];
    const float bs = best_s[x];
    if (best <= 0 || best >= n - 1 || bs < min_corr) {
      d[x] = kNaN;
      cc[x] = kNaN;
      continue;
    }
    const float sm = sc[static_cast<size_t>(best - 1) * w + x],
                sp = sc[static_cast<size_t>(best + 1) * w + x];
    float delta = 0.0f;
    const float curv = sm - 2.0f * bs + sp;
    if (sm > -2.0f && sp > -2.0f && curv < 0.0f)
      delta = std::clamp(0.5f * (sm - sp) / curv, -0.5f, 0.5f);
    d[x] = static_cast<float>((b ? b[x] : 0) + k_min + best) + delta;
    cc[x] = bs;
  }
}

// ZNCC search of `left` against `right` for parallaxes base(x) + k, k in
// [k_min, k_max] (base: per-pixel integer prediction, CV_32S, or empty = 0).
// Masks: CV_8U 1 = content. The right image is warped by base + k and the
// window sums of the warped values, their squares and their products with the
// left image are kept as running sums: column sums updated by one row in and
// one row out per image row, window sums along the row by doubling sums, so
// the cost per pixel and offset hardly depends on the window. Rows are split
// into stripes processed in parallel.
//
// `edge` (CV_8U, optional) marks pixels whose window straddles a depth edge
// of the prediction: there the ZNCC of the small `edge_window` replaces that
// of `window` (computed only on rows that hold such a pixel).
//
// direction +1: `left` is the left image, a pixel x matches right x - (base + k);
// direction -1: `left` is the RIGHT image and `right` the left one, a pixel x
// matches x + (base + k) (the right-to-left search without mirroring).
// `out_right` (direction +1 only, optional): the right-to-left matches taken
// from the same correlation volume: each right pixel xr gets the parallax D
// of the best score among all (left pixel x, parallax D) with x - D = xr
// (the same pair of windows as a right-to-left search, up to the per-pixel
// prediction inside the window), sub-pixel by the parabola through its
// neighbours (xr + D - 1, D - 1) and (xr + D + 1, D + 1); a maximum at the
// border of its left pixel's range is rejected as on the left.
// `ws` and `out` are kept by the caller between calls (same sizes: no new
// memory, no page faults).
void Search(const cv::Mat& left, const cv::Mat& right, const cv::Mat& base, int k_min, int k_max,
            int window, double min_correlation, const cv::Mat& mask_left, const cv::Mat& mask_right,
            int direction, const cv::Mat& edge, int edge_window, SearchWorkspace& ws,
            DenseResult& out, DenseResult* out_right = nullptr) {
  const int w = left.cols, h = left.rows;
  const int n = k_max - k_min + 1;
  const int pad = std::max(std::abs(k_min), std::abs(k_max)) + 1;
  const int off = 2 * pad, wp = w + 4 * pad;
  const bool two_windows = !edge.empty() && edge_window > 0 && edge_window != window;
  const bool left_all_valid = cv::countNonZero(mask_left) == w * h;
  const bool right_all_valid = cv::countNonZero(mask_right) == w * h;
  ComputeWindowStats(left, mask_left, mask_right, window, off, wp, left_all_valid, right_all_valid,
                     ws.main);
  if (two_windows)
    ComputeWindowStats(left, mask_left, mask_right, edge_window, off, wp, left_all_valid,
                       right_all_valid, ws.small);
  std::vector<char> row_has_edge(h, 0);
  if (two_windows)
    for (int y = 0; y < h; ++y) row_has_edge[y] = cv::countNonZero(edge.row(y)) > 0;

  PadRightImage(right, mask_right, base, direction, pad, ws);

  out.disparity.create(h, w, CV_32F);
  out.correlation.create(h, w, CV_32F);
  if (out_right) {
    out_right->disparity.create(h, w, CV_32F);
    out_right->correlation.create(h, w, CV_32F);
  }
  const float min_corr = static_cast<float>(min_correlation);
  const int stripes = std::max(1, std::min(h / 16, 4 * std::max(1, cv::getNumThreads())));
  const cv::Mat& idx = ws.idx;
  const cv::Mat& rp = ws.rp;

  cv::parallel_for_(
      cv::Range(0, stripes),
      [&](const cv::Range& range) {
        static thread_local SearchBuffers buf;
        const int r_main = window / 2, r_small = edge_window / 2;
        const int r_max = two_windows ? std::max(r_main, r_small) : r_main;
        const int cw_len = w + 2 * r_max;
        buf.col.resize(static_cast<size_t>(n) * 3 * cw_len);
        if (two_windows) buf.col_small.resize(static_cast<size_t>(n) * 3 * cw_len);
        buf.box.resize(3 * static_cast<size_t>(w));
        buf.tmp.resize(2 * static_cast<size_t>(cw_len + std::max(window, edge_window)));
        buf.scores.resize(static_cast<size_t>(n) * w);
        buf.score_small.resize(w);
        buf.best_s.resize(w);
        buf.best_k.resize(w);
        if (w <= 8192) {
          buf.best_key32.resize(w + kDummySlots);
          buf.keys.resize(w);
          buf.slots.resize(w);
        } else {
          buf.best_key.resize(w + kDummySlots);
        }
        buf.x0.resize(w);
        // Window sums of a row from column sums (columns reflected at the image border) and the
        // ZNCC.
        auto score_row = [&](std::vector<float>& col, int ki, int k, int y, const WindowStats& st,
                             float* score) {
          const int win = st.window, r = win / 2;
          const float count = static_cast<float>(win) * win;
          float* bx[3];
          for (int ch = 0; ch < 3; ++ch) {
            float* c = &col[(static_cast<size_t>(ki) * 3 + ch) * cw_len] + r_max;
            for (int j = 1; j <= r; ++j) {
              c[-j] = c[Reflect101(-j, w)];
              c[w - 1 + j] = c[Reflect101(w - 1 + j, w)];
            }
            bx[ch] = buf.box.data() + static_cast<size_t>(ch) * w;
            SlidingSum(c - r, w, win, bx[ch], buf.tmp.data());
          }
          ScoreRow(bx[0], bx[1], bx[2], right_all_valid ? nullptr : st.bp.ptr<float>(y),
                   idx.ptr<int>(y), k, off + r, off + w - r, st.mean_l.ptr<float>(y),
                   st.inv_sd_l.ptr<float>(y), 1.0f / count, 1e-12f * count, w, score);
        };
        for (int stripe = range.start; stripe < range.end; ++stripe) {
          const int y0 = static_cast<int>(static_cast<long>(h) * stripe / stripes);
          const int y1 = static_cast<int>(static_cast<long>(h) * (stripe + 1) / stripes);
          std::fill(buf.col.begin(), buf.col.end(), 0.0f);
          int small_y0 = -1;  // first row of the running small-window sums (restarted after rows
                              // without edges)
          for (int y = y0; y < y1; ++y) {
            float* best_s = buf.best_s.data();
            int* best_k = buf.best_k.data();
            std::fill(buf.best_s.begin(), buf.best_s.end(), -2.0f);
            std::fill(buf.best_k.begin(), buf.best_k.end(), -10);
            const bool small_row = two_windows && row_has_edge[y];
            if (small_row && small_y0 < 0) {
              small_y0 = y;
              std::fill(buf.col_small.begin(), buf.col_small.end(), 0.0f);
            }
            if (!small_row) small_y0 = -1;
            const uchar* er = small_row ? edge.ptr<uchar>(y) : nullptr;
            for (int ki = 0; ki < n; ++ki) {
              const int k = direction * (k_min + ki);  // index shift in the padded row
              float* c[3];
              for (int ch = 0; ch < 3; ++ch)
                c[ch] = &buf.col[(static_cast<size_t>(ki) * 3 + ch) * cw_len] + r_max;
              ColumnSums(left, idx, rp, y, y0, h, r_main, k, w, c[0], c[1], c[2]);
              float* score = buf.scores.data() + static_cast<size_t>(ki) * w;
              score_row(buf.col, ki, k, y, ws.main, score);
              if (small_row) {
                for (int ch = 0; ch < 3; ++ch)
                  c[ch] = &buf.col_small[(static_cast<size_t>(ki) * 3 + ch) * cw_len] + r_max;
                ColumnSums(left, idx, rp, y, small_y0, h, r_small, k, w, c[0], c[1], c[2]);
                float* ss = buf.score_small.data();
                score_row(buf.col_small, ki, k, y, ws.small, ss);
                for (int x = 0; x < w; ++x)
                  if (er[x]) score[x] = ss[x];
              }
              ArgMaxRow(score, ki, w, best_s, best_k);
            }
            const int* b = base.empty() ? nullptr : base.ptr<int>(y);
            const float* sc = buf.scores.data();
            SubPixelRow(sc, best_s, best_k, b, k_min, n, w, min_corr, out.disparity.ptr<float>(y),
                        out.correlation.ptr<float>(y));
            if (out_right)
              RightFromVolume(sc, b, k_min, n, w, min_corr, buf, out_right->disparity.ptr<float>(y),
                              out_right->correlation.ptr<float>(y));
          }
        }
      },
      stripes);
}

// Grid of nodes (i, j) at level pixel (j * g, i * g).
cv::Mat SampleGrid(const cv::Mat& dense_map, int g) {
  if (g == 1) return dense_map;
  const int ni = (dense_map.rows - 1) / g + 1, nj = (dense_map.cols - 1) / g + 1;
  cv::Mat grid(ni, nj, CV_32F);
  for (int i = 0; i < ni; ++i) {
    const float* src = dense_map.ptr<float>(i * g);
    float* dst = grid.ptr<float>(i);
    for (int j = 0; j < nj; ++j) dst[j] = src[static_cast<ptrdiff_t>(j) * g];
  }
  return grid;
}

// The 3 x 3 median of the valid (finite) values around the inner nodes of a
// line, branch-free (AVX2, 8 nodes at a time): with k missing values, the median of the
// 9 - k valid ones is the middle of the nine after ceil(k/2) missing ones are
// set to +inf and the rest to -inf (the upper middle when 9 - k is even), or
// after floor(k/2) to +inf (the lower middle); the mean of both is the
// median (the mean of the two middle values for an even count). Nodes that
// are missing themselves stay missing. Returns the first column it did not
// process (1: none; the caller sorts the rest).
int MedianRowScalar(const float*, const float*, const float*, int, float*) { return 1; }

#ifdef SM_DENSE_HAVE_AVX2_PATH
__attribute__((target("avx2"))) int MedianRowAvx2(const float* up, const float* mid,
                                                  const float* dn, int n, float* o) {
  const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity()),
               ninf = _mm256_sub_ps(_mm256_setzero_ps(), inf);
  const __m256 one = _mm256_set1_ps(1.0f), two = _mm256_set1_ps(2.0f), half = _mm256_set1_ps(0.5f);
  int j = 1;
  for (; j + 8 <= n - 1; j += 8) {
    __m256 v[9] = {
        _mm256_loadu_ps(up + j - 1),  _mm256_loadu_ps(up + j),  _mm256_loadu_ps(up + j + 1),
        _mm256_loadu_ps(mid + j - 1), _mm256_loadu_ps(mid + j), _mm256_loadu_ps(mid + j + 1),
        _mm256_loadu_ps(dn + j - 1),  _mm256_loadu_ps(dn + j),  _mm256_loadu_ps(dn + j + 1)};
    __m256 miss[9], c[9];
    __m256 k = _mm256_setzero_ps();
    for (int q = 0; q < 9; ++q) {
      miss[q] = _mm256_cmp_ps(v[q], v[q], _CMP_UNORD_Q);
      c[q] = k;
      k = _mm256_add_ps(k, _mm256_and_ps(miss[q], one));
    }
    __m256 a[9], b[9];
    for (int q = 0; q < 9; ++q) {
      const __m256 c2 = _mm256_mul_ps(two, c[q]);
      const __m256 fa = _mm256_blendv_ps(ninf, inf, _mm256_cmp_ps(c2, k, _CMP_LT_OQ));
      const __m256 fb =
          _mm256_blendv_ps(ninf, inf, _mm256_cmp_ps(_mm256_add_ps(c2, one), k, _CMP_LT_OQ));
      a[q] = _mm256_blendv_ps(v[q], fa, miss[q]);
      b[q] = _mm256_blendv_ps(v[q], fb, miss[q]);
    }
    for (__m256* p : {a, b}) {
      // The median network, six exchanges a line (not reflowed by clang-format).
      // clang-format off
#define SM_V2(x, y)                              \
  {                                              \
    const __m256 lo = _mm256_min_ps(p[x], p[y]); \
    p[y] = _mm256_max_ps(p[x], p[y]);            \
    p[x] = lo;                                   \
  }
      SM_V2(1, 2) SM_V2(4, 5) SM_V2(7, 8) SM_V2(0, 1) SM_V2(3, 4) SM_V2(6, 7)
      SM_V2(1, 2) SM_V2(4, 5) SM_V2(7, 8) SM_V2(0, 3) SM_V2(5, 8) SM_V2(4, 7)
      SM_V2(3, 6) SM_V2(1, 4) SM_V2(2, 5) SM_V2(4, 7) SM_V2(4, 2) SM_V2(6, 4)
      SM_V2(4, 2)
      // clang-format on
#undef SM_V2
    }
    const __m256 m = _mm256_mul_ps(half, _mm256_add_ps(b[4], a[4]));
    _mm256_storeu_ps(o + j, _mm256_blendv_ps(m, v[4], miss[4]));  // missing nodes stay missing
  }
  return j;
}
#endif

// The 3 x 3 median of the inner nodes of a line from column 1 on as far as
// the vector path goes (see above); returns the first column left to the caller.
int MedianRow(const float* up, const float* mid, const float* dn, int n, float* o) {
#ifdef SM_DENSE_HAVE_AVX2_PATH
  static const bool avx2 = __builtin_cpu_supports("avx2");
  if (avx2) return MedianRowAvx2(up, mid, dn, n, o);
#endif
  return MedianRowScalar(up, mid, dn, n, o);
}

// 3 x 3 median of the valid nodes around each valid node (invalid nodes stay
// invalid; an even count takes the mean of the two middle values). Rows in
// parallel; inner nodes branch-free (MedianRow), the rest by sorting.
void MedianFilter(const cv::Mat& in, cv::Mat* grid) {
  grid->create(in.size(), CV_32F);
  const int rows = in.rows, cols = in.cols;
  cv::parallel_for_(cv::Range(0, rows), [&](const cv::Range& range) {
    float v[9];
    for (int i = range.start; i < range.end; ++i) {
      const float* up = in.ptr<float>(std::max(i - 1, 0));
      const float* mid = in.ptr<float>(i);
      const float* dn = in.ptr<float>(std::min(i + 1, rows - 1));
      float* o = grid->ptr<float>(i);
      const bool inner_row = i > 0 && i < rows - 1;
      const int done = (inner_row && cols >= 3) ? MedianRow(up, mid, dn, cols, o) : 1;
      for (int j = 0; j < cols; ++j) {
        if (j >= 1 && j < done) continue;  // MedianRow's value
        if (!Finite(mid[j])) {
          o[j] = mid[j];
          continue;
        }
        int n = 0;
        for (int di = -1; di <= 1; ++di) {
          const int a = i + di;
          if (a < 0 || a >= rows) continue;
          const float* row = in.ptr<float>(a);
          for (int dj = -1; dj <= 1; ++dj) {
            const int b = j + dj;
            if (b < 0 || b >= cols) continue;
            if (Finite(row[b])) v[n++] = row[b];
          }
        }
        for (int a = 1; a < n; ++a)  // insertion sort: at most nine values
          for (int b = a; b > 0 && v[b] < v[b - 1]; --b) std::swap(v[b], v[b - 1]);
        o[j] = (n % 2 == 1) ? v[n / 2] : 0.5f * (v[n / 2 - 1] + v[n / 2]);
      }
    }
  });
}

// Along each line the matched position x - d must not decrease. Returns the
// number of nodes invalidated.
// sign = -1 for the right-to-left grid (matched position x + d).
int OrderCheck(cv::Mat* grid, int g, double tolerance, float sign) {
  std::atomic<int> rejected_total{0};
  cv::parallel_for_(cv::Range(0, grid->rows), [&](const cv::Range& range) {
    int rejected = 0;
    std::vector<int> kill;
    for (int i = range.start; i < range.end; ++i) {
      float* row = grid->ptr<float>(i);
      kill.clear();
      int prev = -1;
      for (int j = 0; j < grid->cols; ++j) {
        if (!Finite(row[j])) continue;
        if (prev >= 0) {
          const double xp = prev * g - sign * row[prev], xc = j * g - sign * row[j];
          if (xc < xp - tolerance) {
            kill.push_back(prev);
            kill.push_back(j);
          }
        }
        prev = j;
      }
      for (int j : kill)
        if (Finite(row[j])) {
          row[j] = kNaN;
          ++rejected;
        }
    }
    rejected_total += rejected;
  });
  return rejected_total;
}

// Linear look-up of a grid line at fractional node position u.
float LookupLine(const float* row, int cols, double u) {
  if (u < 0 || u > cols - 1) return kNaN;
  const int j0 = std::min(static_cast<int>(u), cols - 1);
  const int j1 = std::min(j0 + 1, cols - 1);
  const float a = row[j0], b = row[j1];
  const double t = u - j0;
  if (Finite(a) && Finite(b)) return static_cast<float>((1 - t) * a + t * b);
  if (Finite(a) && t < 0.5) return a;
  if (Finite(b) && t >= 0.5) return b;
  return kNaN;
}

// Holes interpolated along lines, then along columns, then a constant: used
// only to predict the next level.
cv::Mat FillForPrediction(const cv::Mat& grid, float fallback, cv::Mat* store) {
  grid.copyTo(*store);
  cv::Mat out = *store;
  auto fill_line = [](std::vector<float>& v) {
    int last = -1;
    const int n = static_cast<int>(v.size());
    for (int j = 0; j < n; ++j) {
      if (!Finite(v[j])) continue;
      if (last < 0) {
        for (int k = 0; k < j; ++k) v[k] = v[j];
      } else {
        for (int k = last + 1; k < j; ++k)
          v[k] = v[last] + (v[j] - v[last]) * (k - last) / float(j - last);
      }
      last = j;
    }
    if (last >= 0)
      for (int k = last + 1; k < n; ++k) v[k] = v[last];
    return last >= 0;
  };
  std::vector<char> row_ok(out.rows, 0);
  std::vector<float> line;
  for (int i = 0; i < out.rows; ++i) {
    line.assign(out.ptr<float>(i), out.ptr<float>(i) + out.cols);
    row_ok[i] = fill_line(line);
    if (row_ok[i]) std::copy(line.begin(), line.end(), out.ptr<float>(i));
  }
  for (int j = 0; j < out.cols; ++j) {
    line.resize(out.rows);
    for (int i = 0; i < out.rows; ++i) line[i] = row_ok[i] ? out.at<float>(i, j) : kNaN;
    if (!fill_line(line)) std::fill(line.begin(), line.end(), fallback);
    for (int i = 0; i < out.rows; ++i) out.at<float>(i, j) = line[i];
  }
  return out;
}

// Per-pixel integer base parallax of a level (size) from a filled grid of the
// previous level (spacing g in previous-level px): bilinear, times 2.
void PredictBase(const cv::Mat& filled_grid, int g, cv::Size size, cv::Mat* base_out) {
  base_out->create(size, CV_32S);
  cv::Mat& base = *base_out;
  // Column positions and weights once per level.
  std::vector<int> j0s(size.width), j1s(size.width);
  std::vector<float> tjs(size.width);
  for (int x = 0; x < size.width; ++x) {
    const double gj = std::clamp(0.5 * x / g, 0.0, filled_grid.cols - 1.0);
    j0s[x] = std::min(static_cast<int>(gj), filled_grid.cols - 1);
    j1s[x] = std::min(j0s[x] + 1, filled_grid.cols - 1);
    tjs[x] = static_cast<float>(gj - j0s[x]);
  }
  cv::parallel_for_(cv::Range(0, size.height), [&](const cv::Range& range) {
    for (int y = range.start; y < range.end; ++y) {
      const double gi = std::clamp(0.5 * y / g, 0.0, filled_grid.rows - 1.0);
      const int i0 = std::min(static_cast<int>(gi), filled_grid.rows - 1),
                i1 = std::min(i0 + 1, filled_grid.rows - 1);
      const float ti = static_cast<float>(gi - i0);
      const float* r0 = filled_grid.ptr<float>(i0);
      const float* r1 = filled_grid.ptr<float>(i1);
      int* b = base.ptr<int>(y);
      for (int x = 0; x < size.width; ++x) {
        const float tj = tjs[x];
        const float v = (1 - ti) * ((1 - tj) * r0[j0s[x]] + tj * r0[j1s[x]]) +
                        ti * ((1 - tj) * r1[j0s[x]] + tj * r1[j1s[x]]);
        b[x] = static_cast<int>(std::floor(2.0f * v + 0.5f));
      }
    }
  });
}

// A CV_32F matrix of `size` from one of two kept buffers that nobody else
// references (reference count 1: only the cache), else a new one kept in the
// place of a buffer still referenced by the caller.
cv::Mat OutputBuffer(cv::Mat (&buffers)[2], cv::Size size) {
  for (cv::Mat& b : buffers)
    if (!b.empty() && b.u && b.u->refcount == 1 && b.size() == size) return b;
  cv::Mat& slot =
      (!buffers[0].empty() && buffers[0].u && buffers[0].u->refcount > 1) ? buffers[1] : buffers[0];
  slot = cv::Mat(size, CV_32F);
  return slot;
}

// Pixels whose window (window x window) straddles a depth edge of the
// prediction: the predicted parallaxes in it span more than `step` level px.
void EdgeMask(const cv::Mat& base, int window, double step, cv::Mat* b16, cv::Mat* hi, cv::Mat* lo,
              cv::Mat* mask) {
  base.convertTo(*b16, CV_16S);
  const cv::Mat k = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(window, window));
  cv::dilate(*b16, *hi, k, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::erode(*b16, *lo, k, cv::Point(-1, -1), 1, cv::BORDER_REPLICATE);
  cv::subtract(*hi, *lo, *hi);
  cv::compare(*hi, step, *mask, cv::CMP_GT);
}

// Least-squares refinement of the parallax d of left pixel (x, y): minimises
// sum over the window of (l(q) - a - b r(q - d))^2 by Gauss-Newton in (d, a,
// b), r sampled linearly along the line. Returns NaN when a window sample
// leaves the image, the system is singular, or d moves by more than 1 px.
float RefineLsc(const cv::Mat& l, const cv::Mat& r, int x, int y, float d0, int half,
                int iterations) {
  const int w = l.cols, h = l.rows;
  if (x - half < 0 || x + half >= w || y - half < 0 || y + half >= h) return kNaN;
  double d = d0, a = 0.0, b = 1.0;
  for (int it = 0; it < iterations; ++it) {
    double n[3][3] = {{0}}, u[3] = {0};
    for (int yy = y - half; yy <= y + half; ++yy) {
      const float* lr = l.ptr<float>(yy);
      const float* rr = r.ptr<float>(yy);
      for (int xx = x - half; xx <= x + half; ++xx) {
        const double xs = xx - d;
        const int x0 = static_cast<int>(std::floor(xs));
        if (x0 < 0 || x0 + 1 >= w) return kNaN;
        const double t = xs - x0;
        const double rv = (1 - t) * rr[x0] + t * rr[x0 + 1];
        const double gx = rr[x0 + 1] - rr[x0];  // d r / d xs
        const double res = lr[xx] - (a + b * rv);
        // Derivatives of the model a + b r(xx - d) by (d, a, b).
        const double j[3] = {-b * gx, 1.0, rv};
        for (int p = 0; p < 3; ++p) {
          u[p] += j[p] * res;
          for (int q = 0; q < 3; ++q) n[p][q] += j[p] * j[q];
        }
      }
    }
    Eigen::Matrix3d nm;
    for (int p = 0; p < 3; ++p)
      for (int q = 0; q < 3; ++q) nm(p, q) = n[p][q];
    const Eigen::Vector3d dx = nm.ldlt().solve(Eigen::Vector3d(u[0], u[1], u[2]));
    if (!dx.allFinite()) return kNaN;
    d += dx[0];
    a += dx[1];
    b += dx[2];
    if (std::abs(d - d0) > 1.0 || !(b > 0.0)) return kNaN;
    if (std::abs(dx[0]) < 1e-3) break;
  }
  return static_cast<float>(d);
}

// The scale-normalised LoG of matching::LaplacianOfGaussian (same kernels,
// separable: g'' x g + g x g''), written into `out` (kept between calls).
void LogInto(const cv::Mat& image, double sigma, cv::Mat* out, cv::Mat* tmp) {
  static thread_local double cached_sigma = -1.0;
  static thread_local cv::Mat g, g2;
  if (sigma != cached_sigma) {
    g = cv::Mat(matching::GaussianKernel(sigma), true);
    g2 = cv::Mat(matching::GaussianSecondDerivativeKernel(sigma), true);
    cached_sigma = sigma;
  }
  cv::sepFilter2D(image, *out, CV_32F, g2, g, cv::Point(-1, -1), 0.0, cv::BORDER_REFLECT_101);
  cv::sepFilter2D(image, *tmp, CV_32F, g, g2, cv::Point(-1, -1), 0.0, cv::BORDER_REFLECT_101);
  const double s = -(sigma * sigma);
  cv::addWeighted(*out, s, *tmp, s, 0.0, *out);
}

cv::Mat MaskOrOnes(const cv::Mat& m, cv::Size size, const char* what, cv::Mat* ones) {
  if (m.empty()) {
    ones->create(size, CV_8U);
    ones->setTo(1);
    return *ones;
  }
  if (m.size() != size || m.type() != CV_8U)
    throw InvalidArgument(Message("MatchRectified: ", what, " must be CV_8U of the image size"));
  cv::Mat out;
  cv::compare(m, 0, out, cv::CMP_GT);
  return out / 255;
}

cv::Mat Downsample(const cv::Mat& image, int scale, cv::Mat* out) {
  if (scale == 1) return image;
  cv::resize(image, *out, cv::Size(image.cols / scale, image.rows / scale), 0, 0, cv::INTER_AREA);
  return *out;
}

// `all_valid`: the full-resolution mask is all ones (no mask given).
cv::Mat DownsampleMask(const cv::Mat& mask, int scale, bool all_valid, cv::Mat* out) {
  if (scale == 1) return mask;
  const cv::Size size(mask.cols / scale, mask.rows / scale);
  if (all_valid) {
    out->create(size, CV_8U);
    out->setTo(1);
    return *out;
  }
  // A level pixel has content only when all full-resolution pixels under it have.
  cv::Mat f, small;
  mask.convertTo(f, CV_32F);
  cv::resize(f, small, size, 0, 0, cv::INTER_AREA);
  cv::Mat m;
  cv::compare(small, 0.999, m, cv::CMP_GE);
  *out = m / 255;
  return *out;
}

}  // namespace

void CorrelationOptions::Check() const {
  RequireOption("dense correlation", levels >= 1 && levels <= 5, "levels",
                Message("= ", levels, " must be in [1, 5]"));
  RequireOption("dense correlation", peak_frequency > 0 && peak_frequency <= 3, "peak_frequency",
                Message("= ", peak_frequency, " rad/px must be in (0, 3]"));
  RequireOption("dense correlation", grid_spacing >= 1 && grid_spacing <= 64, "grid_spacing",
                Message("= ", grid_spacing, " must be in [1, 64]"));
  RequireOption("dense correlation", final_grid_spacing >= 1 && final_grid_spacing <= 64,
                "final_grid_spacing", Message("= ", final_grid_spacing, " must be in [1, 64]"));
  RequireOption("dense correlation", window >= 3 && window <= 51 && window % 2 == 1, "window",
                Message("= ", window, " must be odd in [3, 51]"));
  RequireOption(
      "dense correlation",
      final_window == 0 || (final_window >= 3 && final_window <= 51 && final_window % 2 == 1),
      "final_window", Message("= ", final_window, " must be 0 (= window) or odd in [3, 51]"));
  RequireOption("dense correlation", search_radius >= 1 && search_radius <= 16, "search_radius",
                Message("= ", search_radius, " must be in [1, 16]"));
  RequireOption(
      "dense correlation",
      std::isfinite(min_disparity) && std::isfinite(max_disparity) && max_disparity > min_disparity,
      "max_disparity",
      Message("= ", max_disparity, " must be finite and > min_disparity = ", min_disparity));
  RequireOption("dense correlation", min_correlation >= -1 && min_correlation < 1,
                "min_correlation", Message("= ", min_correlation, " must be in [-1, 1)"));
  RequireOption("dense correlation", lsc_iterations >= 0 && lsc_iterations <= 20, "lsc_iterations",
                Message("= ", lsc_iterations, " must be in [0, 20]"));
  RequireOption("dense correlation",
                edge_window == 0 || (edge_window >= 3 && edge_window <= 51 && edge_window % 2 == 1),
                "edge_window", Message("= ", edge_window, " must be 0 (off) or odd in [3, 51]"));
  RequireOption("dense correlation", edge_parallax_step > 0, "edge_parallax_step",
                Message("= ", edge_parallax_step, " must be > 0"));
  RequireOption("dense correlation", final_search_radius >= 0 && final_search_radius <= 16,
                "final_search_radius",
                Message("= ", final_search_radius, " must be 0 (= search_radius) or in [1, 16]"));
  RequireOption("dense correlation", lr_tolerance > 0, "lr_tolerance",
                Message("= ", lr_tolerance, " must be > 0"));
  RequireOption("dense correlation", order_tolerance >= 0, "order_tolerance",
                Message("= ", order_tolerance, " must be >= 0"));
}

std::string CorrelationSummary::BriefReport() const {
  std::ostringstream s;
  s << "dense correlation: " << levels << " levels, " << valid_nodes << "/" << nodes
    << " nodes valid (" << 100.0 * ValidFraction() << "%), rejected: correlation "
    << rejected_correlation << ", order " << rejected_order << ", left/right "
    << rejected_left_right << ", " << seconds << " s";
  return s.str();
}

namespace {

// Throws InvalidArgument naming the image without texture (constant value).
void RequireRectifiedTexture(const cv::Mat& left, const cv::Mat& right) {
  for (const cv::Mat* im : {&left, &right}) {
    cv::Scalar mean, sd;
    cv::meanStdDev(*im, mean, sd);
    if (!(sd[0] > 1e-3))
      throw InvalidArgument(Message("MatchRectified: the ", im == &left ? "left" : "right",
                                    " image has no texture (constant value ", mean[0],
                                    ", e.g. all black)"));
  }
}

// Left/right agreement on a level's grids: a left node whose parallax the
// right grid confirms at the matched position (within tol) takes the mean
// of both, the others are rejected (NaN). *averaged may share grid_l's
// data (in place). Returns the rejections.
int AgreeLeftRight(const cv::Mat& grid_l, const cv::Mat& grid_r, int g, float tol,
                   cv::Mat* averaged_io) {
  cv::Mat& averaged = *averaged_io;
  std::atomic<int> rejected{0};
  cv::parallel_for_(cv::Range(0, grid_l.rows), [&](const cv::Range& range) {
    int rej = 0;
    for (int i = range.start; i < range.end; ++i) {
      const float* rr = grid_r.ptr<float>(i);
      const float* ll = grid_l.ptr<float>(i);
      float* av = averaged.ptr<float>(i);
      for (int j = 0; j < grid_l.cols; ++j) {
        const float dl = ll[j];
        if (!Finite(dl)) continue;
        const float drv = LookupLine(rr, grid_r.cols, (static_cast<double>(j) * g - dl) / g);
        if (Finite(drv) && std::abs(drv - dl) <= tol) {
          av[j] = 0.5f * (dl + drv);
        } else {
          av[j] = kNaN;
          ++rej;
        }
      }
    }
    rejected += rej;
  });
  return rejected;
}

// The final level's outputs: its averaged parallaxes (refined by LSC when
// lsc_iterations > 0) and correlations, NaN where no parallax is left. They
// go to one of two buffers kept between calls that the caller no longer
// holds (no fresh memory: page faults were a seventh of the time in this
// VM); a buffer still referenced is never reused.
void FinalLevelOutputs(const cv::Mat& averaged, const cv::Mat& corr_l, const cv::Mat& l,
                       const cv::Mat& r, int g, int window, int lsc_iterations, LevelWorkspace* lw,
                       cv::Mat* final_grid_out, cv::Mat* final_corr_out) {
  cv::Mat& final_grid = *final_grid_out;
  cv::Mat& final_corr = *final_corr_out;
  final_grid = OutputBuffer(lw->out_disp, averaged.size());
  final_corr = OutputBuffer(lw->out_corr, corr_l.size());
  averaged.copyTo(final_grid);
  corr_l.copyTo(final_corr);
  if (lsc_iterations > 0) {
    const int half = window / 2;
    cv::parallel_for_(cv::Range(0, final_grid.rows), [&](const cv::Range& rows) {
      for (int i = rows.start; i < rows.end; ++i) {
        float* row = final_grid.ptr<float>(i);
        for (int j = 0; j < final_grid.cols; ++j) {
          if (!Finite(row[j])) continue;
          const float refined = RefineLsc(l, r, j * g, i * g, row[j], half, lsc_iterations);
          if (Finite(refined)) row[j] = refined;
        }
      }
    });
  }
  for (int i = 0; i < final_grid.rows; ++i) {
    const float* fg = final_grid.ptr<float>(i);
    float* fc = final_corr.ptr<float>(i);
    for (int j = 0; j < final_grid.cols; ++j)
      if (!Finite(fg[j])) fc[j] = kNaN;
  }
}

}  // namespace

ParallaxGrid MatchRectified(const cv::Mat& left_in, const cv::Mat& right_in,
                            const CorrelationOptions& options, CorrelationSummary* summary,
                            const cv::Mat& valid_left, const cv::Mat& valid_right) {
  const auto t0 = std::chrono::steady_clock::now();
  options.Check();
  if (left_in.empty() || right_in.empty()) throw InvalidArgument("MatchRectified: empty image");
  if (left_in.size() != right_in.size())
    throw InvalidArgument(Message("MatchRectified: image sizes differ (", left_in.cols, "x",
                                  left_in.rows, " vs ", right_in.cols, "x", right_in.rows, ")"));
  // Float copies in memory kept between calls (8-bit input is the usual case).
  LevelWorkspace& input = LevelCache(kInputSlot);
  auto to_float = [](const cv::Mat& in, const char* what, cv::Mat* out) -> cv::Mat {
    if (in.depth() == CV_32F || in.channels() != 1) return matching::ToFloat(in, what);
    in.convertTo(*out, CV_32F);
    return *out;
  };
  const cv::Mat left = to_float(left_in, "left image", &input.down_l);
  const cv::Mat right = to_float(right_in, "right image", &input.down_r);
  const int coarse = 1 << (options.levels - 1);
  if (left.cols / coarse < options.window || left.rows / coarse < options.window)
    throw InvalidArgument(Message("MatchRectified: image ", left.cols, "x", left.rows,
                                  " too small for ", options.levels, " levels and a ",
                                  options.window, " px window"));
  RequireRectifiedTexture(left, right);
  const cv::Mat mask_l = MaskOrOnes(valid_left, left.size(), "valid_left", &input.mask_l);
  const cv::Mat mask_r = MaskOrOnes(valid_right, right.size(), "valid_right", &input.mask_r);

  CorrelationSummary sum;
  sum.levels = options.levels;
  cv::Mat pred_left, pred_right;  // filled grids of the previous level
  int prev_g = 0;
  cv::Mat final_grid, final_corr;
  const int half = options.window / 2;
  (void)half;
  for (int k = 0; k < options.levels; ++k) {
    const int scale = 1 << (options.levels - 1 - k);
    const bool last = (k == options.levels - 1);
    const int g = last ? options.final_grid_spacing : options.grid_spacing;
    const int window = (last && options.final_window > 0) ? options.final_window : options.window;
    const double sigma = matching::LogSigmaForPeakFrequency(options.peak_frequency);
    LevelWorkspace& lw = LevelCache(k);
    // Both images at once (two tasks; OpenCV's separable filter runs on one thread).
    cv::parallel_for_(cv::Range(0, 2), [&](const cv::Range& sides) {
      for (int side = sides.start; side < sides.end; ++side) {
        if (side == 0)
          LogInto(Downsample(left, scale, &lw.down_l), sigma, &lw.log_l, &lw.log_tmp);
        else
          LogInto(Downsample(right, scale, &lw.down_r), sigma, &lw.log_r, &lw.log_tmp_r);
      }
    });
    const cv::Mat& l = lw.log_l;
    const cv::Mat& r = lw.log_r;
    const cv::Mat ml = DownsampleMask(mask_l, scale, valid_left.empty(), &lw.mask_l);
    const cv::Mat mr = DownsampleMask(mask_r, scale, valid_right.empty(), &lw.mask_r);

    int k_min, k_max;
    cv::Mat base_l, base_r;
    if (pred_left.empty()) {
      k_min = static_cast<int>(std::floor(options.min_disparity / scale)) - 1;
      k_max = static_cast<int>(std::ceil(options.max_disparity / scale)) + 1;
    } else {
      const int radius = (last && options.final_search_radius > 0) ? options.final_search_radius
                                                                   : options.search_radius;
      k_min = -radius - 1;
      k_max = radius + 1;
      PredictBase(pred_left, prev_g, l.size(), &lw.base_l);
      base_l = lw.base_l;
      if (options.full_right_search) {
        PredictBase(pred_right, prev_g, l.size(), &lw.base_r);
        base_r = lw.base_r;
      }
    }
    // The extra +-1 lets the parabola use both neighbours of a maximum at the
    // edge of the nominal range; a maximum on the extended edge is rejected.
    DenseResult& res_l = lw.res_l;
    cv::Mat edge_l, edge_r;
    if (!base_l.empty() && options.edge_window > 0) {
      EdgeMask(base_l, window, options.edge_parallax_step, &lw.e16, &lw.ehi, &lw.elo, &lw.edge_l);
      edge_l = lw.edge_l;
      if (!base_r.empty()) {
        EdgeMask(base_r, window, options.edge_parallax_step, &lw.e16, &lw.ehi, &lw.elo, &lw.edge_r);
        edge_r = lw.edge_r;
      }
    }
    const bool volume_right = options.two_way && !options.full_right_search;
    Search(l, r, base_l, k_min, k_max, window, options.min_correlation, ml, mr, +1, edge_l,
           options.edge_window, lw.ws_l, res_l, volume_right ? &lw.res_r : nullptr);
    cv::Mat grid_l = SampleGrid(res_l.disparity, g);
    cv::Mat corr_l = SampleGrid(res_l.correlation, g);
    const int nodes = grid_l.rows * grid_l.cols;
    const int found = CountFinite(grid_l);
    cv::Mat grid_r;
    if (options.two_way) {
      // Right-to-left: a right pixel x matches the left x + d.
      DenseResult& res_r = lw.res_r;
      if (options.full_right_search)
        Search(r, l, base_r, k_min, k_max, window, options.min_correlation, mr, ml, -1, edge_r,
               options.edge_window, lw.ws_r, res_r);
      grid_r = SampleGrid(res_r.disparity, g);
    }
    if (options.median_filter) {
      MedianFilter(grid_l, &lw.median_l);
      grid_l = lw.median_l;
      if (!grid_r.empty()) {
        MedianFilter(grid_r, &lw.median_r);
        grid_r = lw.median_r;
      }
    }
    int rejected_order = 0;
    if (options.order_check) {
      rejected_order += OrderCheck(&grid_l, g, options.order_tolerance, 1.0f);
      // For the right grid the matched left position x + d must not decrease.
      if (!grid_r.empty()) rejected_order += OrderCheck(&grid_r, g, options.order_tolerance, -1.0f);
    }
    int rejected_lr = 0;
    cv::Mat averaged = grid_l;  // in place
    if (!grid_r.empty())
      rejected_lr =
          AgreeLeftRight(grid_l, grid_r, g, static_cast<float>(options.lr_tolerance), &averaged);
    if (last) {
      sum.nodes = nodes;
      sum.rejected_correlation = nodes - found;
      sum.rejected_order = rejected_order;
      sum.rejected_left_right = rejected_lr;
      sum.valid_nodes = CountFinite(averaged);
      FinalLevelOutputs(averaged, corr_l, l, r, g, window, options.lsc_iterations, &lw, &final_grid,
                        &final_corr);
    } else {
      const float fallback =
          static_cast<float>(0.5 * (options.min_disparity + options.max_disparity) / scale);
      pred_left = FillForPrediction(averaged, fallback, &lw.pred_l);
      if (options.full_right_search)
        pred_right = grid_r.empty() ? pred_left : FillForPrediction(grid_r, fallback, &lw.pred_r);
      prev_g = g;
      // The next level's nodes are spaced g of ITS pixels; prediction uses
      // this level's grid (spacing g here = 2 g there).
    }
  }
  ParallaxGrid out;
  out.spacing = options.final_grid_spacing;
  out.disparity = final_grid;
  out.correlation = final_corr;
  if (static_cast<double>(left.total()) > kMaxCachedPixels) LevelCacheVector().clear();
  sum.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (summary) *summary = sum;
  return out;
}

cv::Mat FillFromBackground(const cv::Mat& disparity, int max_gap, cv::Mat* filled) {
  if (disparity.type() != CV_32F)
    throw InvalidArgument("FillFromBackground: the parallax map must be CV_32F");
  cv::Mat out = disparity.clone();
  FillFromBackgroundInPlace(&out, max_gap, filled);
  return out;
}

void FillFromBackgroundInPlace(cv::Mat* disparity, int max_gap, cv::Mat* filled) {
  if (disparity->type() != CV_32F)
    throw InvalidArgument("FillFromBackground: the parallax map must be CV_32F");
  cv::Mat& out = *disparity;
  if (filled) *filled = cv::Mat::zeros(out.size(), CV_8U);
  for (int y = 0; y < out.rows; ++y) {
    float* d = out.ptr<float>(y);
    const int w = out.cols;
    for (int x = 0; x < w;) {
      if (Finite(d[x])) {
        ++x;
        continue;
      }
      int e = x;
      while (e < w && !Finite(d[e])) ++e;  // hole [x, e)
      const float a = x > 0 ? d[x - 1] : kNaN, b = e < w ? d[e] : kNaN;
      float v = kNaN;
      if (Finite(a) && Finite(b))
        v = std::min(a, b);
      else if (Finite(a))
        v = a;
      else if (Finite(b))
        v = b;
      if (Finite(v) && e - x <= max_gap) {
        for (int i = x; i < e; ++i) d[i] = v;
        if (filled) std::fill(filled->ptr<uchar>(y) + x, filled->ptr<uchar>(y) + e, 255);
      }
      x = e;
    }
  }
}

}  // namespace dense
}  // namespace slope_monitor
