// Plain data types of the radio phase system, shared by the simulator
// (core/sim/radio_sim.h), the phase extraction and the solver
// (core/radio/*.h). No ROS here: src/ros converts them to and from
// slope_monitor/RadioSampleBlock and RadioPhaseObservation.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace slope_monitor {
namespace radio {

// Speed of light [m/s].
constexpr double kSpeedOfLight = 299792458.0;

// One block of raw ADC samples from one receiver channel after down-conversion
// to baseband; mirrors msg/RadioSampleBlock.msg field by field.
//
// A transmitter at absolute frequency f appears in the samples as a complex
// tone at f - center_frequency [Hz]. Complex (I/Q) sampling: i and q have the
// same length; real sampling: q is empty (not produced by the simulator; the
// phase extraction accepts it and analyses the real signal).
struct SampleBlock {
  std::string receiver_id;        // "rx1"
  std::string frame_id;           // receiver antenna frame (header.frame_id)
  double stamp = 0.0;             // [s] time of the first sample (header.stamp)
  std::uint32_t sequence = 0;     // block counter of this receiver; gaps mean dropped blocks
  double sample_rate = 0.0;       // [Hz] complex (I/Q) or real sample rate
  double center_frequency = 0.0;  // [Hz] local-oscillator frequency that maps to 0 Hz
  double full_scale = 1.0;        // ADC full-scale amplitude of i and q (saturation level)
  std::vector<float> i;           // in-phase samples [ADC units]
  std::vector<float> q;           // quadrature samples [ADC units]; empty for real sampling

  std::size_t size() const { return i.size(); }
  double Duration() const {
    return sample_rate > 0.0 ? static_cast<double>(i.size()) / sample_rate : 0.0;
  }
};

// Phase of one transmitter's carrier at one receiver read from one block
// (mirrors msg/RadioPhaseObservation.msg).
struct PhaseObservation {
  std::string receiver_id;
  std::string transmitter_id;
  double frequency = 0.0;       // [Hz] absolute transmitter frequency
  double phase = 0.0;           // [rad] in (-pi, pi], at the block's start time
  double phase_variance = 0.0;  // [rad^2] from the SNR
  double amplitude = 0.0;       // [ADC units]
  double snr = 0.0;    // [-] linear power ratio of the tone to the noise in its bin (after the DFT)
  bool valid = false;  // false: the tone was not usable (low SNR, saturated block, ...)
  std::string problem;  // why it is not valid (empty when valid)
};

// Wraps an angle to (-pi, pi].
double WrapPhase(double a);

}  // namespace radio
}  // namespace slope_monitor
