#include "slope_monitor/core/sim/radio_sim.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {

namespace {

// A fault of `kind` on the path tx -> rx (tx empty: every block of rx) from
// `start` for `duration` [s]; no bias, amplitude unchanged.
RadioFault FaultOn(RadioFault::Kind kind, const std::string& tx, const std::string& rx,
                   double start, double duration) {
  RadioFault f;
  f.kind = kind;
  f.transmitter_id = tx;
  f.receiver_id = rx;
  f.start = start;
  f.duration = duration;
  return f;
}

}  // namespace

RadioFault RadioFault::BlockedPath(const std::string& tx, const std::string& rx, double start,
                                   double duration, double attenuation) {
  RadioFault f = FaultOn(Kind::kBlockedPath, tx, rx, start, duration);
  f.attenuation = attenuation;
  return f;
}

RadioFault RadioFault::MultipathJump(const std::string& tx, const std::string& rx, double start,
                                     double duration, double bias, double attenuation) {
  RadioFault f = FaultOn(Kind::kMultipathJump, tx, rx, start, duration);
  f.bias = bias;
  f.attenuation = attenuation;
  return f;
}

RadioFault RadioFault::DroppedBlocks(const std::string& rx, double start, double duration) {
  return FaultOn(Kind::kDroppedBlocks, "", rx, start, duration);
}

bool RadioFault::ActiveAt(double t) const {
  if (t < start) return false;
  if (kind == Kind::kMultipathJump && duration <= 0.0) return true;
  return t < start + duration;
}

std::string RadioFault::Describe() const {
  switch (kind) {
    case Kind::kBlockedPath:
      return Message("blocked ", transmitter_id, "->", receiver_id, " from ", std::fixed, start,
                     " s for ", duration, " s (amplitude x", attenuation, ")");
    case Kind::kMultipathJump:
      return Message("multipath jump ", transmitter_id, "->", receiver_id, " of ", bias,
                     " rad from ", std::fixed, start, " s",
                     duration > 0 ? Message(" for ", duration, " s") : std::string(" on"));
    case Kind::kDroppedBlocks:
      return Message("dropped blocks of ", receiver_id, " from ", std::fixed, start, " s for ",
                     duration, " s");
  }
  return "";
}

void RadioSimConfig::Check() const {
  auto bad = [](const std::string& what) { throw InvalidArgument("radio sim config: " + what); };
  if (!(wavelength > 0.0)) bad(Message("wavelength = ", wavelength, " must be > 0 m"));
  if (!(sample_rate > 0.0)) bad(Message("sample_rate = ", sample_rate, " must be > 0 Hz"));
  if (block_size < 16) bad(Message("block_size = ", block_size, " must be >= 16 samples"));
  if (!(noise_sigma >= 0.0)) bad(Message("noise_sigma = ", noise_sigma, " must be >= 0"));
  if (!(full_scale > 0.0)) bad(Message("full_scale = ", full_scale, " must be > 0"));
  if (adc_bits < 0 || adc_bits > 24) bad(Message("adc_bits = ", adc_bits, " must be in [0, 24]"));
  std::set<std::string> rx_ids, tx_ids;
  for (std::size_t j = 0; j < receivers.size(); ++j) {
    if (receivers[j].id.empty()) bad(Message("receivers[", j, "].id is empty"));
    if (!rx_ids.insert(receivers[j].id).second)
      bad(Message("receivers[", j, "].id '", receivers[j].id, "' repeated"));
    if (!receivers[j].position.allFinite())
      bad(Message("receivers[", j, "].position is not finite"));
  }
  const double bin = sample_rate / block_size;
  for (std::size_t i = 0; i < transmitters.size(); ++i) {
    const RadioSimTransmitter& t = transmitters[i];
    if (t.id.empty()) bad(Message("transmitters[", i, "].id is empty"));
    if (!tx_ids.insert(t.id).second) bad(Message("transmitters[", i, "].id '", t.id, "' repeated"));
    if (!(std::abs(t.frequency_offset) < 0.5 * sample_rate))
      bad(Message("transmitters[", i, "].frequency_offset = ", t.frequency_offset,
                  " Hz outside +-sample_rate/2 = ", 0.5 * sample_rate));
    if (!(t.amplitude >= 0.0))
      bad(Message("transmitters[", i, "].amplitude = ", t.amplitude, " must be >= 0"));
    if (!t.position)
      bad(Message("transmitters[", i, "] ('", t.id, "').position function is not set"));
    for (std::size_t k = 0; k < i; ++k)
      if (std::abs(transmitters[k].frequency_offset - t.frequency_offset) < bin)
        bad(Message("transmitters '", transmitters[k].id, "' and '", t.id,
                    "' are closer than one DFT bin (", bin, " Hz)"));
  }
  for (std::size_t f = 0; f < faults.size(); ++f) {
    const RadioFault& fault = faults[f];
    if (!rx_ids.count(fault.receiver_id))
      bad(Message("faults[", f, "].receiver_id '", fault.receiver_id, "' is not a receiver"));
    if (fault.kind != RadioFault::Kind::kDroppedBlocks && !tx_ids.count(fault.transmitter_id))
      bad(Message("faults[", f, "].transmitter_id '", fault.transmitter_id,
                  "' is not a transmitter"));
    if (!(fault.attenuation >= 0.0)) bad(Message("faults[", f, "].attenuation must be >= 0"));
  }
}

RadioSimulator::RadioSimulator(RadioSimConfig config) : config_(std::move(config)) {
  config_.Check();
}

double RadioSimulator::Range(int tx, int rx, double t) const {
  return (config_.transmitters.at(tx).position(t) - config_.receivers.at(rx).position).norm();
}

double RadioSimulator::UnwrappedPhase(int tx, int rx, double t) const {
  return 2.0 * M_PI / config_.wavelength * Range(tx, rx, t) + config_.transmitters[tx].psi +
         config_.receivers[rx].xi;
}

double RadioSimulator::WrappedPhase(int tx, int rx, double t) const {
  return radio::WrapPhase(UnwrappedPhase(tx, rx, t));
}

int RadioSimulator::Ambiguity(int tx, int rx, double t) const {
  const double u = UnwrappedPhase(tx, rx, t);
  return static_cast<int>(std::lround((radio::WrapPhase(u) - u) / (2.0 * M_PI)));
}

double RadioSimulator::FaultBias(int tx, int rx, double t) const {
  double b = 0.0;
  for (const RadioFault& f : config_.faults)
    if (f.kind == RadioFault::Kind::kMultipathJump &&
        f.transmitter_id == config_.transmitters.at(tx).id &&
        f.receiver_id == config_.receivers.at(rx).id && f.ActiveAt(t))
      b += f.bias;
  return b;
}

double RadioSimulator::FaultAttenuation(int tx, int rx, double t) const {
  double a = 1.0;
  for (const RadioFault& f : config_.faults)
    if (f.kind != RadioFault::Kind::kDroppedBlocks &&
        f.transmitter_id == config_.transmitters.at(tx).id &&
        f.receiver_id == config_.receivers.at(rx).id && f.ActiveAt(t))
      a *= f.attenuation;
  return a;
}

bool RadioSimulator::Dropped(int rx, double t) const {
  for (const RadioFault& f : config_.faults)
    if (f.kind == RadioFault::Kind::kDroppedBlocks &&
        f.receiver_id == config_.receivers.at(rx).id && f.ActiveAt(t))
      return true;
  return false;
}

double RadioSimulator::PhaseSigma(int tx) const {
  const double a = config_.transmitters.at(tx).amplitude;
  return a > 0.0 ? config_.noise_sigma / (a * std::sqrt(static_cast<double>(config_.block_size)))
                 : std::numeric_limits<double>::infinity();
}

std::vector<std::string> RadioSimulator::FaultDescriptions() const {
  std::vector<std::string> out;
  for (const RadioFault& f : config_.faults) out.push_back(f.Describe());
  return out;
}

std::optional<radio::SampleBlock> RadioSimulator::Synthesize(int rx, double t_start,
                                                             std::uint32_t sequence) const {
  if (rx < 0 || rx >= NumReceivers())
    throw InvalidArgument(Message("radio sim: receiver index ", rx, " out of range"));
  if (Dropped(rx, t_start)) return std::nullopt;
  const RadioSimReceiver& r = config_.receivers[rx];
  radio::SampleBlock b;
  b.receiver_id = r.id;
  b.frame_id = r.frame_id.empty() ? r.id + "_antenna" : r.frame_id;
  b.stamp = t_start;
  b.sequence = sequence;
  b.sample_rate = config_.sample_rate;
  b.center_frequency = config_.center_frequency;
  b.full_scale = config_.full_scale;
  const int n = config_.block_size;
  std::vector<double> re(n, 0.0), im(n, 0.0);
  for (int tx = 0; tx < NumTransmitters(); ++tx) {
    const RadioSimTransmitter& t = config_.transmitters[tx];
    const double amp = t.amplitude * FaultAttenuation(tx, rx, t_start);
    if (amp <= 0.0) continue;
    const double phase0 = UnwrappedPhase(tx, rx, t_start) + FaultBias(tx, rx, t_start);
    const double w = 2.0 * M_PI * t.frequency_offset / config_.sample_rate;
    for (int k = 0; k < n; ++k) {
      const double ph = phase0 + w * k;
      re[k] += amp * std::cos(ph);
      im[k] += amp * std::sin(ph);
    }
  }
  // Noise from a generator of this block only.
  std::seed_seq seq{config_.seed, static_cast<unsigned int>(rx),
                    static_cast<unsigned int>(sequence), 0x5eedu};
  std::mt19937_64 rng(seq);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double fs = config_.full_scale;
  const double step = config_.adc_bits > 0 ? fs / std::ldexp(1.0, config_.adc_bits - 1) : 0.0;
  auto adc = [&](double v) {
    v = std::clamp(v, -fs, fs);
    if (step > 0.0) v = std::clamp(std::round(v / step) * step, -fs, fs);
    return static_cast<float>(v);
  };
  b.i.resize(n);
  b.q.resize(n);
  for (int k = 0; k < n; ++k) {
    b.i[k] = adc(re[k] + config_.noise_sigma * gauss(rng));
    b.q[k] = adc(im[k] + config_.noise_sigma * gauss(rng));
  }
  return b;
}

std::vector<radio::SampleBlock> RadioSimulator::SynthesizeAll(double t_start,
                                                              std::uint32_t sequence) const {
  std::vector<radio::SampleBlock> out;
  for (int rx = 0; rx < NumReceivers(); ++rx)
    if (auto b = Synthesize(rx, t_start, sequence)) out.push_back(std::move(*b));
  return out;
}

}  // namespace sim
}  // namespace slope_monitor
