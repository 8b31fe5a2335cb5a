#include "slope_monitor/core/radio/phase_solver.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <fstream>
#include <numeric>
#include <queue>
#include <set>
#include <sstream>

#include <Eigen/Dense>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/state_text.h"
#include "slope_monitor/core/io/yaml_map.h"
#include "slope_monitor/core/radio/lambda.h"

namespace slope_monitor {
namespace radio {
namespace {

std::vector<Tone> TonesOf(const NetworkConfig& n) {
  std::vector<Tone> t;
  for (const TransmitterConfig& c : n.transmitters)
    t.push_back({c.id, n.center_frequency + c.frequency_offset});
  return t;
}

Eigen::Vector3d Vec3(const std::vector<double>& v) { return Eigen::Vector3d(v[0], v[1], v[2]); }

// Partial ambiguity fixing: LAMBDA on the full set; while the ratio test
// fails, drop the ambiguity with the largest variance and retry. Returns the
// indices fixed (empty: float only), their integers and the ratio of the
// accepted (or, when none, the full) set.
struct FixResult {
  std::vector<int> fixed;
  Eigen::VectorXd integers;
  double ratio = 0.0;
};
FixResult PartialFix(const Eigen::VectorXd& a, const Eigen::MatrixXd& q, double threshold) {
  FixResult r;
  std::vector<int> idx(a.size());
  std::iota(idx.begin(), idx.end(), 0);
  bool first = true;
  while (!idx.empty()) {
    const int m = static_cast<int>(idx.size());
    Eigen::VectorXd as(m);
    Eigen::MatrixXd qs(m, m);
    for (int i = 0; i < m; ++i) {
      as(i) = a(idx[i]);
      for (int j = 0; j < m; ++j) qs(i, j) = q(idx[i], idx[j]);
    }
    const LambdaResult l = LambdaSearch(as, qs, 2);
    const double ratio = l.Ratio();
    if (first) r.ratio = ratio;
    first = false;
    if (ratio >= threshold) {
      r.fixed = idx;
      r.integers = l.candidates.col(0);
      r.ratio = ratio;
      return r;
    }
    int worst = 0;
    for (int i = 1; i < m; ++i)
      if (qs(i, i) > qs(worst, worst)) worst = i;
    idx.erase(idx.begin() + worst);
  }
  return r;
}

// The circular mean of each link's phase over the buffered epochs where it
// was valid, and its variance; a link valid in fewer than half of them is
// not usable.
template <typename Buffer>
void LinkPhaseMeans(const Buffer& buffer, int nt, int nr, std::vector<std::vector<bool>>* usable,
                    std::vector<std::vector<double>>* mean, std::vector<std::vector<double>>* var) {
  const int ne = static_cast<int>(buffer.size());
  for (int tx = 0; tx < nt; ++tx)
    for (int rx = 0; rx < nr; ++rx) {
      std::complex<double> sum(0.0, 0.0);
      double vsum = 0.0;
      int count = 0;
      for (int e = 0; e < ne; ++e) {
        const auto& o = buffer[e][tx][rx];
        if (!o.valid) continue;
        sum += std::polar(1.0, o.phase);
        vsum += o.variance;
        ++count;
      }
      if (count * 2 < ne || count == 0) continue;
      (*usable)[tx][rx] = true;
      (*mean)[tx][rx] = std::arg(sum);
      (*var)[tx][rx] = vsum / count / count;
    }
}

// The reference solution's parameter layout: [dX_tx (3 each) | psi_tx |
// xi_rx (not the reference receiver's) | N (non-tree links)], -1 where a
// parameter is not solved.
struct ReferenceParameters {
  std::vector<int> px, ppsi, pxi;
  std::vector<std::vector<int>> pn;
  std::vector<std::pair<int, int>> amb_links;  // (tx, rx) of each ambiguity
  int np = 0, first_amb = 0;
};

ReferenceParameters ReferenceParameterLayout(const std::vector<bool>& tx_in,
                                             const std::vector<std::vector<bool>>& usable,
                                             const std::vector<std::vector<bool>>& tree,
                                             const std::vector<bool>& seen, int ref_rx) {
  const int nt = static_cast<int>(tx_in.size());
  const int nr = nt > 0 ? static_cast<int>(usable[0].size()) : 0;
  ReferenceParameters l;
  l.px.assign(nt, -1);
  l.ppsi.assign(nt, -1);
  l.pxi.assign(nr, -1);
  l.pn.assign(nt, std::vector<int>(nr, -1));
  int np = 0;
  for (int tx = 0; tx < nt; ++tx)
    if (tx_in[tx]) {
      l.px[tx] = np;
      np += 3;
    }
  for (int tx = 0; tx < nt; ++tx)
    if (tx_in[tx]) l.ppsi[tx] = np++;
  for (int rx = 0; rx < nr; ++rx)
    if (rx != ref_rx && seen[nt + rx]) l.pxi[rx] = np++;
  l.first_amb = np;
  for (int tx = 0; tx < nt; ++tx)
    for (int rx = 0; rx < nr; ++rx)
      if (usable[tx][rx] && !tree[tx][rx]) {
        l.pn[tx][rx] = np++;
        l.amb_links.push_back({tx, rx});
      }
  l.np = np;
  return l;
}

// The float solution conditioned on the fixed ambiguities: x and its
// covariance updated by the fixed integers, the integers put in place;
// *amb_fixed marks them.
void ConditionOnFixedAmbiguities(const FixResult& fr, const Eigen::MatrixXd& cov, int first_amb,
                                 Eigen::VectorXd* x_io, Eigen::MatrixXd* cov_fixed,
                                 std::vector<bool>* amb_fixed) {
  Eigen::VectorXd& x = *x_io;
  const int np = static_cast<int>(cov.rows());
  const int nf = static_cast<int>(fr.fixed.size());
  Eigen::MatrixXd q_xf(np, nf), q_ff(nf, nf);
  Eigen::VectorXd diff(nf);
  for (int i = 0; i < nf; ++i) {
    const int pi = first_amb + fr.fixed[i];
    q_xf.col(i) = cov.col(pi);
    diff(i) = x(pi) - fr.integers(i);
    (*amb_fixed)[fr.fixed[i]] = true;
    for (int j = 0; j < nf; ++j) q_ff(i, j) = cov(pi, first_amb + fr.fixed[j]);
  }
  const Eigen::MatrixXd gain = q_xf * q_ff.inverse();
  x -= gain * diff;
  *cov_fixed = cov - gain * q_xf.transpose();
  for (int i = 0; i < nf; ++i) x(first_amb + fr.fixed[i]) = fr.integers(i);
}

// The spanning tree of the link graph (nodes: transmitters 0..nt-1,
// receivers nt..nt+nr-1) from the first receiver with usable links, whose
// links get N = 0. Returns that receiver (-1: none); *seen the nodes
// reached, *tree the tree's links.
int ReferenceSpanningTree(const std::vector<std::vector<bool>>& usable, int nt, int nr,
                          std::vector<bool>* seen, std::vector<std::vector<bool>>* tree) {
  std::vector<bool>& s = *seen;
  std::vector<std::vector<bool>>& tr = *tree;
  int ref_rx = -1;
  for (int rx = 0; rx < nr && ref_rx < 0; ++rx)
    for (int tx = 0; tx < nt; ++tx)
      if (usable[tx][rx]) {
        ref_rx = rx;
        break;
      }
  if (ref_rx < 0) return -1;
  std::queue<int> todo;
  todo.push(nt + ref_rx);
  s[nt + ref_rx] = true;
  while (!todo.empty()) {
    const int v = todo.front();
    todo.pop();
    if (v >= nt) {
      const int rx = v - nt;
      for (int tx = 0; tx < nt; ++tx)
        if (usable[tx][rx] && !s[tx]) {
          s[tx] = true;
          tr[tx][rx] = true;
          todo.push(tx);
        }
    } else {
      for (int rx = 0; rx < nr; ++rx)
        if (usable[v][rx] && !s[nt + rx]) {
          s[nt + rx] = true;
          tr[v][rx] = true;
          todo.push(nt + rx);
        }
    }
  }
  return ref_rx;
}

// The float solution's normal equations: each usable link's mean phase
// reduced by k * r0 (r0 from the installation survey) against the
// transmitter's shift, its psi, the receiver's xi (not the reference
// receiver's) and its ambiguity (non-tree links), weighted by the inverse
// phase variance; the installation survey as a prior on each shift.
// *reduced the reduced phases.
void ReferenceNormalEquations(const NetworkConfig& network, double k,
                              const std::vector<bool>& tx_in,
                              const std::vector<std::vector<bool>>& usable,
                              const std::vector<std::vector<double>>& mean,
                              const std::vector<std::vector<double>>& var,
                              const std::vector<int>& px, const std::vector<int>& ppsi,
                              const std::vector<int>& pxi, const std::vector<std::vector<int>>& pn,
                              Eigen::MatrixXd* normal_out, Eigen::VectorXd* rhs_out,
                              std::vector<std::vector<double>>* reduced_out) {
  const int nt = static_cast<int>(network.transmitters.size());
  const int nr = static_cast<int>(network.receivers.size());
  const int np = static_cast<int>(normal_out->rows());
  Eigen::MatrixXd& normal = *normal_out;
  Eigen::VectorXd& rhs = *rhs_out;
  std::vector<std::vector<double>>& reduced = *reduced_out;
  for (int tx = 0; tx < nt; ++tx) {
    if (!tx_in[tx]) continue;
    const Eigen::Vector3d& x0 = network.transmitters[tx].initial_position;
    for (int rx = 0; rx < nr; ++rx) {
      if (!usable[tx][rx]) continue;
      const Eigen::Vector3d dx = x0 - network.receivers[rx].position;
      const double r0 = dx.norm();
      const double y = WrapPhase(mean[tx][rx] - k * r0);
      reduced[tx][rx] = y;
      Eigen::VectorXd a = Eigen::VectorXd::Zero(np);
      a.segment<3>(px[tx]) = k * dx / r0;
      a(ppsi[tx]) = 1.0;
      if (pxi[rx] >= 0) a(pxi[rx]) = 1.0;
      if (pn[tx][rx] >= 0) a(pn[tx][rx]) = 2.0 * M_PI;
      const double w = 1.0 / var[tx][rx];
      normal += w * a * a.transpose();
      rhs += w * y * a;
    }
    const double wp = 1.0 / std::pow(network.transmitters[tx].initial_sigma, 2);
    normal.block<3, 3>(px[tx], px[tx]) += wp * Eigen::Matrix3d::Identity();
  }
}

}  // namespace

// ---------------------------------------------------------------------------
std::string FixStateName(FixState s) {
  switch (s) {
    case FixState::kNone:
      return "none";
    case FixState::kFloat:
      return "float";
    case FixState::kPartial:
      return "partial";
    case FixState::kFixed:
      return "fixed";
  }
  return "?";
}

NetworkConfig NetworkConfig::FromYaml(const std::string& text, const std::string& context) {
  io::YamlMap root = io::YamlMap::Parse(text, context);
  NetworkConfig n;
  root.String("format", "slope_monitor_radio_network/1", {"slope_monitor_radio_network/1"});
  n.wavelength = root.RequiredDouble("wavelength", 1e-3, 10.0, "m");
  n.center_frequency = root.RequiredDouble("center_frequency", 1.0, 1e12, "Hz");
  n.sample_rate = root.RequiredDouble("sample_rate", 1.0, 1e10, "Hz");
  for (io::YamlMap& r : root.List("receivers")) {
    ReceiverConfig c;
    c.id = r.RequiredString("id");
    c.position = Vec3(r.RequiredDoubles("position", 3));
    r.CheckNoUnknownKeys();
    n.receivers.push_back(c);
  }
  for (io::YamlMap& t : root.List("transmitters")) {
    TransmitterConfig c;
    c.id = t.RequiredString("id");
    c.frequency_offset =
        t.RequiredDouble("frequency_offset", -0.5 * n.sample_rate, 0.5 * n.sample_rate, "Hz");
    c.initial_position = Vec3(t.RequiredDoubles("initial_position", 3));
    c.initial_sigma = t.Double("initial_sigma", 0.005, 1e-5, 10.0, "m");
    t.CheckNoUnknownKeys();
    n.transmitters.push_back(c);
  }
  root.CheckNoUnknownKeys();
  n.Check(context);
  return n;
}

NetworkConfig NetworkConfig::Load(const std::string& path) {
  io::YamlMap root = io::YamlMap::Load(path);  // throws IoError naming the file
  (void)root;
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return FromYaml(ss.str(), path);
}

std::string NetworkConfig::ToYaml() const {
  std::ostringstream o;
  o.precision(12);
  o << "format: slope_monitor_radio_network/1\nwavelength: " << wavelength
    << "\ncenter_frequency: " << center_frequency << "\nsample_rate: " << sample_rate
    << "\nreceivers:\n";
  for (const auto& r : receivers)
    o << "  - {id: " << r.id << ", position: [" << r.position.x() << ", " << r.position.y() << ", "
      << r.position.z() << "]}\n";
  o << "transmitters:\n";
  for (const auto& t : transmitters)
    o << "  - {id: " << t.id << ", frequency_offset: " << t.frequency_offset
      << ", initial_position: [" << t.initial_position.x() << ", " << t.initial_position.y() << ", "
      << t.initial_position.z() << "], initial_sigma: " << t.initial_sigma << "}\n";
  return o.str();
}

void NetworkConfig::Check(const std::string& context) const {
  if (receivers.size() < 3)
    throw ConfigError(
        Message(context, ": receivers: ", receivers.size(),
                " configured, at least 3 are needed for a 3-D position of a transmitter"));
  if (transmitters.empty()) throw ConfigError(Message(context, ": transmitters: none configured"));
  if (!(wavelength > 0.0))
    throw ConfigError(Message(context, ": wavelength = ", wavelength, " must be > 0"));
  std::set<std::string> ids;
  for (std::size_t j = 0; j < receivers.size(); ++j) {
    if (receivers[j].id.empty())
      throw ConfigError(Message(context, ": receivers[", j, "].id is empty"));
    if (!ids.insert(receivers[j].id).second)
      throw ConfigError(
          Message(context, ": receivers[", j, "].id '", receivers[j].id, "' repeated"));
  }
  ids.clear();
  for (std::size_t i = 0; i < transmitters.size(); ++i) {
    const TransmitterConfig& t = transmitters[i];
    if (t.id.empty()) throw ConfigError(Message(context, ": transmitters[", i, "].id is empty"));
    if (!ids.insert(t.id).second)
      throw ConfigError(Message(context, ": transmitters[", i, "].id '", t.id, "' repeated"));
    if (!(std::abs(t.frequency_offset) < 0.5 * sample_rate))
      throw ConfigError(Message(context, ": transmitters[", i, "].frequency_offset = ",
                                t.frequency_offset, " Hz outside +-sample_rate/2"));
    if (!(t.initial_sigma > 0.0))
      throw ConfigError(Message(context, ": transmitters[", i, "].initial_sigma must be > 0"));
  }
}

int NetworkConfig::FindReceiver(const std::string& id) const {
  for (std::size_t j = 0; j < receivers.size(); ++j)
    if (receivers[j].id == id) return static_cast<int>(j);
  return -1;
}

int NetworkConfig::FindTransmitter(const std::string& id) const {
  for (std::size_t i = 0; i < transmitters.size(); ++i)
    if (transmitters[i].id == id) return static_cast<int>(i);
  return -1;
}

void RadioSolverOptions::Check() const {
  extraction.Check();
  auto bad = [](const std::string& what) { throw ConfigError(what); };
  if (init_epochs < 1 || init_epochs > 1000)
    bad(Message("init_epochs = ", init_epochs, " must be in [1, 1000]"));
  if (!(ratio_threshold >= 1.0 && ratio_threshold <= 100.0))
    bad(Message("ratio_threshold = ", ratio_threshold, " must be in [1, 100]"));
  if (!(process_noise >= 0.0 && process_noise <= 1.0))
    bad(Message("process_noise = ", process_noise, " must be in [0, 1] m^2/s"));
  if (!(outlier_sigma >= 2.0 && outlier_sigma <= 100.0))
    bad(Message("outlier_sigma = ", outlier_sigma, " must be in [2, 100]"));
  if (refix_after < 1 || refix_after > 1000)
    bad(Message("refix_after = ", refix_after, " must be in [1, 1000]"));
  if (!(min_phase_sigma >= 0.0 && min_phase_sigma <= 1.0))
    bad(Message("min_phase_sigma = ", min_phase_sigma, " must be in [0, 1] rad"));
  if (min_receivers < 3 || min_receivers > 100)
    bad(Message("min_receivers = ", min_receivers, " must be in [3, 100]"));
  if (!(max_refix_sigma > 0.0)) bad(Message("max_refix_sigma = ", max_refix_sigma, " must be > 0"));
}

bool RadioEpochSummary::IsSolutionUsable() const {
  for (const auto& t : transmitters)
    if (t.initialized) return true;
  return false;
}

// ---------------------------------------------------------------------------
RadioPhaseSolver::RadioPhaseSolver(NetworkConfig network, RadioSolverOptions options)
    : network_(std::move(network)),
      options_(options),
      extractor_(TonesOf(network_), network_.center_frequency, network_.sample_rate,
                 options.extraction) {
  network_.Check();
  options_.Check();
  if (options_.max_refix_sigma > network_.wavelength / 4)
    throw ConfigError(
        Message("max_refix_sigma = ", options_.max_refix_sigma, " must be <= wavelength / 4"));
  tx_.resize(network_.transmitters.size());
  links_.assign(network_.transmitters.size(), std::vector<Link>(network_.receivers.size()));
  last_sequence_.resize(network_.receivers.size());
}

double RadioPhaseSolver::Wavenumber() const { return 2.0 * M_PI / network_.wavelength; }

std::optional<double> RadioPhaseSolver::LinkConstant(int tx, int rx) const {
  const Link& l = links_.at(tx).at(rx);
  if (!l.has_constant) return std::nullopt;
  return l.constant;
}

RadioEpochSummary RadioPhaseSolver::ProcessEpoch(double stamp,
                                                 const std::vector<SampleBlock>& blocks) {
  RadioEpochSummary summary;
  summary.stamp = stamp;
  const int nt = static_cast<int>(network_.transmitters.size());
  const int nr = static_cast<int>(network_.receivers.size());
  std::vector<std::vector<Obs>> obs(nt, std::vector<Obs>(nr));
  std::vector<bool> got(nr, false);
  for (const SampleBlock& b : blocks) {
    const int rx = network_.FindReceiver(b.receiver_id);
    if (rx < 0) {
      summary.problems.push_back(Message("receiver '", b.receiver_id,
                                         "' is not in the network configuration: block ignored"));
      continue;
    }
    if (got[rx]) {
      summary.problems.push_back(
          Message("receiver '", b.receiver_id, "': two blocks in one epoch, second ignored"));
      continue;
    }
    got[rx] = true;
    if (last_sequence_[rx] && b.sequence > *last_sequence_[rx] + 1)
      summary.events.push_back(
          Message("receiver '", b.receiver_id, "': ", b.sequence - *last_sequence_[rx] - 1,
                  " block(s) dropped (sequence ", *last_sequence_[rx], " -> ", b.sequence, ")"));
    last_sequence_[rx] = b.sequence;
    std::vector<PhaseObservation> po;
    try {
      po = extractor_.Extract(b);
    } catch (const Error& e) {
      summary.problems.push_back(e.what());
      continue;
    }
    bool reported = false;
    for (int tx = 0; tx < nt; ++tx) {
      const PhaseObservation& p = po[tx];
      Obs& o = obs[tx][rx];
      o.valid = p.valid;
      o.phase = p.phase;
      o.snr = p.snr;
      o.variance = std::max(p.phase_variance, options_.min_phase_sigma * options_.min_phase_sigma);
      o.problem = p.problem;
      if (!p.valid && p.problem.find("saturated") != std::string::npos && !reported) {
        summary.problems.push_back(p.problem);
        reported = true;
      }
      summary.observations.push_back(p);
    }
  }
  for (int rx = 0; rx < nr; ++rx)
    if (!got[rx])
      for (int tx = 0; tx < nt; ++tx) obs[tx][rx].problem = "no block";
  last_phases_ = {stamp, obs};
  Solve(stamp, obs, &summary);
  return summary;
}

RadioEpochSummary RadioPhaseSolver::ProcessPhases(const std::string& text) {
  EpochPhases phases = LoadPhases(text);
  RadioEpochSummary summary;
  summary.stamp = phases.stamp;
  last_phases_ = phases;
  Solve(phases.stamp, phases.obs, &summary);
  return summary;
}

void RadioPhaseSolver::Solve(double stamp, const std::vector<std::vector<Obs>>& obs,
                             RadioEpochSummary* out) {
  RadioEpochSummary& summary = *out;
  const int nt = static_cast<int>(network_.transmitters.size());
  const int nr = static_cast<int>(network_.receivers.size());
  if (!reference_.solved) {
    init_buffer_.push_back(obs);
    init_stamps_.push_back(stamp);
    if (static_cast<int>(init_buffer_.size()) >= options_.init_epochs) {
      SolveReference(&summary);
      init_buffer_.clear();
      init_stamps_.clear();
    }
  }
  std::vector<TrackInfo> infos(nt, TrackInfo(nr));
  if (reference_.solved && !summary.reference_solved_now) {
    for (int tx = 0; tx < nt; ++tx)
      if (tx_[tx].initialized) infos[tx] = Track(tx, stamp, obs[tx], &summary);
  }

  // Outputs.
  for (int tx = 0; tx < nt; ++tx) {
    const TxState& s = tx_[tx];
    TransmitterEstimate e;
    e.id = network_.transmitters[tx].id;
    e.initialized = s.initialized;
    e.fix_state = s.fix_state;
    e.ratio = s.ratio;
    e.reference_stamp = reference_.stamp;
    e.reference_position = s.reference;
    e.reference_covariance = s.reference_cov;
    e.displacement = s.d;
    e.displacement_covariance = s.p;
    e.position = s.reference + s.d;
    e.position_covariance = s.reference_cov + s.p;
    e.status = s.status;
    summary.transmitters.push_back(e);
    for (int rx = 0; rx < nr; ++rx) {
      LinkDiagnostics d;
      d.transmitter_id = e.id;
      d.receiver_id = network_.receivers[rx].id;
      d.observed = obs[tx][rx].valid;
      d.phase = obs[tx][rx].phase;
      d.phase_sigma = std::sqrt(obs[tx][rx].variance);
      d.snr = obs[tx][rx].snr;
      d.rejected_streak = links_[tx][rx].rejected_streak;
      d.refixes = links_[tx][rx].refixes;
      d.status = obs[tx][rx].valid
                     ? "ok"
                     : (obs[tx][rx].problem.empty() ? "no phase" : obs[tx][rx].problem);
      summary.links.push_back(d);
    }
  }
  for (int tx = 0; tx < nt; ++tx) {
    summary.transmitters[tx].epoch_fix_state = infos[tx].state;
    summary.transmitters[tx].epoch_ratio = infos[tx].ratio;
    summary.transmitters[tx].links_used = infos[tx].used;
    for (int rx = 0; rx < nr; ++rx) {
      LinkDiagnostics& d = summary.links[tx * nr + rx];
      d.used = infos[tx].link_used[rx];
      d.innovation = infos[tx].innovation[rx];
      if (!infos[tx].status[rx].empty()) d.status = infos[tx].status[rx];
    }
  }
}

// ---------------------------------------------------------------------------
// Reference solution: float least squares + LAMBDA over the first epochs.
void RadioPhaseSolver::SolveReference(RadioEpochSummary* summary) {
  const int nt = static_cast<int>(network_.transmitters.size());
  const int nr = static_cast<int>(network_.receivers.size());
  const double k = Wavenumber();

  // Circular mean of each link's phase over the epochs where it was valid.
  std::vector<std::vector<bool>> usable(nt, std::vector<bool>(nr, false));
  std::vector<std::vector<double>> mean(nt, std::vector<double>(nr, 0.0)),
      var(nt, std::vector<double>(nr, 0.0));
  LinkPhaseMeans(init_buffer_, nt, nr, &usable, &mean, &var);
  // Transmitters with too few receivers are left out (reported), the rest solved.
  std::vector<bool> tx_in(nt, false);
  for (int tx = 0; tx < nt; ++tx) {
    const int n = static_cast<int>(std::count(usable[tx].begin(), usable[tx].end(), true));
    if (n >= options_.min_receivers) {
      tx_in[tx] = true;
    } else {
      const std::string msg =
          Message("transmitter '", network_.transmitters[tx].id, "': only ", n,
                  " receiver(s) with a usable phase at the reference epochs, ",
                  options_.min_receivers, " needed for a 3-D position; not solved");
      summary->problems.push_back(msg);
      reference_.excluded.push_back(network_.transmitters[tx].id);
      tx_[tx].status = msg;
      std::fill(usable[tx].begin(), usable[tx].end(), false);
    }
  }
  // Spanning tree of the link graph (nodes: transmitters 0..nt-1, receivers
  // nt..nt+nr-1) from the first receiver with links: N = 0 on its edges.
  std::vector<bool> seen(nt + nr, false);
  std::vector<std::vector<bool>> tree(nt, std::vector<bool>(nr, false));
  const int ref_rx = ReferenceSpanningTree(usable, nt, nr, &seen, &tree);
  if (ref_rx < 0) {
    summary->problems.push_back(
        "radio reference solution: no transmitter has enough usable links; retrying");
    return;
  }
  for (int tx = 0; tx < nt; ++tx)
    if (tx_in[tx] && !seen[tx]) {  // not connected to the reference receiver
      const std::string msg =
          Message("transmitter '", network_.transmitters[tx].id,
                  "': its receivers share no transmitter with the rest of the network; not solved");
      summary->problems.push_back(msg);
      tx_[tx].status = msg;
      tx_in[tx] = false;
      std::fill(usable[tx].begin(), usable[tx].end(), false);
    }
  const ReferenceParameters layout = ReferenceParameterLayout(tx_in, usable, tree, seen, ref_rx);
  const std::vector<int>&px = layout.px, &ppsi = layout.ppsi, &pxi = layout.pxi;
  const std::vector<std::vector<int>>& pn = layout.pn;
  const std::vector<std::pair<int, int>>& amb_links = layout.amb_links;
  const int np = layout.np, first_amb = layout.first_amb, na = np - first_amb;

  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(np, np);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(np);
  std::vector<std::vector<double>> reduced(nt, std::vector<double>(nr, 0.0));
  ReferenceNormalEquations(network_, k, tx_in, usable, mean, var, px, ppsi, pxi, pn, &normal, &rhs,
                           &reduced);
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(normal);
  if (ldlt.info() != Eigen::Success || ldlt.vectorD().minCoeff() <= 0.0) {
    summary->problems.push_back("radio reference solution: singular normal equations; retrying");
    return;
  }
  const Eigen::MatrixXd cov = ldlt.solve(Eigen::MatrixXd::Identity(np, np));
  Eigen::VectorXd x = cov * rhs;
  Eigen::MatrixXd cov_fixed = cov;

  // Integer ambiguities (in cycles).
  FixState net_state = FixState::kFixed;
  std::vector<bool> amb_fixed(na, false);
  if (na > 0) {
    const Eigen::VectorXd a = x.segment(first_amb, na);
    const Eigen::MatrixXd qa = cov.block(first_amb, first_amb, na, na);
    const FixResult fr = PartialFix(a, qa, options_.ratio_threshold);
    reference_.ratio = fr.ratio;
    const int nf = static_cast<int>(fr.fixed.size());
    reference_.num_fixed = nf;
    net_state = nf == na ? FixState::kFixed : (nf > 0 ? FixState::kPartial : FixState::kFloat);
    if (nf > 0) ConditionOnFixedAmbiguities(fr, cov, first_amb, &x, &cov_fixed, &amb_fixed);
    // Every ambiguity fixed is the normal outcome (a note); a partial or
    // float reference solution is worth a warning (an event).
    (net_state == FixState::kFixed ? summary->notes : summary->events)
        .push_back(Message("reference solution: ", nf, " of ", na, " ambiguities fixed, ratio ",
                           fr.ratio, " (", FixStateName(net_state), ")"));
  } else {
    reference_.ratio = std::numeric_limits<double>::infinity();
  }
  reference_.num_ambiguities = na;
  reference_.mean_phase.assign(nt,
                               std::vector<double>(nr, std::numeric_limits<double>::quiet_NaN()));
  for (int tx = 0; tx < nt; ++tx)
    for (int rx = 0; rx < nr; ++rx)
      if (usable[tx][rx]) reference_.mean_phase[tx][rx] = mean[tx][rx];
  reference_.fix_state = net_state;
  reference_.solved = true;
  double mean_stamp = 0.0;
  for (double s : init_stamps_) mean_stamp += s;
  reference_.stamp = mean_stamp / init_stamps_.size();
  summary->reference_solved_now = true;

  for (int tx = 0; tx < nt; ++tx) {
    if (!tx_in[tx]) continue;
    TxState& s = tx_[tx];
    s.initialized = true;
    s.reference = network_.transmitters[tx].initial_position + x.segment<3>(px[tx]);
    s.reference_cov = cov_fixed.block<3, 3>(px[tx], px[tx]);
    s.d.setZero();
    s.p.setZero();
    s.last_stamp = init_stamps_.back();
    int own = 0, own_fixed = 0;
    for (int i = 0; i < na; ++i)
      if (amb_links[i].first == tx) {
        ++own;
        own_fixed += amb_fixed[i] ? 1 : 0;
      }
    s.fix_state =
        own == 0 ? net_state
                 : (own_fixed == own ? FixState::kFixed
                                     : (own_fixed > 0 ? FixState::kPartial : FixState::kFloat));
    s.ratio = reference_.ratio;
    s.status = "ok";
    for (int rx = 0; rx < nr; ++rx) {
      if (!usable[tx][rx]) continue;
      Link& l = links_[tx][rx];
      // Tracking constant: consistent with the reference position and the
      // mean phase, so the displacement starts at zero.
      const double r = (s.reference - network_.receivers[rx].position).norm();
      l.has_constant = true;
      l.constant = WrapPhase(mean[tx][rx] - k * r);
      // Model constant psi + xi + 2 pi N (+ the wrap of the reduced phase):
      // its double differences are 2 pi times integers (LinkConstant()).
      const double r0 =
          (network_.transmitters[tx].initial_position - network_.receivers[rx].position).norm();
      double model = x(ppsi[tx]) + (pxi[rx] >= 0 ? x(pxi[rx]) : 0.0) +
                     (pn[tx][rx] >= 0 ? 2.0 * M_PI * x(pn[tx][rx]) : 0.0) +
                     (mean[tx][rx] - k * r0 - reduced[tx][rx]);
      model_constant_[{tx, rx}] = model;
    }
  }
}

std::optional<double> RadioPhaseSolver::ModelConstant(int tx, int rx) const {
  auto it = model_constant_.find({tx, rx});
  if (it == model_constant_.end()) return std::nullopt;
  return it->second;
}

// ---------------------------------------------------------------------------
// Tracking: EKF of the displacement with per-epoch integer cycle counts.
RadioPhaseSolver::TrackInfo RadioPhaseSolver::Track(int tx, double stamp,
                                                    const std::vector<Obs>& obs,
                                                    RadioEpochSummary* summary) {
  const int nr = static_cast<int>(network_.receivers.size());
  const double k = Wavenumber();
  const std::string& tx_id = network_.transmitters[tx].id;
  TrackInfo info(nr);
  TxState& s = tx_[tx];
  const double dt = std::max(0.0, stamp - s.last_stamp);
  s.last_stamp = std::max(s.last_stamp, stamp);
  s.p += options_.process_noise * dt * Eigen::Matrix3d::Identity();

  std::vector<int> idx;
  for (int rx = 0; rx < nr; ++rx)
    if (obs[rx].valid && links_[tx][rx].has_constant) idx.push_back(rx);
  auto predict = [&](int rx, Eigen::RowVector3d* h_row) {
    const Eigen::Vector3d dx = s.reference + s.d - network_.receivers[rx].position;
    const double r = dx.norm();
    if (h_row) *h_row = k * dx.transpose() / r;
    return k * r + links_[tx][rx].constant;
  };
  std::vector<int> used;
  std::vector<double> v_used;
  if (!idx.empty()) {
    const int m = static_cast<int>(idx.size());
    Eigen::MatrixXd h(m, 3);
    Eigen::VectorXd pred(m), phi(m), rvar(m);
    for (int i = 0; i < m; ++i) {
      Eigen::RowVector3d row;
      pred(i) = predict(idx[i], &row);
      h.row(i) = row;
      phi(i) = obs[idx[i]].phase;
      rvar(i) = obs[idx[i]].variance;
    }
    const Eigen::MatrixXd hph = h * s.p * h.transpose();
    const Eigen::MatrixXd qn = (hph + Eigen::MatrixXd(rvar.asDiagonal())) / (4.0 * M_PI * M_PI);
    const Eigen::VectorXd nf = (pred - phi) / (2.0 * M_PI);
    const FixResult fr = PartialFix(nf, qn, options_.ratio_threshold);
    info.ratio = fr.ratio;
    const int nfix = static_cast<int>(fr.fixed.size());
    info.state = nfix == m ? FixState::kFixed : (nfix > 0 ? FixState::kPartial : FixState::kFloat);
    std::vector<double> v(nfix);
    std::vector<int> cand;
    for (int i = 0; i < nfix; ++i) {
      const int li = fr.fixed[i];
      v[i] = phi(li) + 2.0 * M_PI * fr.integers(i) - pred(li);
      cand.push_back(li);
    }
    for (int i = 0; i < m; ++i)
      if (std::find(cand.begin(), cand.end(), i) == cand.end())
        info.status[idx[i]] = "cycle count not fixed";
    // Outlier: the worst normalised innovation above the threshold is rejected.
    std::vector<bool> reject(nfix, false);
    if (nfix >= 2) {
      int worst = -1;
      double worst_t = 0.0;
      for (int i = 0; i < nfix; ++i) {
        const int li = cand[i];
        const double t = std::abs(v[i]) / std::sqrt(hph(li, li) + rvar(li));
        if (t > worst_t) {
          worst_t = t;
          worst = i;
        }
      }
      if (worst >= 0 && worst_t > options_.outlier_sigma) {
        reject[worst] = true;
        const int rx = idx[cand[worst]];
        Link& l = links_[tx][rx];
        ++l.rejected_streak;
        info.status[rx] = Message("outlier (", worst_t, " sigma, streak ", l.rejected_streak, ")");
        summary->events.push_back(Message("link ", tx_id, "->", network_.receivers[rx].id,
                                          ": phase rejected, ", v[worst],
                                          " rad from the prediction (", worst_t, " sigma)"));
      }
    }
    for (int i = 0; i < nfix; ++i) {
      const int rx = idx[cand[i]];
      info.innovation[rx] = v[i];
      if (reject[i]) continue;
      links_[tx][rx].rejected_streak = 0;
      used.push_back(cand[i]);
      v_used.push_back(v[i]);
    }
    if (!used.empty()) {
      const int u = static_cast<int>(used.size());
      Eigen::MatrixXd hu(u, 3);
      Eigen::VectorXd vu(u), ru(u);
      for (int i = 0; i < u; ++i) {
        hu.row(i) = h.row(used[i]);
        vu(i) = v_used[i];
        ru(i) = rvar(used[i]);
        info.link_used[idx[used[i]]] = true;
      }
      const Eigen::MatrixXd sm = hu * s.p * hu.transpose() + Eigen::MatrixXd(ru.asDiagonal());
      const Eigen::MatrixXd gain = s.p * hu.transpose() * sm.inverse();
      s.d += gain * vu;
      const Eigen::Matrix3d ikh = Eigen::Matrix3d::Identity() - gain * hu;
      s.p = ikh * s.p * ikh.transpose() + gain * ru.asDiagonal() * gain.transpose();
      s.p = 0.5 * (s.p + s.p.transpose()).eval();
    }
  }
  info.used = static_cast<int>(used.size());
  if (s.p.trace() == 0.0 && used.empty()) s.p += 1e-12 * Eigen::Matrix3d::Identity();
  // Re-fix links rejected too often, and let links without a constant join,
  // when the displacement is known well enough.
  const double sigma_max = std::sqrt(s.p.eigenvalues().real().maxCoeff());
  for (int rx = 0; rx < nr; ++rx) {
    Link& l = links_[tx][rx];
    const bool refix = l.has_constant && l.rejected_streak >= options_.refix_after;
    const bool join = !l.has_constant && obs[rx].valid;
    if (!(refix || join) || !obs[rx].valid) continue;
    if (sigma_max > options_.max_refix_sigma || info.used < 2) continue;
    const double r = (s.reference + s.d - network_.receivers[rx].position).norm();
    l.constant = WrapPhase(obs[rx].phase - k * r);
    l.has_constant = true;
    l.rejected_streak = 0;
    ++l.refixes;
    info.status[rx] = refix ? "constant re-fixed" : "joined";
    summary->events.push_back(
        Message("link ", tx_id, "->", network_.receivers[rx].id,
                refix ? ": constant re-fixed after repeated rejections (multipath change or slip)"
                      : ": joined (constant fixed from the current estimate)"));
  }
  s.status = info.used >= 3 ? "ok" : Message("coasting: ", info.used, " link(s) in the update");
  return info;
}

// ---------------------------------------------------------------------------
EpochAssembler::EpochAssembler(std::vector<std::string> receiver_ids, double tolerance,
                               double max_wait)
    : receivers_(std::move(receiver_ids)), tolerance_(tolerance), max_wait_(max_wait) {}

std::vector<EpochAssembler::Epoch> EpochAssembler::Add(SampleBlock block) {
  const double t = block.stamp;
  auto it = std::find_if(pending_.begin(), pending_.end(),
                         [&](const Epoch& e) { return std::abs(e.stamp - t) <= tolerance_; });
  if (it == pending_.end()) {
    Epoch e;
    e.stamp = t;
    pending_.push_back(e);
    it = pending_.end() - 1;
  }
  auto& latest = latest_[block.receiver_id];
  latest = std::max(latest, t);
  it->blocks.push_back(std::move(block));
  std::vector<Epoch> done;
  std::vector<Epoch> keep;
  for (Epoch& e : pending_) {
    std::set<std::string> have;
    for (const auto& b : e.blocks) have.insert(b.receiver_id);
    // Complete, or every missing receiver has moved past it (it dropped its
    // block), or a silent receiver: overtaken by four newer epochs and older
    // than max_wait. Topics of different receivers interleave freely on a
    // fast replay, so one receiver's next block alone closes nothing.
    bool complete = true, passed = true;
    for (const auto& r : receivers_) {
      if (have.count(r)) continue;
      complete = false;
      auto l = latest_.find(r);
      passed = passed && l != latest_.end() && l->second > e.stamp + tolerance_;
    }
    int newer = 0;
    for (const Epoch& o : pending_) newer += o.stamp > e.stamp + tolerance_ ? 1 : 0;
    const bool silent = e.stamp < t - max_wait_ && newer >= 4;
    if (complete || passed || silent)
      done.push_back(std::move(e));
    else
      keep.push_back(std::move(e));
  }
  pending_ = std::move(keep);
  std::sort(done.begin(), done.end(),
            [](const Epoch& a, const Epoch& b) { return a.stamp < b.stamp; });
  return done;
}

std::vector<EpochAssembler::Epoch> EpochAssembler::Flush() {
  std::vector<Epoch> done = std::move(pending_);
  pending_.clear();
  std::sort(done.begin(), done.end(),
            [](const Epoch& a, const Epoch& b) { return a.stamp < b.stamp; });
  return done;
}

namespace {
constexpr char kSolverKind[] = "radio_phase_solver";
constexpr int kSolverVersion = 1;

std::string NetworkIds(const NetworkConfig& n) {
  std::string ids = "transmitters";
  for (const TransmitterConfig& t : n.transmitters) ids += " " + t.id;
  ids += ", receivers";
  for (const ReceiverConfig& r : n.receivers) ids += " " + r.id;
  return ids;
}
}  // namespace

std::string RadioPhaseSolver::Save() const {
  StateWriter w(kSolverKind, kSolverVersion);
  w.Put(NetworkIds(network_));
  for (const TxState& t : tx_) {
    w.Put(t.initialized).Put(static_cast<int>(t.fix_state)).Put(t.ratio).Put(t.reference);
    w.Put(t.reference_cov).Put(t.d).Put(t.p).Put(t.last_stamp).Put(t.status);
  }
  for (const auto& row : links_)
    for (const Link& l : row)
      w.Put(l.has_constant).Put(l.constant).Put(l.rejected_streak).Put(l.refixes);
  w.Put(static_cast<int>(init_buffer_.size()));
  for (size_t e = 0; e < init_buffer_.size(); ++e) {
    w.Put(init_stamps_.at(e));
    for (const auto& row : init_buffer_[e])
      for (const Obs& o : row)
        w.Put(o.valid).Put(o.phase).Put(o.variance).Put(o.snr).Put(o.problem);
  }
  for (const auto& s : last_sequence_)
    w.Put(s.has_value()).Put(static_cast<int64_t>(s.value_or(0)));
  const ReferenceSolution& r = reference_;
  w.Put(r.solved).Put(r.stamp).Put(r.num_ambiguities).Put(r.num_fixed).Put(r.ratio);
  w.Put(static_cast<int>(r.fix_state)).Put(static_cast<int>(r.excluded.size()));
  for (const std::string& x : r.excluded) w.Put(x);
  w.Put(static_cast<int>(r.mean_phase.size()));
  for (const auto& row : r.mean_phase) {
    w.Put(static_cast<int>(row.size()));
    for (double v : row) w.Put(v);
  }
  w.Put(static_cast<int>(model_constant_.size()));
  for (const auto& [link, v] : model_constant_) w.Put(link.first).Put(link.second).Put(v);
  return w.str();
}

void RadioPhaseSolver::Load(const std::string& text) {
  StateReader r(text, kSolverKind, kSolverVersion);
  const std::string ids = r.String();
  if (ids != NetworkIds(network_))
    throw InvalidArgument(Message("the saved radio state is of another network (", ids,
                                  "; this one: ", NetworkIds(network_), ")"));
  const size_t nt = network_.transmitters.size(), nr = network_.receivers.size();
  std::vector<TxState> tx(nt);
  for (TxState& t : tx) {
    t.initialized = r.Bool();
    t.fix_state = static_cast<FixState>(r.Int());
    t.ratio = r.Double();
    r.Get(&t.reference);
    r.Get(&t.reference_cov);
    r.Get(&t.d);
    r.Get(&t.p);
    t.last_stamp = r.Double();
    t.status = r.String();
  }
  std::vector<std::vector<Link>> links(nt, std::vector<Link>(nr));
  for (auto& row : links)
    for (Link& l : row) {
      l.has_constant = r.Bool();
      l.constant = r.Double();
      l.rejected_streak = r.Int();
      l.refixes = r.Int();
    }
  const int epochs = r.Int();
  std::vector<std::vector<std::vector<Obs>>> buffer;
  std::vector<double> stamps;
  for (int e = 0; e < epochs; ++e) {
    stamps.push_back(r.Double());
    buffer.emplace_back(nt, std::vector<Obs>(nr));
    for (auto& row : buffer.back())
      for (Obs& o : row) {
        o.valid = r.Bool();
        o.phase = r.Double();
        o.variance = r.Double();
        o.snr = r.Double();
        o.problem = r.String();
      }
  }
  std::vector<std::optional<std::uint32_t>> sequences(nr);
  for (auto& s : sequences) {
    const bool has = r.Bool();
    const int64_t v = r.Int64();
    if (has) s = static_cast<std::uint32_t>(v);
  }
  ReferenceSolution ref;
  ref.solved = r.Bool();
  ref.stamp = r.Double();
  ref.num_ambiguities = r.Int();
  ref.num_fixed = r.Int();
  ref.ratio = r.Double();
  ref.fix_state = static_cast<FixState>(r.Int());
  for (int n = r.Int(), i = 0; i < n; ++i) ref.excluded.push_back(r.String());
  for (int n = r.Int(), i = 0; i < n; ++i) {
    ref.mean_phase.emplace_back();
    for (int m = r.Int(), j = 0; j < m; ++j) ref.mean_phase.back().push_back(r.Double());
  }
  std::map<std::pair<int, int>, double> constants;
  for (int n = r.Int(), i = 0; i < n; ++i) {
    const int a = r.Int(), b = r.Int();
    constants[{a, b}] = r.Double();
  }
  tx_ = std::move(tx);
  links_ = std::move(links);
  init_buffer_ = std::move(buffer);
  init_stamps_ = std::move(stamps);
  last_sequence_ = std::move(sequences);
  reference_ = std::move(ref);
  model_constant_ = std::move(constants);
}

namespace {
constexpr char kPhasesKind[] = "radio_phases";
constexpr int kPhasesVersion = 1;
}  // namespace

std::string RadioPhaseSolver::LastPhases() const {
  StateWriter w(kPhasesKind, kPhasesVersion);
  w.Put(NetworkIds(network_)).Put(last_phases_.stamp);
  w.Put(static_cast<int>(last_phases_.obs.size()));
  for (const auto& row : last_phases_.obs) {
    w.Put(static_cast<int>(row.size()));
    for (const Obs& o : row) w.Put(o.valid).Put(o.phase).Put(o.variance).Put(o.snr).Put(o.problem);
  }
  return w.str();
}

RadioPhaseSolver::EpochPhases RadioPhaseSolver::LoadPhases(const std::string& text) const {
  StateReader r(text, kPhasesKind, kPhasesVersion);
  const std::string ids = r.String();
  if (ids != NetworkIds(network_))
    throw InvalidArgument(Message("saved radio phases are of another network (", ids,
                                  "; this one: ", NetworkIds(network_), ")"));
  EpochPhases p;
  p.stamp = r.Double();
  const int nt = r.Int();
  if (nt != static_cast<int>(network_.transmitters.size()))
    throw InvalidArgument("saved radio phases: wrong number of transmitters");
  for (int tx = 0; tx < nt; ++tx) {
    p.obs.emplace_back(static_cast<size_t>(r.Int()));
    if (p.obs.back().size() != network_.receivers.size())
      throw InvalidArgument("saved radio phases: wrong number of receivers");
    for (Obs& o : p.obs.back()) {
      o.valid = r.Bool();
      o.phase = r.Double();
      o.variance = r.Double();
      o.snr = r.Double();
      o.problem = r.String();
    }
  }
  return p;
}

}  // namespace radio
}  // namespace slope_monitor
