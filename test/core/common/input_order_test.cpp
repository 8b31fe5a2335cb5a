// InputOrder: batches of two inputs released in one stamp
// order whatever order they arrive in; hand-made sequences.
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/input_order.h"

namespace slope_monitor {
namespace {

const char kAdjuster[] = "/bundle_adjuster/displacements";
const char kRadio[] = "/radio/radio_displacements";

// "<input initial><stamp>" of each released batch, e.g. "r10".
std::vector<std::string> Names(const std::vector<InputOrder<std::string>::Released>& released) {
  std::vector<std::string> out;
  for (const auto& r : released) out.push_back(r.item);
  return out;
}

void Append(std::vector<std::string>* all, const std::vector<std::string>& more) {
  all->insert(all->end(), more.begin(), more.end());
}

// Feeds (input, stamp) pairs in the given arrival order, then flushes.
std::vector<std::string> Feed(const std::vector<std::pair<std::string, double>>& arrivals) {
  InputOrder<std::string> order({kAdjuster, kRadio});
  std::vector<std::string> out;
  for (const auto& [input, stamp] : arrivals) {
    const std::string name = (input == kAdjuster ? "a" : "r") + std::to_string(int(stamp));
    Append(&out, Names(order.Add(input, stamp, name, 0.0)));
  }
  Append(&out, Names(order.Flush()));
  EXPECT_EQ(order.pending(), 0u);
  return out;
}

TEST(InputOrder, RadioAheadOfTheAdjusterWaitsForIt) {
  InputOrder<std::string> order({kAdjuster, kRadio});
  // The radio epochs at 10, 20, 30 s come before the adjuster's epoch at 15 s
  // (its solve took longer than the bag clock's next blocks).
  EXPECT_TRUE(order.Add(kRadio, 10, "r10", 0).empty());
  EXPECT_TRUE(order.Add(kRadio, 20, "r20", 0).empty());
  EXPECT_TRUE(order.Add(kRadio, 30, "r30", 0).empty());
  EXPECT_EQ(Names(order.Add(kAdjuster, 15, "a15", 0)), (std::vector<std::string>{"r10", "a15"}));
  // The next adjuster epoch (35 s) lets the radio up to 30 s through; it waits for radio past 35.
  EXPECT_EQ(Names(order.Add(kAdjuster, 35, "a35", 0)), (std::vector<std::string>{"r20", "r30"}));
  EXPECT_EQ(order.pending(), 1u);
  EXPECT_EQ(Names(order.Add(kRadio, 40, "r40", 0)), (std::vector<std::string>{"a35"}));
  EXPECT_EQ(Names(order.Flush()), (std::vector<std::string>{"r40"}));
}

TEST(InputOrder, TheSameSequenceWhateverTheInterleaving) {
  // One graph run where the adjuster is fast, one where it lags three radio blocks.
  const std::vector<std::string> fast = Feed({{kRadio, 0},
                                              {kAdjuster, 0},
                                              {kRadio, 15},
                                              {kRadio, 30},
                                              {kRadio, 45},
                                              {kRadio, 60},
                                              {kRadio, 75},
                                              {kRadio, 90},
                                              {kAdjuster, 90},
                                              {kRadio, 105},
                                              {kRadio, 120}});
  const std::vector<std::string> slow = Feed({{kRadio, 0},
                                              {kRadio, 15},
                                              {kRadio, 30},
                                              {kRadio, 45},
                                              {kAdjuster, 0},
                                              {kRadio, 60},
                                              {kRadio, 75},
                                              {kRadio, 90},
                                              {kRadio, 105},
                                              {kRadio, 120},
                                              {kAdjuster, 90}});
  const std::vector<std::string> expected = {"a0",  "r0",  "r15", "r30",  "r45", "r60",
                                             "r75", "a90", "r90", "r105", "r120"};
  EXPECT_EQ(fast, expected);  // equal stamps: the inputs' order (adjuster first)
  EXPECT_EQ(slow, expected);
}

TEST(InputOrder, ExpireReleasesForASilentInputAndNamesIt) {
  InputOrder<std::string> order({kAdjuster, kRadio});
  EXPECT_TRUE(order.Add(kRadio, 10, "r10", 100.0).empty());
  EXPECT_TRUE(order.Add(kRadio, 20, "r20", 130.0).empty());
  std::vector<std::string> given_up;
  EXPECT_TRUE(order.Expire(150.0, 60.0, &given_up).empty());  // waited 50 s and 20 s
  EXPECT_TRUE(given_up.empty());
  EXPECT_EQ(Names(order.Expire(161.0, 60.0, &given_up)), (std::vector<std::string>{"r10"}));
  EXPECT_EQ(given_up, (std::vector<std::string>{kAdjuster}));
  EXPECT_EQ(order.pending(), 1u);
}

TEST(InputOrder, BadInputsAreNamed) {
  EXPECT_THROW(InputOrder<int>({}), InvalidArgument);
  try {
    InputOrder<int>({kRadio, kRadio});
    FAIL() << "a repeated input was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(kRadio), std::string::npos) << e.what();
  }
  InputOrder<int> order({kAdjuster});
  try {
    order.Add("/elsewhere", 1.0, 1, 0.0);
    FAIL() << "an unknown input was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'/elsewhere'"), std::string::npos) << e.what();
  }
  // A single input: released at once.
  EXPECT_EQ(order.Add(kAdjuster, 1.0, 7, 0.0).size(), 1u);
}

}  // namespace
}  // namespace slope_monitor
