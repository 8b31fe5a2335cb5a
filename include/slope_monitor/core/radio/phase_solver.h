// Transmitter positions and displacements from radio carrier phase
// ("inverse GPS", doc/design.md):
//   phi_ij = (2 pi / lambda) |x_i - X_j| + psi_i + xi_j + 2 pi N_ij
// receivers j at known (surveyed) X_j, transmitters i at unknown x_i(t).
//
// ---------------------------------------------------------------------------
// Why this estimator (and what it assumes; see core/sim/radio_sim.h)
// ---------------------------------------------------------------------------
// Transmitters and receivers are locked to a common disciplined reference, so
// psi_i and xi_j are constants. Two quantities are observable:
//  * Changes of range: phi_ij(t) - phi_ij(t0) = k (|x_i(t) - X_j| - |x_i(t0) - X_j|)
//    (k = 2 pi / lambda) once the integer count of cycles is known; three
//    receivers give the 3-D displacement of a transmitter at every block.
//  * Absolute positions: the geometry of a slope transmitter hardly changes
//    (mm per day), so the phases alone cannot separate position from the
//    constants psi_i, xi_j, N_ij. The installation survey (the configured
//    `initial_position` with its sigma) closes that gap.
// Choice for the nuisance terms: psi_i and xi_j are *estimated* (not
// differenced away) in the reference solution, with the datum xi_ref = 0 and
// N = 0 on a spanning tree of the link graph (each transmitter-receiver link
// an edge). Every remaining link's integer is then one generalised double
// difference (one independent cycle of the graph), the only integer
// combinations that are observable; with a full network they are the
// (T-1)(R-1) classic double differences. Estimating instead of differencing
// keeps a missing link from removing a whole row/column of differences, and
// gives the per-link constant B_ij = psi_i + xi_j + 2 pi N_ij that the
// tracking needs directly.
//
// 1. Reference solution (first `init_epochs` epochs): the circular mean of
//    each link's phase, reduced by the configured positions, y_ij =
//    wrap(phi_ij - k |x0_i - X_j|); a linear least-squares float solution of
//    position corrections (with the installation prior), psi, xi and the tree
//    complement integers; LAMBDA (LDL^T decorrelation + search, best and
//    second-best) with the ratio test; partial fixing (drop the least precise
//    ambiguity and retry) when the full set fails; "float only" when nothing
//    passes. The fixed solution is the float one conditioned on the integers.
// 2. Tracking (every later epoch), per transmitter: an extended Kalman filter
//    of the displacement d_i (random walk, `process_noise` m^2/s per axis).
//    Phase continuity between blocks (and across gaps) is kept by resolving
//    each epoch's integer cycle counts against the prediction with LAMBDA
//    (their float values (h(d_pred) - phi) / 2 pi, covariance from the
//    prediction and the phase noise) — a cycle slip or a gap becomes a re-fix
//    of the count; when the ratio test fails the links stay out of the update
//    (float state) instead of risking a wrong cycle.
//    Outliers: the link with the largest normalised innovation above
//    `outlier_sigma` is rejected (one per epoch, only with >= 3 links), so a
//    blocked path or a multipath jump hides one measurement. A link rejected
//    `refix_after` epochs in a row gets its constant B_ij re-fixed from the
//    current estimate (a lasting multipath change or a slip of the receiver);
//    a link that was not usable at the reference joins the same way.
// Output per transmitter: reference position (fixed solution), position and
// displacement with 3x3 covariances, fix state, ratio; per link: phase,
// SNR, innovation, status.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/radio/phase_extraction.h"
#include "slope_monitor/core/radio/types.h"

namespace slope_monitor {
namespace radio {

struct ReceiverConfig {
  std::string id;
  Eigen::Vector3d position{0, 0, 0};  // [m] antenna phase centre in site (surveyed)
};

struct TransmitterConfig {
  std::string id;
  double frequency_offset = 0.0;              // [Hz] carrier minus center_frequency
  Eigen::Vector3d initial_position{0, 0, 0};  // [m] installation survey in site
  double initial_sigma = 0.005;               // [m] its standard deviation per axis
};

// The radio network (config/radio/*.yaml, format slope_monitor_radio_network/1):
//   wavelength: 0.125            # [m] (0, 10]
//   center_frequency: 2.4e9      # [Hz] receivers' LO
//   sample_rate: 100000          # [Hz] expected complex sample rate
//   receivers:    [{id: rx1, position: [x, y, z]}]
//   transmitters: [{id: tx1, frequency_offset: 2441.4, initial_position: [x, y, z], initial_sigma:
//   0.005}]
struct NetworkConfig {
  double wavelength = 0.125;
  double center_frequency = 2.4e9;
  double sample_rate = 100e3;
  std::vector<ReceiverConfig> receivers;
  std::vector<TransmitterConfig> transmitters;

  static NetworkConfig Load(
      const std::string& path);  // throws IoError / ConfigError naming file and key
  static NetworkConfig FromYaml(const std::string& text, const std::string& context);
  std::string ToYaml() const;
  // Throws ConfigError: fewer than 3 receivers (no 3-D geometry), no
  // transmitter, duplicate ids, offsets outside the band.
  void Check(const std::string& context = "radio network") const;
  int FindReceiver(const std::string& id) const;     // -1 when absent
  int FindTransmitter(const std::string& id) const;  // -1 when absent
};

struct RadioSolverOptions {
  PhaseExtractionOptions extraction;
  int init_epochs = 5;           // [epochs] averaged for the reference solution; [1, 1000]
  double ratio_threshold = 3.0;  // [-] ratio test s2/s1 to accept integers; [1, 100]
  double process_noise =
      1e-9;  // [m^2/s] random-walk spectral density of the displacement per axis; [0, 1]
  double outlier_sigma = 5.0;  // [-] normalised innovation above which a link is rejected; [2, 100]
  int refix_after =
      5;  // [epochs] consecutive rejections before a link's constant is re-fixed; [1, 1000]
  double min_phase_sigma =
      0.01;  // [rad] floor on the phase standard deviation (multipath, model errors); [0, 1]
  int min_receivers = 3;  // receivers a transmitter needs at the reference solution; [3, 100]
  double max_refix_sigma =
      0.01;            // [m] displacement sigma up to which a link may (re-)join; (0, lambda/4]
  void Check() const;  // throws ConfigError naming the field
};

enum class FixState { kNone = 0, kFloat = 1, kPartial = 2, kFixed = 3 };
std::string FixStateName(FixState s);

struct TransmitterEstimate {
  std::string id;
  bool initialized = false;
  FixState fix_state =
      FixState::kNone;  // of the reference solution's integers touching this transmitter
  double ratio = 0.0;   // ratio test value of the reference solution
  FixState epoch_fix_state = FixState::kNone;  // of this epoch's cycle counts
  double epoch_ratio = 0.0;
  int links_used = 0;                                              // links in this epoch's update
  double reference_stamp = 0.0;                                    // [s]
  Eigen::Vector3d reference_position{0, 0, 0};                     // [m] site
  Eigen::Matrix3d reference_covariance = Eigen::Matrix3d::Zero();  // [m^2]
  Eigen::Vector3d position{0, 0, 0};                               // [m] site, now
  Eigen::Matrix3d position_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d displacement{0, 0, 0};  // [m] now minus reference
  Eigen::Matrix3d displacement_covariance = Eigen::Matrix3d::Zero();
  std::string status;  // "ok", "initialising", why not solved
};

struct LinkDiagnostics {
  std::string transmitter_id, receiver_id;
  bool observed = false;     // a valid phase this epoch
  bool used = false;         // in the update
  double phase = 0.0;        // [rad]
  double phase_sigma = 0.0;  // [rad]
  double snr = 0.0;          // [-]
  double innovation = 0.0;   // [rad] after the integer fix
  int rejected_streak = 0;   // consecutive outlier rejections
  int refixes = 0;           // times its constant was (re-)fixed after the reference
  std::string status;        // "ok", "outlier", "low SNR", "no block", "float", ...
};

struct RadioEpochSummary {
  double stamp = 0.0;
  std::vector<PhaseObservation> observations;  // all extracted phases (valid or not)
  std::vector<TransmitterEstimate> transmitters;
  std::vector<LinkDiagnostics> links;  // transmitter-major
  std::vector<std::string> problems;   // bad input of this epoch (one line each)
  std::vector<std::string> events;     // faults handled (outliers, re-fixes, dropped blocks)
  // Routine results, nothing wrong (the reference solution with every
  // ambiguity fixed): logged at INFO, where events are WARN.
  std::vector<std::string> notes;
  bool reference_solved_now = false;
  // True when at least one transmitter has an initialised estimate.
  bool IsSolutionUsable() const;
};

// The reference solution, kept for inspection and tests.
struct ReferenceSolution {
  bool solved = false;
  double stamp = 0.0;
  int num_ambiguities = 0;
  int num_fixed = 0;
  double ratio = 0.0;
  FixState fix_state = FixState::kNone;
  std::vector<std::string> excluded;  // transmitters without enough receivers
  // Circular mean phase per link over the reference epochs [tx][rx] (NaN: not usable).
  std::vector<std::vector<double>> mean_phase;
};

class RadioPhaseSolver {
 public:
  // Throws ConfigError for a bad network or options.
  RadioPhaseSolver(NetworkConfig network, RadioSolverOptions options = {});

  // One epoch: the blocks of (some of) the receivers starting at `stamp`.
  // Never throws for bad blocks: each one's problem (unknown receiver, NaN,
  // wrong rate, saturation) goes to summary.problems and the rest is solved.
  RadioEpochSummary ProcessEpoch(double stamp, const std::vector<SampleBlock>& blocks);

  // The phases the last epoch extracted from its blocks (every link's phase,
  // variance, SNR), as text exact to the bit: the site's history keeps them,
  // so that epochs can be tracked again in time order when an earlier
  // recording is processed after them (ProcessPhases).
  std::string LastPhases() const;
  // One epoch from phases LastPhases() wrote: tracked as ProcessEpoch tracks
  // (the summary has no PhaseObservation list). Throws InvalidArgument for
  // text that is not such phases of this network.
  RadioEpochSummary ProcessPhases(const std::string& phases);

  const NetworkConfig& network() const { return network_; }
  const ReferenceSolution& reference() const { return reference_; }
  // Tracking constant B_ij of a link (phi = k |x_i - X_j| + B_ij mod 2 pi,
  // x_i the reference position), if it has one.
  std::optional<double> LinkConstant(int tx, int rx) const;
  // The reference solution's model constant psi_i + xi_j + 2 pi N_ij of a
  // link (estimated psi, xi with their datum, the fixed integer): its double
  // differences between two transmitters and two receivers are 2 pi times
  // the double-differenced integer ambiguity, comparable with the truth.
  std::optional<double> ModelConstant(int tx, int rx) const;

  // The whole state (reference solution, link constants, each transmitter's
  // tracking filter, the epochs still being averaged), exact to the bit
  // (core/common/state_text.h): the site's history keeps it between
  // recordings, so a later recording goes on from the same reference.
  std::string Save() const;
  // Throws InvalidArgument for text that is not a saved state of this
  // network (other transmitter or receiver ids, naming them).
  void Load(const std::string& text);

 private:
  struct Link {
    bool has_constant = false;
    double constant = 0.0;
    int rejected_streak = 0;
    int refixes = 0;
  };
  struct TxState {
    bool initialized = false;
    FixState fix_state = FixState::kNone;
    double ratio = 0.0;
    Eigen::Vector3d reference{0, 0, 0};
    Eigen::Matrix3d reference_cov = Eigen::Matrix3d::Zero();
    Eigen::Vector3d d{0, 0, 0};
    Eigen::Matrix3d p = Eigen::Matrix3d::Zero();
    double last_stamp = 0.0;
    std::string status = "initialising";
  };
  struct Obs {
    bool valid = false;
    double phase = 0.0, variance = 0.0, snr = 0.0;
    std::string problem;
  };
  struct TrackInfo {
    explicit TrackInfo(int nr) : link_used(nr, false), innovation(nr, 0.0), status(nr) {}
    FixState state = FixState::kNone;
    double ratio = 0.0;
    int used = 0;
    std::vector<bool> link_used;
    std::vector<double> innovation;
    std::vector<std::string> status;
  };
  struct EpochPhases {
    double stamp = 0.0;
    std::vector<std::vector<Obs>> obs;  // [tx][rx]
  };
  // Reference solution (first epochs) or tracking of one epoch's phases.
  void Solve(double stamp, const std::vector<std::vector<Obs>>& obs, RadioEpochSummary* summary);
  EpochPhases LoadPhases(const std::string& text) const;
  void SolveReference(RadioEpochSummary* summary);
  TrackInfo Track(int tx, double stamp, const std::vector<Obs>& obs, RadioEpochSummary* summary);
  double Wavenumber() const;

  NetworkConfig network_;
  RadioSolverOptions options_;
  PhaseExtractor extractor_;
  std::vector<TxState> tx_;
  std::vector<std::vector<Link>> links_;                    // [tx][rx]
  std::vector<std::vector<std::vector<Obs>>> init_buffer_;  // [epoch][tx][rx]
  std::vector<double> init_stamps_;
  std::vector<std::optional<std::uint32_t>> last_sequence_;  // per receiver
  ReferenceSolution reference_;
  std::map<std::pair<int, int>, double> model_constant_;
  EpochPhases last_phases_;
};

// Groups blocks arriving one by one (per receiver topic) into epochs by
// stamp. An epoch is complete when every configured receiver delivered a
// block with that stamp (within `tolerance` s). It is released incomplete
// when every missing receiver has delivered a newer block (it dropped this
// one), or when it is more than `max_wait` s older than the newest block and
// four newer epochs are pending (a receiver fell silent). Per-receiver topics
// interleave freely on a fast replay, so the result does not depend on the
// order in which the receivers' blocks arrive.
class EpochAssembler {
 public:
  EpochAssembler(std::vector<std::string> receiver_ids, double tolerance = 1e-3,
                 double max_wait = 2.5);
  struct Epoch {
    double stamp = 0.0;
    std::vector<SampleBlock> blocks;
  };
  // Adds a block; returns the epochs completed by it, oldest first.
  std::vector<Epoch> Add(SampleBlock block);
  std::vector<Epoch> Flush();  // everything pending
  std::size_t pending() const { return pending_.size(); }

 private:
  std::vector<std::string> receivers_;
  double tolerance_, max_wait_;
  std::vector<Epoch> pending_;
  std::map<std::string, double> latest_;  // newest stamp per receiver
};

}  // namespace radio
}  // namespace slope_monitor
