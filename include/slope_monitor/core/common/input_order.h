// One stamp order for several inputs (topics), whatever order they arrive in.
//
// Messages of different topics reach a node in the order its transport
// delivers them, which on a fast replay or a busy machine is not the order
// of their stamps. Two uses:
//   * the deformation estimator's history (the observations' arrival order, the
// estimate published after each batch), its series samples and its alerts
// depend on the order in which batches reach it. In the graph that order is
// the order in which the inputs' solvers finish: the bundle adjuster's
// epoch at stamp t arrives after the radio epochs that followed t in bag
// time whenever its solve takes longer than the bag clock's next radio
// block (a fast replay, a busy machine). The result then depends on the CPU
// and on the replay rate.
//
// InputOrder holds every batch until every input has delivered one at or
// past its stamp (each input delivers its own batches in stamp order), then
// releases it: batches leave sorted by (stamp, input, arrival), which is the
// same sequence whenever the inputs' own messages are the same. It decides by
// the messages, never by a clock. `Expire` is for live sensors only: a batch
// that waited longer than a time-out for a silent input is released, and the
// inputs given up on are named. `Flush` releases everything (end of a replay).
//
//   InputOrder<Msg> order({"/bundle_adjuster/displacements", "/radio/radio_displacements"});
//   for (auto& r : order.Add(topic, stamp, msg, now)) Fuse(r.item, r.input);
//   for (auto& r : order.Expire(now, timeout, &given_up)) Fuse(r.item, r.input);
//   for (auto& r : order.Flush()) Fuse(r.item, r.input);  // end of input
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {

template <typename T>
class InputOrder {
 public:
  struct Released {
    std::string input;
    double stamp = 0.0;
    T item;
  };

  // `inputs`: the names of the inputs (e.g. topics); their order breaks ties
  // of equal stamps. Throws InvalidArgument for none or a repeated name.
  explicit InputOrder(std::vector<std::string> inputs) : inputs_(std::move(inputs)) {
    if (inputs_.empty()) throw InvalidArgument("InputOrder: no input");
    for (size_t i = 0; i < inputs_.size(); ++i) {
      if (!index_.emplace(inputs_[i], i).second)
        throw InvalidArgument(Message("InputOrder: input '", inputs_[i], "' named twice"));
    }
    newest_.assign(inputs_.size(), -std::numeric_limits<double>::infinity());
  }

  // A batch of `input` with `stamp` [s] arrived at `now` (any clock; only
  // Expire compares it). Returns the batches it releases, in order. Throws
  // InvalidArgument naming an unknown input.
  std::vector<Released> Add(const std::string& input, double stamp, T item, double now) {
    const auto it = index_.find(input);
    if (it == index_.end())
      throw InvalidArgument(Message("InputOrder: unknown input '", input, "'"));
    newest_[it->second] = std::max(newest_[it->second], stamp);
    pending_.emplace(Key{stamp, it->second, next_arrival_++}, Waiting{now, std::move(item)});
    return Release(Watermark());
  }

  // Batches that waited longer than `timeout` [s] (on Add's clock) for a
  // silent input, with everything before them. `given_up` receives the names
  // of the inputs that had not reached the newest released stamp.
  std::vector<Released> Expire(double now, double timeout, std::vector<std::string>* given_up) {
    double upto = -std::numeric_limits<double>::infinity();
    for (const auto& [key, w] : pending_)
      if (now - w.arrived > timeout) upto = std::max(upto, std::get<0>(key));
    if (upto == -std::numeric_limits<double>::infinity()) return {};
    for (size_t i = 0; i < inputs_.size(); ++i)
      if (newest_[i] < upto && given_up) given_up->push_back(inputs_[i]);
    return Release(upto);
  }

  // Everything pending, in order (the inputs have ended).
  std::vector<Released> Flush() { return Release(std::numeric_limits<double>::infinity()); }

  size_t pending() const { return pending_.size(); }
  const std::vector<std::string>& inputs() const { return inputs_; }

 private:
  using Key = std::tuple<double, size_t, uint64_t>;  // stamp, input index, arrival
  struct Waiting {
    double arrived = 0.0;
    T item;
  };

  // Every input has delivered up to this stamp.
  double Watermark() const { return *std::min_element(newest_.begin(), newest_.end()); }

  std::vector<Released> Release(double upto) {
    std::vector<Released> out;
    while (!pending_.empty() && std::get<0>(pending_.begin()->first) <= upto) {
      auto node = pending_.extract(pending_.begin());
      out.push_back(Released{inputs_[std::get<1>(node.key())], std::get<0>(node.key()),
                             std::move(node.mapped().item)});
    }
    return out;
  }

  std::vector<std::string> inputs_;
  std::map<std::string, size_t> index_;
  std::vector<double> newest_;  // per input: the newest stamp delivered
  std::map<Key, Waiting> pending_;
  uint64_t next_arrival_ = 0;
};

}  // namespace slope_monitor
