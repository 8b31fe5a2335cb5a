#include "slope_monitor/core/radio/phase_extraction.h"

#include <cmath>
#include <complex>
#include <limits>

#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace radio {

void PhaseExtractionOptions::Check() const {
  if (!(min_snr > 0.0)) throw ConfigError(Message("min_snr = ", min_snr, " must be > 0"));
  if (!(max_saturated_fraction >= 0.0 && max_saturated_fraction <= 1.0))
    throw ConfigError(
        Message("max_saturated_fraction = ", max_saturated_fraction, " must be in [0, 1]"));
  if (!(sample_rate_tolerance >= 0.0)) throw ConfigError("sample_rate_tolerance must be >= 0");
}

PhaseExtractor::PhaseExtractor(std::vector<Tone> tones, double center_frequency, double sample_rate,
                               PhaseExtractionOptions options)
    : tones_(std::move(tones)),
      center_frequency_(center_frequency),
      sample_rate_(sample_rate),
      options_(options) {
  options_.Check();
  if (!(sample_rate_ > 0.0))
    throw ConfigError(Message("sample_rate = ", sample_rate_, " must be > 0 Hz"));
  for (const Tone& t : tones_)
    if (!(std::abs(t.frequency - center_frequency_) < 0.5 * sample_rate_))
      throw ConfigError(Message("transmitter '", t.transmitter_id, "' frequency ", std::fixed,
                                t.frequency, " Hz is outside the receiver band ", center_frequency_,
                                " +- ", 0.5 * sample_rate_, " Hz"));
}

const PhaseExtractor::GramCache& PhaseExtractor::Gram(int n) const {
  auto it = gram_.find(n);
  if (it != gram_.end()) return it->second;
  const int k = static_cast<int>(tones_.size()) + (options_.fit_dc ? 1 : 0);
  std::vector<double> w(k, 0.0);
  for (std::size_t i = 0; i < tones_.size(); ++i)
    w[i] = 2.0 * M_PI * (tones_[i].frequency - center_frequency_) / sample_rate_;
  // G_ab = sum_n exp(j (w_b - w_a) n): geometric sum in closed form.
  Eigen::MatrixXcd g(k, k);
  for (int a = 0; a < k; ++a)
    for (int b = 0; b < k; ++b) {
      const double d = w[b] - w[a];
      if (std::abs(std::remainder(d, 2.0 * M_PI)) < 1e-12) {
        g(a, b) = static_cast<double>(n);
      } else {
        const std::complex<double> num = 1.0 - std::polar(1.0, d * n);
        const std::complex<double> den = 1.0 - std::polar(1.0, d);
        g(a, b) = num / den;
      }
    }
  // Condition check: tones closer than ~1/4 bin make the fit ill-posed.
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXcd> es(g);
  if (es.eigenvalues().minCoeff() < 0.05 * n)
    throw InvalidArgument(Message("tone frequencies too close for blocks of ", n,
                                  " samples (frequency resolution ", sample_rate_ / n,
                                  " Hz): joint fit ill-conditioned"));
  GramCache c;
  c.g_inverse = g.inverse();
  return gram_.emplace(n, c).first->second;
}

std::vector<PhaseObservation> PhaseExtractor::Extract(const SampleBlock& block) const {
  const std::string& rx = block.receiver_id;
  if (std::abs(block.sample_rate - sample_rate_) > options_.sample_rate_tolerance * sample_rate_)
    throw InvalidArgument(Message("receiver '", rx, "': sample_rate ", block.sample_rate,
                                  " Hz, the network expects ", sample_rate_, " Hz"));
  if (std::abs(block.center_frequency - center_frequency_) > 1e-3)
    throw InvalidArgument(Message("receiver '", rx, "': center_frequency ", std::fixed,
                                  block.center_frequency, " Hz, the network expects ",
                                  center_frequency_, " Hz"));
  if (block.q.empty())
    throw InvalidArgument(Message("receiver '", rx, "': real sampling (empty q) is not supported"));
  if (block.q.size() != block.i.size())
    throw InvalidArgument(
        Message("receiver '", rx, "': i has ", block.i.size(), " samples but q ", block.q.size()));
  const int n = static_cast<int>(block.i.size());
  const int k = static_cast<int>(tones_.size()) + (options_.fit_dc ? 1 : 0);
  if (n < 4 * k + 16)
    throw InvalidArgument(Message("receiver '", rx, "': block of ", n, " samples is too short"));
  int saturated = 0;
  const double clip = block.full_scale * (1.0 - 1e-6);
  for (int s = 0; s < n; ++s) {
    if (!std::isfinite(block.i[s]) || !std::isfinite(block.q[s]))
      throw InvalidArgument(Message("receiver '", rx, "' block ", block.sequence, ": sample ", s,
                                    " is not finite (", block.i[s], ", ", block.q[s], ")"));
    if (block.full_scale > 0.0 && (std::abs(block.i[s]) >= clip || std::abs(block.q[s]) >= clip))
      ++saturated;
  }
  std::vector<PhaseObservation> out(tones_.size());
  for (std::size_t t = 0; t < tones_.size(); ++t) {
    out[t].receiver_id = rx;
    out[t].transmitter_id = tones_[t].transmitter_id;
    out[t].frequency = tones_[t].frequency;
  }
  if (saturated > options_.max_saturated_fraction * n) {
    for (auto& o : out) {
      o.valid = false;
      o.problem = Message("receiver '", rx, "' block ", block.sequence, ": ", saturated, " of ", n,
                          " samples at full scale ", block.full_scale, " (saturated)");
    }
    return out;
  }
  const GramCache& gram = Gram(n);

  // Projections b_a = sum_n s_n exp(-j w_a n) by phasor rotation, re-anchored
  // every 512 samples against rounding drift.
  std::vector<std::complex<double>> s(n);
  for (int m = 0; m < n; ++m) s[m] = {block.i[m], block.q[m]};
  Eigen::VectorXcd b(k);
  std::vector<double> w(k, 0.0);
  for (std::size_t t = 0; t < tones_.size(); ++t)
    w[t] = 2.0 * M_PI * (tones_[t].frequency - center_frequency_) / sample_rate_;
  for (int a = 0; a < k; ++a) {
    std::complex<double> acc(0.0, 0.0);
    const std::complex<double> step = std::polar(1.0, -w[a]);
    std::complex<double> rot(1.0, 0.0);
    for (int m = 0; m < n; ++m) {
      if ((m & 511) == 0) rot = std::polar(1.0, -w[a] * m);
      acc += s[m] * rot;
      rot *= step;
    }
    b(a) = acc;
  }
  const Eigen::VectorXcd c = gram.g_inverse * b;
  // Residual energy = sum |s|^2 - b^H c (projection identity).
  double energy = 0.0;
  for (int m = 0; m < n; ++m) energy += std::norm(s[m]);
  const double residual = std::max(0.0, energy - std::real(b.dot(c)));
  const double sigma2 = residual / (2.0 * (n - k));  // per I/Q component
  for (std::size_t t = 0; t < tones_.size(); ++t) {
    PhaseObservation& o = out[t];
    const double amp = std::abs(c(t));
    o.amplitude = amp;
    o.phase = WrapPhase(std::arg(c(t)));
    const double var_c = sigma2 * std::real(gram.g_inverse(t, t));  // per component of c_t
    o.snr = var_c > 0.0 ? amp * amp / (2.0 * var_c) : std::numeric_limits<double>::infinity();
    o.phase_variance = std::isfinite(o.snr) ? 1.0 / (2.0 * o.snr) : 0.0;
    o.valid = o.snr >= options_.min_snr;
    if (!o.valid)
      o.problem = Message("receiver '", rx, "' transmitter '", o.transmitter_id, "': SNR ", o.snr,
                          " below ", options_.min_snr, " (blocked path or transmitter off)");
  }
  return out;
}

}  // namespace radio
}  // namespace slope_monitor
