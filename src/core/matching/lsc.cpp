#include "slope_monitor/core/matching/lsc.h"

#include <cmath>
#include <vector>

#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace matching {

namespace {

void CheckImage(const cv::Mat& image, const char* what) {
  if (image.empty() || image.type() != CV_32FC1) {
    throw InvalidArgument(Message("LSC: ", what,
                                  " must be a non-empty CV_32FC1 image (use ToFloat), got type ",
                                  image.type()));
  }
}

double Ncc(const std::vector<double>& a, const std::vector<double>& b) {
  const size_t n = a.size();
  double ma = 0, mb = 0;
  for (size_t i = 0; i < n; ++i) {
    ma += a[i];
    mb += b[i];
  }
  ma /= n;
  mb /= n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < n; ++i) {
    const double da = a[i] - ma, db = b[i] - mb;
    sab += da * db;
    saa += da * da;
    sbb += db * db;
  }
  if (saa <= 0 || sbb <= 0) return 0.0;
  return sab / std::sqrt(saa * sbb);
}

// Value and derivatives of b at (x, y). Bilinear derivatives are taken as
// half-pixel central differences of the interpolant (continuous in x, y),
// bicubic ones analytically.
inline float ValueGrad(const cv::Mat& b, double x, double y, Interpolation interp, float* dx,
                       float* dy) {
  if (interp == Interpolation::kBicubic) return SampleBicubicGrad(b, x, y, dx, dy);
  const float v = SampleBilinear(b, x, y);
  *dx = SampleBilinear(b, x + 0.5, y) - SampleBilinear(b, x - 0.5, y);
  *dy = SampleBilinear(b, x, y + 0.5) - SampleBilinear(b, x, y - 0.5);
  return v;
}

using Mat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, 8, 8>;
using Vec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, 8, 1>;

// Gradient energy of window a (central differences inside the window) and
// the ratio of its structure tensor's eigenvalues: false when the window is
// textureless for the options' limits.
bool LscWindowHasTexture(const std::vector<double>& wa, int h, const LscOptions& options) {
  double e = 0, sxx = 0, syy = 0, sxy = 0;
  int m = 0;
  const int w = 2 * h + 1;
  for (int v = 1; v < w - 1; ++v)
    for (int u = 1; u < w - 1; ++u) {
      const double gx = 0.5 * (wa[v * w + u + 1] - wa[v * w + u - 1]);
      const double gy = 0.5 * (wa[(v + 1) * w + u] - wa[(v - 1) * w + u]);
      e += gx * gx + gy * gy;
      sxx += gx * gx;
      syy += gy * gy;
      sxy += gx * gy;
      ++m;
    }
  if (h == 1) {  // 3x3: one interior pixel only
    m = std::max(m, 1);
  }
  const double tr = 0.5 * (sxx + syy), df = 0.5 * (sxx - syy);
  const double root = std::sqrt(df * df + sxy * sxy);
  const double ratio = tr + root > 0 ? (tr - root) / (tr + root) : 0.0;
  return !(e / m < options.min_gradient_energy || e == 0.0 || ratio < options.min_eigen_ratio);
}

// The template gradient: central differences of window a, read one pixel
// beyond it. The Jacobian is built from it, mapped into b by the affine part
// (g grad B(X) = M^-T grad A(u, v) with M = dX/d(u, v)), not from the
// gradient of the resampled b: b's interpolated noise and its interpolated
// derivative are correlated wherever the noise variance of the interpolant
// changes with the sub-pixel position, and that correlation biases the
// solution (pixel locking). Central differences of a exclude the centre
// pixel, so the Jacobian is uncorrelated with the residual's noise. False
// when the patch leaves image a.
bool LscTemplateGradient(const cv::Mat& image_a, const Eigen::Vector2d& xa, int h, double margin,
                         Interpolation interp, const std::vector<double>& us,
                         const std::vector<double>& vs, std::vector<double>* ga_u,
                         std::vector<double>* ga_v) {
  const int n = static_cast<int>(us.size());
  const int hp = h + 1;  // half size of the patch read from a
  const double mg = margin + 1.0;
  if (xa.x() - h < mg || xa.y() - h < mg || xa.x() + h > image_a.cols - 1 - mg ||
      xa.y() + h > image_a.rows - 1 - mg) {
    return false;
  }
  const int w = 2 * hp + 1;
  std::vector<double> patch(static_cast<size_t>(w) * w);
  for (int v = -hp, k = 0; v <= hp; ++v)
    for (int u = -hp; u <= hp; ++u, ++k) patch[k] = Sample(image_a, xa.x() + u, xa.y() + v, interp);
  auto at = [&](int u, int v) { return patch[(v + hp) * w + (u + hp)]; };
  for (int k = 0; k < n; ++k) {
    const int u = static_cast<int>(us[k]), v = static_cast<int>(vs[k]);
    (*ga_u)[k] = 0.5 * (at(u + 1, v) - at(u - 1, v));
    (*ga_v)[k] = 0.5 * (at(u, v + 1) - at(u, v - 1));
  }
  return true;
}

// The Gauss-Newton solve of window a at xb in image b: eq. 2 (shift,
// offset, gain) to convergence first, then, for the affine model, all
// parameters from there. Starting the four affine parameters together with
// a shift that is still up to a pixel off lets Gauss-Newton trade shift for
// scale along an edge and settle in a wrong minimum (measured: errors up to
// 1 px at 8 sigma on the warped Cones texture, doc/nodes/hex_matcher.md).
struct LscSolve {
  LscSolve(const cv::Mat& image_b_in, const LscOptions& options_in, int h_in,
           Interpolation interp_in, double margin_in, const std::vector<double>& wa_in,
           const std::vector<double>& us_in, const std::vector<double>& vs_in,
           const std::vector<double>& ga_u_in, const std::vector<double>& ga_v_in,
           const Eigen::Vector2d& start)
      : image_b(image_b_in),
        options(options_in),
        h(h_in),
        n(static_cast<int>(wa_in.size())),
        interp(interp_in),
        margin(margin_in),
        wa(wa_in),
        us(us_in),
        vs(vs_in),
        ga_u(ga_u_in),
        ga_v(ga_v_in),
        affine_model(options_in.model == LscModel::kAffine),
        gain(options_in.estimate_gain),
        xb(start),
        wb(n) {
    SetStage(false);
  }

  void SetStage(bool with_affine) {
    affine = with_affine;
    m = 2 + (affine ? 4 : 0) + (gain ? 1 : 0) + 1;
    ig = affine ? 6 : 2;
    io = ig + (gain ? 1 : 0);
    jtj.resize(m, m);
    jtr.resize(m);
  }
  bool Inside(double X, double Y) const {
    return X >= margin && Y >= margin && X <= image_b.cols - 1 - margin &&
           Y <= image_b.rows - 1 - margin;
  }
  void Map(int k, double* X, double* Y) const {
    *X = xb.x() + (1 + p_aff[0]) * us[k] + p_aff[1] * vs[k];
    *Y = xb.y() + p_aff[2] * us[k] + (1 + p_aff[3]) * vs[k];
  }
  // Offset start: difference of means. False when window b leaves image b.
  bool StartOffset() {
    double mb = 0, ma = 0;
    for (int k = 0; k < n; ++k) {
      double X, Y;
      Map(k, &X, &Y);
      if (!Inside(X, Y)) return false;
      mb += Sample(image_b, X, Y, interp);
      ma += wa[k];
    }
    o = (ma - mb) / n;
    return true;
  }
  // Normal equations J^T J, J^T r and sum r^2 at the current parameters, one
  // routine for both models (eq. 1 adds the four affine columns). False if
  // the window leaves image b.
  bool Assemble() {
    // Accumulated in plain arrays (the lower triangle, mirrored at the end):
    // the same products summed in the same order as jtj += row row^T, without
    // the dynamic-size expression per pixel.
    double a[8][8] = {}, t[8] = {};
    double row[8];
    sum_r2 = 0;
    // M^-T for the template gradient.
    const double m11 = 1 + p_aff[0], m12 = p_aff[1], m21 = p_aff[2], m22 = 1 + p_aff[3];
    const double det = m11 * m22 - m12 * m21;
    // Shift stage (no affine part yet): window b is a shifted grid, sampled
    // with one set of weights.
    const bool shifted_grid = options.gradient == LscGradient::kTemplate && p_aff[0] == 0.0 &&
                              p_aff[1] == 0.0 && p_aff[2] == 0.0 && p_aff[3] == 0.0;
    if (shifted_grid) {
      if (!Inside(xb.x() - h, xb.y() - h) || !Inside(xb.x() + h, xb.y() + h)) return false;
      SampleWindow(image_b, xb.x(), xb.y(), h, interp, wb.data());
    }
    for (int k = 0; k < n; ++k) {
      double gx, gy, b;
      if (shifted_grid) {
        b = wb[k];
        gx = ga_u[k];
        gy = ga_v[k];
      } else if (options.gradient == LscGradient::kTemplate) {
        double X, Y;
        Map(k, &X, &Y);
        if (!Inside(X, Y)) return false;
        b = Sample(image_b, X, Y, interp);
        gx = (m22 * ga_u[k] - m21 * ga_v[k]) / det;
        gy = (-m12 * ga_u[k] + m11 * ga_v[k]) / det;
      } else {
        double X, Y;
        Map(k, &X, &Y);
        if (!Inside(X, Y)) return false;
        float bx, by;
        b = ValueGrad(image_b, X, Y, interp, &bx, &by);
        gx = g * bx;
        gy = g * by;
      }
      wb[k] = b;
      const double r = g * b + o - wa[k];
      sum_r2 += r * r;
      row[0] = gx;
      row[1] = gy;
      if (affine) {
        row[2] = gx * us[k];
        row[3] = gx * vs[k];
        row[4] = gy * us[k];
        row[5] = gy * vs[k];
      }
      if (gain) row[ig] = b;
      row[io] = 1.0;
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j <= i; ++j) a[i][j] += row[i] * row[j];
        t[i] += row[i] * r;
      }
    }
    for (int i = 0; i < m; ++i) {
      for (int j = 0; j <= i; ++j) jtj(i, j) = jtj(j, i) = a[i][j];
      jtr(i) = t[i];
    }
    return true;
  }
  // The iterations; false (s's status set) when the solve stops early.
  bool Iterate(LscSummary* summary) {
    using Status = LscSummary::Status;
    LscSummary& s = *summary;
    for (; it < options.max_iterations; ++it) {
      if (!Assemble()) {
        s.status = Status::kOutside;
        s.iterations = it;
        return false;
      }
      // Conditioning on the column-scaled normal matrix.
      const Vec d = jtj.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
      const Mat scaled = d.asDiagonal() * jtj * d.asDiagonal();
      // Symmetric positive semi-definite: its singular values are its
      // eigenvalues (the eigenvalue solver is several times cheaper than SVD).
      const Eigen::SelfAdjointEigenSolver<Mat> eig(scaled, Eigen::EigenvaluesOnly);
      if (eig.eigenvalues()(0) < 1e-8) {
        s.status = Status::kTextureless;
        s.iterations = it;
        return false;
      }
      const Vec step = -jtj.partialPivLu().solve(jtr);
      xb += step.head<2>();
      double max_aff_step = 0;
      if (affine) {
        for (int i = 0; i < 4; ++i) {
          p_aff[i] += step(2 + i);
          max_aff_step = std::max(max_aff_step, std::fabs(step(2 + i)));
        }
      }
      if (gain) g += step(ig);
      o += step(io);
      const bool diverged =
          (xb - s.start).norm() > options.max_shift || !std::isfinite(xb.x()) ||
          !std::isfinite(xb.y()) ||
          (affine &&
           (std::fabs(p_aff[0]) > options.max_affine || std::fabs(p_aff[1]) > options.max_affine ||
            std::fabs(p_aff[2]) > options.max_affine ||
            std::fabs(p_aff[3]) > options.max_affine)) ||
          (gain && (g < 1.0 / options.max_gain_ratio || g > options.max_gain_ratio));
      if (diverged) {
        s.status = Status::kDiverged;
        s.xb = xb;
        s.iterations = it + 1;
        return false;
      }
      if (step.head<2>().norm() < options.convergence_shift &&
          max_aff_step < options.convergence_affine) {
        if (affine_model && !affine) {
          // Eq. 2 converged: keep its solution and residual for the F test,
          // then release the affine parameters.
          xb_shift = xb;
          g_shift = g;
          o_shift = o;
          if (!Assemble()) {
            s.status = Status::kOutside;
            s.iterations = it + 1;
            return false;
          }
          ssr_shift = sum_r2;
          SetStage(true);
          continue;
        }
        converged = true;
        ++it;
        break;
      }
    }
    return true;
  }
  // Eq. 1: the F test (false, s's status set, when window b leaves image b
  // on the way back to eq. 2).
  bool AffineFTest(LscSummary* summary) {
    using Status = LscSummary::Status;
    LscSummary& s = *summary;
    // Eq. 1: F test of the four affine parameters against eq. 2 (residual sum
    // of squares of both fits). Not significant -> the eq. 2 solution, whose
    // shift is better determined (the affine terms would fit the noise).
    if (converged && affine && options.affine_min_f > 0 && ssr_shift >= 0) {
      const double ssr_affine = sum_r2;
      s.affine_f =
          ((ssr_shift - ssr_affine) / 4.0) / std::max(ssr_affine / std::max(1, n - m), 1e-12);
      if (s.affine_f < options.affine_min_f) {
        fallback_cov = (ssr_affine / std::max(1, n - m)) * Mat(jtj.inverse()).topLeftCorner(2, 2);
        fell_back = true;
        xb = xb_shift;
        g = g_shift;
        o = o_shift;
        for (double& a : p_aff) a = 0.0;
        SetStage(false);
        if (!Assemble()) {
          s.status = Status::kOutside;
          s.iterations = it;
          return false;
        }
      }
    }
    return true;
  }

  const cv::Mat& image_b;
  const LscOptions& options;
  const int h, n;
  const Interpolation interp;
  const double margin;
  const std::vector<double>&wa, &us, &vs, &ga_u,
      &ga_v;  // window a, its offsets and template gradient
  const bool affine_model, gain;
  bool affine = false;  // the stage: affine columns active
  int m = 0, ig = 0, io = 0;
  Mat jtj;
  Vec jtr;
  double p_aff[4] = {0, 0, 0, 0};
  double g = 1.0, o = 0.0;
  Eigen::Vector2d xb;
  std::vector<double> wb;
  double sum_r2 = 0;
  Eigen::Vector2d xb_shift;  // eq. 2's solution, its gain, offset and residual sum of squares
  double g_shift = 1.0, o_shift = 0.0, ssr_shift = -1;
  bool converged = false;
  int it = 0;
  Eigen::Matrix2d fallback_cov = Eigen::Matrix2d::Zero();
  bool fell_back = false;
};

}  // namespace

LscModel LscModelFromName(const std::string& name) {
  if (name == "affine") return LscModel::kAffine;
  if (name == "shift") return LscModel::kShift;
  throw InvalidArgument(Message("LSC model '", name, "' unknown (use 'affine' or 'shift')"));
}

const char* LscModelName(LscModel model) { return model == LscModel::kAffine ? "affine" : "shift"; }

LscGradient LscGradientFromName(const std::string& name) {
  if (name == "template") return LscGradient::kTemplate;
  if (name == "resampled") return LscGradient::kResampled;
  throw InvalidArgument(
      Message("LSC gradient '", name, "' unknown (use 'template' or 'resampled')"));
}

const char* LscGradientName(LscGradient gradient) {
  return gradient == LscGradient::kTemplate ? "template" : "resampled";
}

const char* LscStatusName(LscSummary::Status status) {
  switch (status) {
    case LscSummary::Status::kConverged:
      return "converged";
    case LscSummary::Status::kNotConverged:
      return "not_converged";
    case LscSummary::Status::kOutside:
      return "outside";
    case LscSummary::Status::kTextureless:
      return "textureless";
    case LscSummary::Status::kDiverged:
      return "diverged";
    case LscSummary::Status::kLowCorrelation:
      return "low_correlation";
    case LscSummary::Status::kImprecise:
      return "imprecise";
    case LscSummary::Status::kIllConditioned:
      return "ill_conditioned";
  }
  return "unknown";
}

void LscOptions::Check() const {
  auto fail = [](const char* key, auto value, const char* range) {
    throw ConfigError(Message("LSC option '", key, "' = ", value, " out of range ", range));
  };
  if (half_window < 1 || half_window > 50) fail("half_window", half_window, "[1, 50]");
  if (max_iterations < 1 || max_iterations > 1000)
    fail("max_iterations", max_iterations, "[1, 1000]");
  if (!(convergence_shift > 0)) fail("convergence_shift", convergence_shift, "(0, inf)");
  if (!(convergence_affine > 0)) fail("convergence_affine", convergence_affine, "(0, inf)");
  if (!(max_shift > 0)) fail("max_shift", max_shift, "(0, inf)");
  if (!(max_affine > 0)) fail("max_affine", max_affine, "(0, inf)");
  if (!(affine_min_f >= 0)) fail("affine_min_f", affine_min_f, "[0, inf)");
  if (!(max_gain_ratio > 1)) fail("max_gain_ratio", max_gain_ratio, "(1, inf)");
  if (!(min_correlation >= -1 && min_correlation <= 1))
    fail("min_correlation", min_correlation, "[-1, 1]");
  if (!(min_gradient_energy >= 0)) fail("min_gradient_energy", min_gradient_energy, "[0, inf)");
  if (!(max_sigma > 0)) fail("max_sigma", max_sigma, "(0, inf)");
  if (!(min_eigen_ratio >= 0 && min_eigen_ratio < 1))
    fail("min_eigen_ratio", min_eigen_ratio, "[0, 1)");
  if (!(max_shift_affine_correlation > 0 && max_shift_affine_correlation <= 1)) {
    fail("max_shift_affine_correlation", max_shift_affine_correlation, "(0, 1]");
  }
  if (search_radius < 0 || search_radius > 200) fail("search_radius", search_radius, "[0, 200]");
  if (search_radius_y < -1 || search_radius_y > 200)
    fail("search_radius_y", search_radius_y, "[-1, 200]");
  if (search_half_window < 0 || search_half_window > 50)
    fail("search_half_window", search_half_window, "[0, 50]");
}

Eigen::Vector2d CorrelateInteger(const cv::Mat& image_a, const cv::Mat& image_b,
                                 const Eigen::Vector2d& xa, const Eigen::Vector2d& xb_start,
                                 int half_window, int radius, double* ncc, int radius_y) {
  if (radius_y < 0) radius_y = radius;
  CheckImage(image_a, "image a");
  CheckImage(image_b, "image b");
  const int h = half_window;
  const int ax = static_cast<int>(std::lround(xa.x())), ay = static_cast<int>(std::lround(xa.y()));
  const int bx0 = static_cast<int>(std::lround(xb_start.x())),
            by0 = static_cast<int>(std::lround(xb_start.y()));
  double best = -2.0;
  Eigen::Vector2d best_pos = xb_start;
  if (ax - h < 0 || ay - h < 0 || ax + h >= image_a.cols || ay + h >= image_a.rows) {
    if (ncc) *ncc = best;
    return best_pos;
  }
  const int n = (2 * h + 1) * (2 * h + 1);
  std::vector<float> wa;
  wa.reserve(n);
  double sa = 0, saa = 0;
  for (int v = -h; v <= h; ++v) {
    const float* row = image_a.ptr<float>(ay + v);
    for (int u = -h; u <= h; ++u) {
      wa.push_back(row[ax + u]);
      sa += row[ax + u];
    }
  }
  const double ma = sa / n;
  for (float& x : wa) {
    x -= static_cast<float>(ma);
    saa += double(x) * x;
  }
  if (saa <= 0) {
    if (ncc) *ncc = best;
    return best_pos;
  }
  for (int dy = -radius_y; dy <= radius_y; ++dy) {
    const int by = by0 + dy;
    if (by - h < 0 || by + h >= image_b.rows) continue;
    for (int dx = -radius; dx <= radius; ++dx) {
      const int bx = bx0 + dx;
      if (bx - h < 0 || bx + h >= image_b.cols) continue;
      double sb = 0, sbb = 0, sab = 0;
      int k = 0;
      for (int v = -h; v <= h; ++v) {
        const float* row = image_b.ptr<float>(by + v) + bx;
        for (int u = -h; u <= h; ++u, ++k) {
          const double b = row[u];
          sb += b;
          sbb += b * b;
          sab += wa[k] * b;
        }
      }
      const double var_b = sbb - sb * sb / n;
      if (var_b <= 1e-9) continue;
      const double c = sab / std::sqrt(saa * var_b);
      if (c > best) {
        best = c;
        best_pos = Eigen::Vector2d(bx, by);
      }
    }
  }
  if (ncc) *ncc = best;
  return best_pos;
}

LscSummary MatchLsc(const cv::Mat& image_a, const cv::Mat& image_b, const Eigen::Vector2d& xa,
                    const Eigen::Vector2d& xb_start, const LscOptions& options) {
  CheckImage(image_a, "image a");
  CheckImage(image_b, "image b");
  options.Check();
  using Status = LscSummary::Status;
  LscSummary s;
  s.xb = xb_start;
  s.start = xb_start;
  const int h = options.half_window;
  const Interpolation interp = options.interpolation;
  const double margin = interp == Interpolation::kBicubic ? 1.0 : 0.0;
  // Window a (bilinear read; exact at integer positions).
  if (xa.x() - h < margin || xa.y() - h < margin || xa.x() + h > image_a.cols - 1 - margin ||
      xa.y() + h > image_a.rows - 1 - margin) {
    s.status = Status::kOutside;
    return s;
  }
  const int n = (2 * h + 1) * (2 * h + 1);
  std::vector<double> wa(n), us(n), vs(n);
  {
    int k = 0;
    for (int v = -h; v <= h; ++v)
      for (int u = -h; u <= h; ++u, ++k) {
        wa[k] = Sample(image_a, xa.x() + u, xa.y() + v, interp);
        us[k] = u;
        vs[k] = v;
      }
  }
  if (!LscWindowHasTexture(wa, h, options)) {
    s.status = Status::kTextureless;
    return s;
  }

  // Modified LSC: integer correlation first.
  if (options.search_radius > 0) {
    double c = -2;
    const Eigen::Vector2d best =
        CorrelateInteger(image_a, image_b, xa, xb_start,
                         options.search_half_window > 0 ? options.search_half_window : h,
                         options.search_radius, &c, options.search_radius_y);
    if (c <= -2) {
      s.status = Status::kOutside;
      return s;
    }
    // Keep the sub-pixel part of xa (windows are centred on xa, not on its rounding).
    s.start = best + (xa - xa.array().round().matrix());
    s.xb = s.start;
  }

  // Template gradient (LscTemplateGradient).
  std::vector<double> ga_u(n), ga_v(n);
  if (options.gradient == LscGradient::kTemplate &&
      !LscTemplateGradient(image_a, xa, h, margin, interp, us, vs, &ga_u, &ga_v)) {
    s.status = Status::kOutside;
    return s;
  }

  LscSolve st(image_b, options, h, interp, margin, wa, us, vs, ga_u, ga_v, s.start);
  if (!st.StartOffset()) {
    s.status = Status::kOutside;
    return s;
  }
  st.xb_shift = st.xb;
  st.g_shift = st.g;
  st.o_shift = st.o;
  if (!st.Iterate(&s)) return s;
  // Final residuals, precision and correlation at the solution.
  if (!st.Assemble()) {
    s.status = Status::kOutside;
    s.iterations = st.it;
    return s;
  }
  if (!st.AffineFTest(&s)) return s;
  s.affine_used = st.affine;
  if (st.affine && st.ssr_shift >= 0) s.model_difference = (st.xb - st.xb_shift).norm();
  s.iterations = st.it;
  s.xb = st.xb;
  s.affine = Eigen::Vector4d(st.p_aff[0], st.p_aff[1], st.p_aff[2], st.p_aff[3]);
  s.gain = st.g;
  s.offset = st.o;
  const int dof = std::max(1, st.n - st.m);
  const double s0sq = st.sum_r2 / dof;
  s.sigma0 = std::sqrt(s0sq);
  s.correlation = Ncc(st.wa, st.wb);
  const Mat cov = s0sq * st.jtj.inverse();
  s.covariance = cov.topLeftCorner<2, 2>();
  if (st.affine) {
    for (int i = 0; i < 4; ++i) s.affine_sigma(i) = std::sqrt(std::max(0.0, cov(2 + i, 2 + i)));
    for (int i = 0; i < 2; ++i)
      for (int j = 2; j < 6; ++j) {
        const double d = std::sqrt(std::max(1e-300, cov(i, i) * cov(j, j)));
        s.shift_affine_correlation = std::max(s.shift_affine_correlation, std::fabs(cov(i, j)) / d);
      }
  }
  if (!st.converged) {
    s.status = Status::kNotConverged;
    return s;
  }
  if (s.correlation < options.min_correlation) {
    s.status = Status::kLowCorrelation;
    return s;
  }
  // Larger eigenvalue of the symmetric 2 x 2 covariance, closed form. After
  // the F test fell back to eq. 2, optionally checked on eq. 1's covariance
  // (the affine terms were not determined, not shown to be zero).
  const Eigen::Matrix2d& check =
      st.fell_back && options.fallback_affine_precision ? st.fallback_cov : s.covariance;
  const double tr = 0.5 * (check(0, 0) + check(1, 1));
  const double df = 0.5 * (check(0, 0) - check(1, 1));
  const double lmax = tr + std::sqrt(df * df + check(0, 1) * check(0, 1));
  if (!(std::sqrt(std::max(0.0, lmax)) <= options.max_sigma)) {
    s.status = Status::kImprecise;
    return s;
  }
  if (st.affine && s.shift_affine_correlation > options.max_shift_affine_correlation) {
    s.status = Status::kIllConditioned;
    return s;
  }
  s.status = Status::kConverged;
  return s;
}

}  // namespace matching
}  // namespace slope_monitor
