// Phase, amplitude and SNR of each transmitter's tone in one baseband sample
// block, at the known frequencies.
//
// Method: joint least-squares fit of all tones (plus a DC term for the
// receiver's LO leakage) to the complex samples,
//   s_n = c_dc + sum_i c_i exp(j w_i n) + noise,   w_i = 2 pi (f_i - f_LO) / fs,
// i.e. a DFT at each known frequency (b_i = sum_n s_n exp(-j w_i n)) followed
// by solving G c = b with the Gram matrix G_ab = sum_n exp(j (w_b - w_a) n).
// For tones on the DFT bin grid G = N I and this *is* the plain DFT; for any
// other frequency plan the fit removes the leakage of every tone into the
// others exactly (no window needed, no loss of SNR for well separated tones).
// The noise variance per I/Q component is estimated from the fit residual,
//   sigma^2 = sum |r_n|^2 / (2 (N - K)),  K = number of complex unknowns,
// the tone's post-fit SNR is |c_i|^2 / (2 sigma^2 (G^-1)_ii) and the phase
// variance 1 / (2 SNR) [rad^2] (= sigma^2 / (N A^2) for the plain DFT).
//
// The reported phase is arg(c_i): the tone's phase at the block's first
// sample, wrapped to (-pi, pi].
#pragma once

#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/radio/types.h"

namespace slope_monitor {
namespace radio {

struct PhaseExtractionOptions {
  double min_snr = 100.0;  // [-] tones below it are invalid (phase sigma 0.07 rad); > 0
  double max_saturated_fraction =
      1e-3;  // [-] share of samples at full scale above which the block is rejected; [0, 1]
  double sample_rate_tolerance =
      1e-6;            // [-] relative difference to the configured rate that is accepted
  bool fit_dc = true;  // also fit a DC term (LO leakage)
  void Check() const;  // throws ConfigError naming the field
};

struct Tone {
  std::string transmitter_id;
  double frequency = 0.0;  // [Hz] absolute carrier frequency
};

class PhaseExtractor {
 public:
  // center_frequency [Hz] and sample_rate [Hz] are what the network expects;
  // a block that disagrees is rejected. Throws ConfigError for tones outside
  // the band or closer than 1/4 of a DFT bin of the block size
  // (ill-conditioned fit; checked in Extract when the size is known).
  PhaseExtractor(std::vector<Tone> tones, double center_frequency, double sample_rate,
                 PhaseExtractionOptions options = {});

  // One observation per tone, in the order of the tones. Throws
  // InvalidArgument naming the receiver and the problem for: NaN / inf
  // samples, wrong sample rate or center frequency, i/q of different lengths,
  // real sampling (q empty), fewer samples than 4 per unknown, tones too
  // close for this block size. A saturated block does not throw: every
  // observation is returned invalid with the reason (the caller reports it).
  std::vector<PhaseObservation> Extract(const SampleBlock& block) const;

  const std::vector<Tone>& tones() const { return tones_; }

 private:
  struct GramCache {
    Eigen::MatrixXcd g_inverse;
  };
  const GramCache& Gram(int n) const;

  std::vector<Tone> tones_;
  double center_frequency_;
  double sample_rate_;
  PhaseExtractionOptions options_;
  mutable std::map<int, GramCache> gram_;
};

}  // namespace radio
}  // namespace slope_monitor
