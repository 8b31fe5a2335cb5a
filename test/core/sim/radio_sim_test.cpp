// The simulated radio samples reproduce the phase model of doc/design.md,
//   phi_ij = 2 pi / lambda |x_i - X_j| + psi_i + xi_j + 2 pi N_ij,
// when analysed with a plain (rectangular-window) DFT at the known
// frequencies; the faults do what their description says.
#include "slope_monitor/core/sim/radio_sim.h"

#include <cmath>
#include <complex>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace sim {
namespace {

constexpr double kT0 = 1700000000.0;

RadioSimConfig DemoConfig(double noise_sigma, int adc_bits, bool all_bin_centred = false) {
  RadioSimConfig c;
  c.wavelength = 0.125;
  c.sample_rate = 100e3;
  c.block_size = 4096;
  c.noise_sigma = noise_sigma;
  c.adc_bits = adc_bits;
  c.full_scale = 2048.0;
  c.seed = 11;
  c.receivers = {{"rx1", {20.0, -40.0, 5.0}, 0.3, ""},
                 {"rx2", {110.0, -50.0, 2.0}, -1.2, ""},
                 {"rx3", {190.0, -35.0, 8.0}, 2.5, ""}};
  const double bin = c.sample_rate / c.block_size;  // 24.414 Hz
  for (int i = 0; i < 5; ++i) {
    RadioSimTransmitter t;
    t.id = "tx" + std::to_string(i + 1);
    // Bin-centred offsets (a plain DFT has no leakage between them) except tx5.
    t.frequency_offset = (i < 4 || all_bin_centred) ? (100 + 150 * i) * bin : -7013.7;
    t.psi = 0.7 * i - 1.3;
    t.amplitude = 150.0 + 10.0 * i;
    const Eigen::Vector3d x0(60.0 + 20.0 * i, 60.0 + 5.0 * i, 20.0 + 2.0 * i);
    // Moves 1 mm/s south and down (fast, so that a few seconds show it).
    t.position = [x0](double t) {
      return Eigen::Vector3d(x0 + (t - kT0) * Eigen::Vector3d(0.0, -1e-3, -3e-4));
    };
    c.transmitters.push_back(t);
  }
  return c;
}

std::complex<double> Dft(const radio::SampleBlock& b, double f) {
  std::complex<double> s(0.0, 0.0);
  for (std::size_t k = 0; k < b.size(); ++k) {
    const double a = -2.0 * M_PI * f * k / b.sample_rate;
    s += std::complex<double>(b.i[k], b.q[k]) * std::complex<double>(std::cos(a), std::sin(a));
  }
  return s / static_cast<double>(b.size());
}

TEST(RadioSim, NoiseFreeDftPhaseIsTheModel) {
  const RadioSimulator sim(DemoConfig(0.0, 0, true));
  const RadioSimulator off_bin(DemoConfig(0.0, 0));
  for (double dt : {0.0, 3.0, 17.5}) {
    const auto blocks = sim.SynthesizeAll(kT0 + dt, static_cast<std::uint32_t>(dt));
    const auto off_blocks = off_bin.SynthesizeAll(kT0 + dt, static_cast<std::uint32_t>(dt));
    ASSERT_EQ(blocks.size(), 3u);
    for (int j = 0; j < 3; ++j) {
      EXPECT_EQ(blocks[j].receiver_id, sim.config().receivers[j].id);
      EXPECT_DOUBLE_EQ(blocks[j].stamp, kT0 + dt);
      for (int i = 0; i < 5; ++i) {  // bin-centred tones: exact up to float32 samples
        const std::complex<double> x =
            Dft(blocks[j], sim.config().transmitters[i].frequency_offset);
        const double model = 2.0 * M_PI / 0.125 * sim.Range(i, j, kT0 + dt) +
                             sim.config().transmitters[i].psi + sim.config().receivers[j].xi +
                             2.0 * M_PI * sim.Ambiguity(i, j, kT0 + dt);
        EXPECT_NEAR(radio::WrapPhase(std::arg(x) - model), 0.0, 1e-4) << "tx" << i << " rx" << j;
        EXPECT_NEAR(std::abs(x), sim.config().transmitters[i].amplitude, 1e-3);
        // wrapped model = sum with the truth ambiguity, exactly
        EXPECT_NEAR(model, sim.WrappedPhase(i, j, kT0 + dt), 1e-9);
        EXPECT_LE(std::abs(model), M_PI + 1e-12);
      }
      // With one tone off the bin grid a plain DFT leaks a little between
      // tones (rectangular window sidelobes): still within 5 mrad.
      for (int i = 0; i < 5; ++i) {
        const std::complex<double> x =
            Dft(off_blocks[j], off_bin.config().transmitters[i].frequency_offset);
        EXPECT_NEAR(radio::WrapPhase(std::arg(x) - off_bin.WrappedPhase(i, j, kT0 + dt)), 0.0,
                    5e-3);
      }
    }
  }
  // The phase follows the motion: 1 mm/s over 17.5 s changes the range by
  // 17.5 mm * (unit vector . motion) -> check the unwrapped model difference.
  const double dr = sim.Range(0, 0, kT0 + 17.5) - sim.Range(0, 0, kT0);
  EXPECT_GT(std::abs(dr), 1e-3);
  EXPECT_NEAR(sim.UnwrappedPhase(0, 0, kT0 + 17.5) - sim.UnwrappedPhase(0, 0, kT0),
              2.0 * M_PI / 0.125 * dr, 1e-9);
}

TEST(RadioSim, NoisyPhaseScatterMatchesPhaseSigma) {
  const RadioSimulator sim(DemoConfig(30.0, 12));
  const double sigma = sim.PhaseSigma(0);
  EXPECT_NEAR(sigma, 30.0 / (150.0 * 64.0), 1e-12);
  double sum2 = 0.0;
  int n = 0;
  for (std::uint32_t k = 0; k < 200; ++k) {
    const auto b = sim.Synthesize(1, kT0 + k, k);
    ASSERT_TRUE(b.has_value());
    const double e =
        radio::WrapPhase(std::arg(Dft(*b, sim.config().transmitters[0].frequency_offset)) -
                         sim.WrappedPhase(0, 1, kT0 + k));
    sum2 += e * e;
    ++n;
  }
  const double rms = std::sqrt(sum2 / n);
  std::printf("phase noise: predicted %.5f rad, measured %.5f rad over %d blocks\n", sigma, rms, n);
  EXPECT_NEAR(rms, sigma, 0.15 * sigma);
}

TEST(RadioSim, DeterministicPerBlock) {
  const RadioSimulator sim(DemoConfig(30.0, 12));
  const auto a = sim.Synthesize(2, kT0 + 5, 5);
  (void)sim.Synthesize(0, kT0 + 6, 6);
  const auto b = sim.Synthesize(2, kT0 + 5, 5);
  ASSERT_TRUE(a && b);
  EXPECT_EQ(a->i, b->i);
  EXPECT_EQ(a->q, b->q);
  const auto c = sim.Synthesize(2, kT0 + 5, 6);
  EXPECT_NE(a->i, c->i);
}

TEST(RadioSim, FaultsBlockBiasAndDrop) {
  RadioSimConfig cfg = DemoConfig(0.0, 0, true);
  cfg.faults.push_back(RadioFault::BlockedPath("tx2", "rx1", kT0 + 10, 5));
  cfg.faults.push_back(RadioFault::MultipathJump("tx3", "rx2", kT0 + 20, 0.0, 1.0));
  cfg.faults.push_back(RadioFault::DroppedBlocks("rx3", kT0 + 30, 2.5));
  const RadioSimulator sim(cfg);
  EXPECT_EQ(sim.FaultDescriptions().size(), 3u);
  // Blocked: amplitude x0.02 during [10, 15) only.
  auto amp = [&](double t, int tx, int rx) {
    return std::abs(Dft(*sim.Synthesize(rx, t, 0), sim.config().transmitters[tx].frequency_offset));
  };
  EXPECT_NEAR(amp(kT0 + 9, 1, 0), 160.0, 1e-3);
  EXPECT_NEAR(amp(kT0 + 12, 1, 0), 160.0 * 0.02, 1e-3);
  EXPECT_NEAR(amp(kT0 + 15, 1, 0), 160.0, 1e-3);
  EXPECT_NEAR(amp(kT0 + 12, 1, 1), 160.0, 1e-3);  // other link untouched
  // Multipath: +1 rad from 20 s on.
  auto phase_err = [&](double t, int tx, int rx) {
    return radio::WrapPhase(
        std::arg(Dft(*sim.Synthesize(rx, t, 0), sim.config().transmitters[tx].frequency_offset)) -
        sim.WrappedPhase(tx, rx, t));
  };
  EXPECT_NEAR(phase_err(kT0 + 19, 2, 1), 0.0, 1e-4);
  EXPECT_NEAR(phase_err(kT0 + 25, 2, 1), 1.0, 1e-4);
  EXPECT_NEAR(phase_err(kT0 + 250, 2, 1), 1.0, 1e-4);
  EXPECT_NEAR(sim.FaultBias(2, 1, kT0 + 25), 1.0, 0.0);
  // Dropped: rx3 has no block in [30, 32.5).
  EXPECT_TRUE(sim.Synthesize(2, kT0 + 29, 29).has_value());
  EXPECT_FALSE(sim.Synthesize(2, kT0 + 30, 30).has_value());
  EXPECT_FALSE(sim.Synthesize(2, kT0 + 32, 32).has_value());
  EXPECT_TRUE(sim.Synthesize(2, kT0 + 33, 33).has_value());
  EXPECT_EQ(sim.SynthesizeAll(kT0 + 31, 31).size(), 2u);
}

TEST(RadioSim, SaturationClipsAtFullScale) {
  RadioSimConfig cfg = DemoConfig(0.0, 12);
  cfg.full_scale = 200.0;  // 5 tones of ~170 each: the sum clips
  const RadioSimulator sim(cfg);
  const auto b = sim.Synthesize(0, kT0, 0);
  float mx = 0.0f;
  for (float v : b->i) mx = std::max(mx, std::abs(v));
  EXPECT_FLOAT_EQ(mx, 200.0f);
}

TEST(RadioSim, BadConfigNamesTheField) {
  RadioSimConfig cfg = DemoConfig(1.0, 12);
  cfg.transmitters[3].frequency_offset = cfg.transmitters[2].frequency_offset + 1.0;
  try {
    RadioSimulator sim(cfg);
    FAIL() << "no exception";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("closer than one DFT bin"), std::string::npos) << e.what();
  }
  cfg = DemoConfig(1.0, 12);
  cfg.faults.push_back(RadioFault::BlockedPath("tx9", "rx1", kT0, 1));
  EXPECT_THROW(RadioSimulator{cfg}, InvalidArgument);
  cfg = DemoConfig(1.0, 12);
  cfg.transmitters[0].position = nullptr;
  EXPECT_THROW(RadioSimulator{cfg}, InvalidArgument);
}

}  // namespace
}  // namespace sim
}  // namespace slope_monitor
