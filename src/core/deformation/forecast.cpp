#include "slope_monitor/core/deformation/forecast.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace deformation {

void ForecastOptions::Check() const {
  if (!(window > 0.0)) throw ConfigError(Message("forecast window = ", window, " s must be > 0"));
  if (!(alpha > 1.0 && alpha <= 10.0))
    throw ConfigError(Message("forecast alpha = ", alpha, " must be in (1, 10]"));
  if (min_samples < 3)
    throw ConfigError(Message("forecast min_samples = ", min_samples, " must be >= 3"));
  if (!(min_velocity >= 0.0))
    throw ConfigError(Message("forecast min_velocity = ", min_velocity, " m/s must be >= 0"));
  if (!(significance >= 0.0))
    throw ConfigError(Message("forecast significance = ", significance, " must be >= 0"));
  if (!(max_horizon > 0.0))
    throw ConfigError(Message("forecast max_horizon = ", max_horizon, " s must be > 0"));
}

namespace {

// The samples of the last `window` seconds up to the latest stamp (*t_last),
// oldest first (samples_in is not empty).
template <typename Sample>
std::vector<Sample> SamplesInWindow(const std::vector<Sample>& samples_in, double window,
                                    double* t_last) {
  std::vector<Sample> samples = samples_in;
  std::sort(samples.begin(), samples.end(),
            [](const Sample& a, const Sample& b) { return a.stamp < b.stamp; });
  *t_last = samples.back().stamp;
  std::vector<Sample> in_window;
  for (const Sample& s : samples)
    if (!(s.stamp < *t_last - window)) in_window.push_back(s);
  return in_window;
}

// A forecast not made yet: alpha from the options, and the reason when
// there are no `kind` samples at all.
template <typename Sample>
Forecast NewForecast(const std::vector<Sample>& samples, const char* kind,
                     const ForecastOptions& options) {
  Forecast f;
  f.alpha = options.alpha;
  if (samples.empty()) f.reason = Message("no ", kind, " samples");
  return f;
}

// The forecast's window from the first usable sample (t relative to t_last)
// to the last stamp.
void SetWindow(const std::vector<double>& t, double t_last, Forecast* f) {
  f->window_start = t.front() + t_last;
  f->window_end = t_last;
  f->window = f->window_end - f->window_start;
}

}  // namespace

Forecast ForecastFailure(const std::vector<VelocitySample>& samples_in,
                         const ForecastOptions& options) {
  Forecast f = NewForecast(samples_in, "velocity", options);
  if (samples_in.empty()) return f;
  double t_last = 0.0;
  std::vector<double> t, y;
  for (const VelocitySample& s : SamplesInWindow(samples_in, options.window, &t_last)) {
    if (!(s.velocity > 0.0) || s.velocity < options.min_velocity || !std::isfinite(s.velocity))
      continue;
    t.push_back(s.stamp - t_last);
    y.push_back(std::pow(s.velocity, 1.0 - options.alpha));
  }
  f.num_samples = static_cast<int>(t.size());
  if (f.num_samples < options.min_samples) {
    f.reason = Message("only ", f.num_samples, " usable velocity samples in the window (need ",
                       options.min_samples, ")");
    return f;
  }
  SetWindow(t, t_last, &f);
  const int n = f.num_samples;
  Eigen::MatrixXd A(n, 2);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) {
    A(i, 0) = 1.0;
    A(i, 1) = t[i];
    b(i) = y[i];
  }
  const Eigen::Matrix2d N = A.transpose() * A;
  const Eigen::Vector2d c = N.ldlt().solve(A.transpose() * b);
  const Eigen::VectorXd res = b - A * c;
  const double s2 = res.squaredNorm() / std::max(1, n - 2);
  const Eigen::Matrix2d C = s2 * N.inverse();
  f.slope = c(1);
  f.slope_sigma = std::sqrt(std::max(0.0, C(1, 1)));
  if (!(c(1) + options.significance * f.slope_sigma < 0.0)) {
    f.reason = Message("not accelerating significantly (slope of v^(1-alpha) = ", c(1), " +- ",
                       f.slope_sigma, ")");
    return f;
  }
  const double tf_rel = -c(0) / c(1);
  const Eigen::RowVector2d J(-1.0 / c(1), c(0) / (c(1) * c(1)));
  f.failure_time = t_last + tf_rel;
  f.sigma = std::sqrt(std::max(0.0, (J * C * J.transpose())(0, 0)));
  if (tf_rel > options.max_horizon) {
    f.reason = Message("failure time ", tf_rel / 86400.0, " days ahead is beyond the horizon");
    return f;
  }
  f.valid = true;
  f.reason = "ok";
  return f;
}

namespace {

struct Fit {
  double chi2 = 1e300;
  double C = 0.0, D = 0.0;
};

// Basis g(t) with y = D + C g(t) for a given tf (see forecast.h).
double Basis(double tf_minus_t, double alpha) {
  if (std::abs(alpha - 2.0) < 1e-12) return -std::log(tf_minus_t);
  const double b = (alpha - 2.0) / (alpha - 1.0);
  return -std::pow(tf_minus_t, b) / b;
}

// Weighted linear fit of y = D + C g; t relative to the last sample.
Fit LinearFit(const std::vector<double>& g, const std::vector<double>& y,
              const std::vector<double>& w) {
  double sw = 0, sg = 0, sy = 0, sgg = 0, sgy = 0;
  for (size_t i = 0; i < g.size(); ++i) {
    sw += w[i];
    sg += w[i] * g[i];
    sy += w[i] * y[i];
    sgg += w[i] * g[i] * g[i];
    sgy += w[i] * g[i] * y[i];
  }
  Fit f;
  const double det = sw * sgg - sg * sg;
  if (!(std::abs(det) > 0)) return f;
  f.C = (sw * sgy - sg * sy) / det;
  f.D = (sy - f.C * sg) / sw;
  f.chi2 = 0;
  for (size_t i = 0; i < g.size(); ++i) {
    const double r = y[i] - f.D - f.C * g[i];
    f.chi2 += w[i] * r * r;
  }
  return f;
}

}  // namespace

Forecast ForecastFromDisplacements(const std::vector<DisplacementSample>& samples_in,
                                   const ForecastOptions& options) {
  Forecast f = NewForecast(samples_in, "displacement", options);
  if (samples_in.empty()) return f;
  double t_last = 0.0;
  std::vector<double> t, y, w;
  for (const DisplacementSample& s : SamplesInWindow(samples_in, options.window, &t_last)) {
    if (!(s.sigma > 0.0) || !std::isfinite(s.displacement)) continue;
    t.push_back(s.stamp - t_last);
    y.push_back(s.displacement);
    w.push_back(1.0 / (s.sigma * s.sigma));
  }
  const int n = static_cast<int>(t.size());
  f.num_samples = n;
  if (n < std::max(options.min_samples, 4)) {
    f.reason = Message("only ", n, " usable displacement samples in the window (need ",
                       std::max(options.min_samples, 4), ")");
    return f;
  }
  SetWindow(t, t_last, &f);
  const Fit line = LinearFit(t, y, w);
  std::vector<double> g(n);
  auto fit_at = [&](double log_h) {  // h = tf - t_last
    const double h = std::exp(log_h);
    for (int i = 0; i < n; ++i) g[i] = Basis(h - t[i], options.alpha);
    return LinearFit(g, y, w);
  };
  // Grid over log(h) from 1 minute to the horizon, then golden section.
  const double lo = std::log(60.0), hi = std::log(options.max_horizon);
  const int kGrid = 120;
  int best = 0;
  double best_chi2 = 1e300;
  for (int k = 0; k <= kGrid; ++k) {
    const Fit fk = fit_at(lo + (hi - lo) * k / kGrid);
    if (fk.C > 0 && fk.chi2 < best_chi2) {
      best_chi2 = fk.chi2;
      best = k;
    }
  }
  if (best_chi2 >= 1e300) {
    f.reason =
        "no accelerating solution (the displacement does not grow along the direction of motion)";
    return f;
  }
  if (best == kGrid) {
    f.reason = "not accelerating significantly (best failure time at the horizon)";
    return f;
  }
  double a = lo + (hi - lo) * std::max(0, best - 1) / kGrid,
         b = lo + (hi - lo) * std::min(kGrid, best + 1) / kGrid;
  const double gr = 0.5 * (std::sqrt(5.0) - 1.0);
  double c = b - gr * (b - a), d = a + gr * (b - a);
  double fc = fit_at(c).chi2, fd = fit_at(d).chi2;
  for (int it = 0; it < 80; ++it) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - gr * (b - a);
      fc = fit_at(c).chi2;
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + gr * (b - a);
      fd = fit_at(d).chi2;
    }
  }
  const double log_h = 0.5 * (a + b);
  const Fit best_fit = fit_at(log_h);
  const double h = std::exp(log_h);
  // Covariance of (h, C, D): Jacobian of the model D + C g(h - t_i).
  Eigen::Matrix3d JtWJ = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) {
    const double u = h - t[i];
    // d g / d h: alpha = 2: -1/u; else -u^(b-1) with b as in Basis.
    const double dg = std::abs(options.alpha - 2.0) < 1e-12
                          ? -1.0 / u
                          : -std::pow(u, (options.alpha - 2.0) / (options.alpha - 1.0) - 1.0);
    const Eigen::Vector3d J(best_fit.C * dg, Basis(u, options.alpha), 1.0);
    JtWJ += w[i] * J * J.transpose();
  }
  const double reduced = best_fit.chi2 / std::max(1, n - 3);
  const Eigen::Matrix3d cov = JtWJ.inverse() * std::max(1.0, reduced);
  f.failure_time = t_last + h;
  f.sigma = std::sqrt(std::max(0.0, cov(0, 0)));
  // tf is far from linear near the failure: take the wider of the linearised
  // sigma and the profile-likelihood 1-sigma interval (chi2 rises by the
  // reduced chi-square), on each side of the best tf.
  const double target = best_fit.chi2 + std::max(1.0, reduced);
  for (int side : {-1, 1}) {
    double inner = log_h, outer = log_h;
    bool bracketed = false;
    for (int k = 1; k <= 60 && !bracketed; ++k) {
      outer = log_h + side * 0.05 * k;
      if (outer < lo - 3.0 || outer > hi) break;
      const Fit fk = fit_at(outer);
      if (fk.chi2 >= target || fk.C <= 0)
        bracketed = true;
      else
        inner = outer;
    }
    if (!bracketed) {
      f.sigma = std::max(f.sigma, side > 0 ? options.max_horizon - h : h);
      continue;
    }
    for (int it = 0; it < 40; ++it) {
      const double mid = 0.5 * (inner + outer);
      const Fit fm = fit_at(mid);
      if (fm.chi2 >= target || fm.C <= 0)
        outer = mid;
      else
        inner = mid;
    }
    f.sigma = std::max(f.sigma, std::abs(std::exp(0.5 * (inner + outer)) - h));
  }
  f.slope = -1.0 / best_fit.C;  // d(1/v)/dt for alpha = 2
  f.slope_sigma = std::sqrt(std::max(0.0, cov(1, 1))) / (best_fit.C * best_fit.C);
  const double improvement = (line.chi2 - best_fit.chi2) / std::max(1.0, reduced);
  if (!(improvement >= options.significance * options.significance) || !std::isfinite(f.sigma)) {
    f.reason = Message("not accelerating significantly (chi2 gain over constant velocity ",
                       improvement, ")");
    return f;
  }
  f.valid = true;
  f.reason = "ok";
  return f;
}

}  // namespace deformation
}  // namespace slope_monitor
