// Time to process one epoch of radio samples for the demo network
// (config/sim/demo_site.yaml "radio": 3 receivers, 5 transmitters, 20 kHz,
// 1024-sample blocks), as a ratio to the block duration (real time), and
// against a plain DFT of the same blocks at the known frequencies (baseline
// run in this process).
//   bench_radio_epoch [epochs=300]
#include <chrono>
#include <complex>
#include <cstdio>
#include <cstdlib>

#include "slope_monitor/core/radio/phase_solver.h"
#include "slope_monitor/core/sim/radio_sim.h"

using namespace slope_monitor;

int main(int argc, char** argv) {
  const int epochs = argc > 1 ? std::atoi(argv[1]) : 300;
  const double t0 = 1700000000.0;
  sim::RadioSimConfig cfg;
  cfg.sample_rate = 20000.0;
  cfg.block_size = 1024;
  cfg.noise_sigma = 10.0;
  radio::NetworkConfig net;
  net.sample_rate = cfg.sample_rate;
  const std::vector<Eigen::Vector3d> rx = {
      {40, 135, 43},
      {160, 135, 43},
      {100, 146, 46},
  };
  const std::vector<Eigen::Vector3d> tx = {
      {100, 80, 21.5}, {90, 96, 26.5}, {110, 96, 26.5}, {92, 62, 16.5}, {108, 62, 16.5}};
  for (int j = 0; j < 3; ++j) {
    cfg.receivers.push_back({"rx" + std::to_string(j + 1), rx[j], 0.3 * j, ""});
    net.receivers.push_back({"rx" + std::to_string(j + 1), rx[j]});
  }
  for (int i = 0; i < 5; ++i) {
    sim::RadioSimTransmitter t;
    t.id = "tx" + std::to_string(i + 1);
    t.frequency_offset = 1000.0 + 1500.0 * i;
    t.psi = 0.5 * i;
    t.amplitude = 100.0;
    const Eigen::Vector3d x0 = tx[i];
    t.position = [x0, t0](double t) {
      return Eigen::Vector3d(x0 + Eigen::Vector3d(0, -1e-6, 0) * (t - t0));
    };
    cfg.transmitters.push_back(t);
    net.transmitters.push_back({t.id, t.frequency_offset, x0, 0.005});
  }
  const sim::RadioSimulator sim(cfg);
  std::vector<std::vector<radio::SampleBlock>> data;
  for (int e = 0; e < epochs; ++e) data.push_back(sim.SynthesizeAll(t0 + e, e));

  using Clock = std::chrono::steady_clock;
  radio::RadioPhaseSolver solver(net);
  const auto a = Clock::now();
  int usable = 0;
  for (int e = 0; e < epochs; ++e)
    usable += solver.ProcessEpoch(t0 + e, data[e]).IsSolutionUsable();
  const double ours = std::chrono::duration<double>(Clock::now() - a).count() / epochs;

  // Baseline: a plain DFT at the 5 frequencies of every block (no fit, no solver).
  const auto b = Clock::now();
  double sink = 0.0;
  for (int e = 0; e < epochs; ++e)
    for (const auto& blk : data[e])
      for (const auto& t : cfg.transmitters) {
        std::complex<double> s(0, 0);
        const double w = -2.0 * M_PI * t.frequency_offset / blk.sample_rate;
        for (std::size_t k = 0; k < blk.size(); ++k)
          s += std::complex<double>(blk.i[k], blk.q[k]) *
               std::polar(1.0, w * static_cast<double>(k));
        sink += std::arg(s);
      }
  const double dft = std::chrono::duration<double>(Clock::now() - b).count() / epochs;
  const double block = cfg.block_size / cfg.sample_rate;
  std::printf(
      "epochs %d (usable %d), receivers 3, transmitters 5, block %d samples @ %.0f Hz = %.4f s\n",
      epochs, usable, cfg.block_size, cfg.sample_rate, block);
  std::printf("time per epoch: ours %.3f ms, plain DFT %.3f ms (checksum %.3f)\n", 1e3 * ours,
              1e3 * dft, sink);
  std::printf("ratio ours/block_duration = %.5f\n", ours / block);
  std::printf("ratio ours/plain_dft = %.2f\n", ours / dft);
  return 0;
}
