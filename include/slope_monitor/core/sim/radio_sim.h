// Synthetic raw radio sample blocks for the "inverse GPS" field sensors
// (doc/design.md, radio phase displacement): transmitters on the moving slope,
// passive receivers on stable ground.
//
//   sim::RadioSimConfig cfg;
//   cfg.receivers = {{"rx1", {0, 0, 5}, 0.3}, ...};
//   cfg.transmitters.push_back({"tx1", 5000.0, 1.1, 200.0,
//       [&](double t) { return x0 + field.DisplacementAt(x0, t); }});
//   cfg.faults.push_back(sim::RadioFault::BlockedPath("tx2", "rx1", t0 + 60, 10));
//   sim::RadioSimulator radio(cfg);                    // throws InvalidArgument
//   for (uint32_t k = 0; ; ++k) {
//     double t = t0 + k * cfg.block_interval;
//     for (const radio::SampleBlock& b : radio.SynthesizeAll(t, k)) publish(b);
//   }
//   int n = radio.Ambiguity(i, j, t0);                 // truth N_ij
//
// ---------------------------------------------------------------------------
// Physical model and its assumptions (what makes it realistic AND solvable)
// ---------------------------------------------------------------------------
// Carrier phase of transmitter i at receiver j (doc/design.md):
//   phi_ij(t) = (2 pi / lambda) |x_i(t) - X_j| + psi_i + xi_j + 2 pi N_ij
// * One wavelength lambda for all transmitters (config `wavelength`): the
//   transmitters' frequency offsets are a few kHz to ~100 kHz on a 2.4 GHz
//   carrier, which changes lambda by < 5e-5 relative (< 0.02 cycles over
//   400 m of range); the model of doc/design.md uses one lambda.
// * Sign convention: the receiver's mixer is arranged (spectral inversion)
//   so that the baseband phase *grows* with range, as in the formula above.
// * Disciplined oscillators: transmitters and receivers are locked to a common
//   time/frequency reference (GNSS-disciplined). Hence psi_i and xi_j are
//   constant over the survey, the frequency offsets are exact, all receivers
//   sample synchronously, and the per-receiver local-oscillator / sample-clock
//   phase is a constant that is part of xi_j. (With free-running transmitter
//   oscillators psi_i(t) would be an unknown per block and a 3-receiver
//   network could not give 3-D displacement; with free-running receiver LOs
//   the same for xi_j(t).) There is no common phase-noise term per block.
// * Block-referenced phase: every block starts on the common clock's grid,
//   and the receiver's timestamped NCO removes 2 pi f_offset t_start, so that
//   at the block's first sample tone i has exactly phase phi_ij(t_start).
//   Within a block the sample n (time t_start + n / sample_rate) is
//     s_n = sum_i A_i exp(j (2 pi df_i n / fs + phi_ij(t_start) + b_ij(t)))
//           + w_n,            w_n complex Gaussian, sigma per I and Q
//   then clipped to +-full_scale per component and, when adc_bits > 0,
//   quantised to full_scale / 2^(adc_bits - 1) steps. b_ij(t) is the
//   multipath fault bias (0 without faults). The transmitter position is taken
//   at t_start for the whole block (the slope moves mm per day; a block lasts
//   tens of ms).
// * Amplitude: A_i per transmitter (ADC units), the same at every receiver,
//   times the fault attenuation of a blocked path.
// * Thermal noise only: the phase noise of a tone read by a rectangular-window
//   DFT over N samples is sigma_phi = noise_sigma / (A sqrt(N)) [rad]
//   (PhaseSigma()); with lambda = 0.125 m, sigma_phi = 0.05 rad is a range
//   noise of lambda sigma_phi / 2 pi = 1.0 mm per link and block.
// * Ambiguity truth: N_ij(t) is the integer that makes
//   wrap(phi_ij) = (2 pi / lambda)|x_i(t) - X_j| + psi_i + xi_j + 2 pi N_ij
//   with wrap to (-pi, pi] (Ambiguity()); only its double differences
//   (between receivers and transmitters) are observable.
//
// Faults (RadioFault):
// * blocked path (tx, rx, start, duration, attenuation): the tone of that
//   transmitter at that receiver is attenuated by `attenuation` (amplitude
//   factor, default 0.02 = -34 dB) during [start, start + duration).
// * multipath jump (tx, rx, start, duration, bias): a phase bias of `bias`
//   rad (and amplitude factor `attenuation`, default 1) is added to that link
//   during [start, start + duration) (duration <= 0: for ever).
// * dropped blocks (rx, start, duration): no block of that receiver starts in
//   [start, start + duration) (Synthesize returns nothing; sequence numbers of
//   later blocks continue, so the gap shows in `sequence`).
//
// Determinism: each block's noise comes from its own generator seeded by
// (seed, receiver index, sequence), so the same config gives bit-identical
// blocks whatever the order of calls.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/radio/types.h"

namespace slope_monitor {
namespace sim {

struct RadioSimReceiver {
  std::string id;                     // "rx1"; also the block's receiver_id
  Eigen::Vector3d position{0, 0, 0};  // [m] antenna phase centre in site (stable)
  double xi = 0.0;                    // [rad] channel delay xi_j
  std::string frame_id;               // header frame of its blocks (empty: "<id>_antenna")
};

struct RadioSimTransmitter {
  std::string id;                 // "tx1"
  double frequency_offset = 0.0;  // [Hz] carrier minus center_frequency; |.| < sample_rate / 2
  double psi = 0.0;               // [rad] phase offset psi_i
  double amplitude = 100.0;       // [ADC units] tone amplitude at every receiver
  // Antenna position in site [m] at time t [s] (bag time); the simulator
  // supplies it from its displacement field. Must be set.
  std::function<Eigen::Vector3d(double t)> position;
};

struct RadioFault {
  enum class Kind { kBlockedPath, kMultipathJump, kDroppedBlocks };
  Kind kind = Kind::kBlockedPath;
  std::string transmitter_id;  // blocked path / multipath jump
  std::string receiver_id;     // all kinds
  double start = 0.0;          // [s] bag time
  double duration = 0.0;       // [s]; multipath jump: <= 0 means until the end
  double bias = 0.0;           // [rad] multipath jump
  double attenuation = 1.0;    // [-] amplitude factor while active

  static RadioFault BlockedPath(const std::string& tx, const std::string& rx, double start,
                                double duration, double attenuation = 0.02);
  static RadioFault MultipathJump(const std::string& tx, const std::string& rx, double start,
                                  double duration, double bias, double attenuation = 1.0);
  static RadioFault DroppedBlocks(const std::string& rx, double start, double duration);
  bool ActiveAt(double t) const;
  std::string Describe() const;  // "blocked tx2->rx1 from 1700000060 s for 10 s (amplitude x0.02)"
};

struct RadioSimConfig {
  double wavelength = 0.125;        // [m] lambda of the phase model
  double center_frequency = 2.4e9;  // [Hz] receivers' LO frequency (0 Hz in the samples)
  double sample_rate = 100e3;       // [Hz] complex (I/Q) sample rate
  int block_size = 4096;            // [samples] per block
  double block_interval = 1.0;  // [s] nominal time between block starts (for callers; not enforced)
  double noise_sigma = 10.0;    // [ADC units] Gaussian noise per I and Q component
  double full_scale = 2048.0;   // [ADC units] saturation level of I and Q
  int adc_bits = 12;            // quantisation bits (0: no quantisation)
  unsigned int seed = 1;
  std::vector<RadioSimReceiver> receivers;
  std::vector<RadioSimTransmitter> transmitters;
  std::vector<RadioFault> faults;

  // Throws InvalidArgument naming the field (empty ids, duplicate ids,
  // offsets outside +-sample_rate/2, two offsets closer than one DFT bin,
  // non-positive rates/sizes, missing position function, faults naming an
  // unknown transmitter or receiver).
  void Check() const;
};

class RadioSimulator {
 public:
  explicit RadioSimulator(RadioSimConfig config);  // calls config.Check()

  const RadioSimConfig& config() const { return config_; }
  int NumReceivers() const { return static_cast<int>(config_.receivers.size()); }
  int NumTransmitters() const { return static_cast<int>(config_.transmitters.size()); }

  // The block of receiver `rx` (index into config.receivers) starting at
  // t_start, or nothing when a dropped-blocks fault covers t_start.
  std::optional<radio::SampleBlock> Synthesize(int rx, double t_start,
                                               std::uint32_t sequence) const;
  // Blocks of all receivers starting at t_start (dropped ones left out).
  std::vector<radio::SampleBlock> SynthesizeAll(double t_start, std::uint32_t sequence) const;

  // Truth, noise- and fault-free, for transmitter index tx and receiver index rx:
  double Range(int tx, int rx, double t) const;             // [m] |x_i(t) - X_j|
  double UnwrappedPhase(int tx, int rx, double t) const;    // [rad] 2pi/lambda range + psi + xi
  double WrappedPhase(int tx, int rx, double t) const;      // [rad] the above wrapped to (-pi, pi]
  int Ambiguity(int tx, int rx, double t) const;            // N_ij(t) (see the model above)
  double FaultBias(int tx, int rx, double t) const;         // [rad] multipath bias active at t
  double FaultAttenuation(int tx, int rx, double t) const;  // [-] product of active attenuations
  bool Dropped(int rx, double t) const;                     // a dropped-blocks fault covers t
  // Expected phase standard deviation of a rectangular-window DFT over one
  // block, noise_sigma / (A sqrt(N)) [rad] (no attenuation, no quantisation).
  double PhaseSigma(int tx) const;
  // Descriptions of all faults (for the truth file).
  std::vector<std::string> FaultDescriptions() const;

 private:
  RadioSimConfig config_;
};

}  // namespace sim
}  // namespace slope_monitor
