// The notification hook in process_bag (issue 18, must show): a level change
// on a survey bag runs the site's hook once per change with the right JSON.
// The survey (estimator_restart: a body moving 200 mm/day, cameras and radio)
// raises alerts in its first epochs and again when the circle targets appear;
// the changes expected are read from process_bag's own output bag (each
// point's alert level, message by message on /deformation_estimator/deformation),
// the hook's runs from the file it appends to.
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>

#include "../core/deformation/hook_json.h"
#include "process_bag_run.h"
#include "slope_monitor/SlopeDeformation.h"

namespace slope_monitor {
namespace {

using namespace process_bag_run;  // NOLINT: the test helpers
using hook_json::Field;
using hook_json::Lines;

std::vector<hook_json::LevelChange> ChangesInOutputBag(const fs::path& bag_path) {
  rosbag::Bag bag(bag_path.string(), rosbag::bagmode::Read);
  hook_json::LevelChanges changes;
  for (const rosbag::MessageInstance& m :
       rosbag::View(bag, rosbag::TopicQuery("/deformation_estimator/deformation")))
    if (const auto d = m.instantiate<slope_monitor::SlopeDeformation>()) changes.Add(*d);
  return changes.changes();
}

TEST(ProcessBagHook, OneHookRunPerLevelChangeWithItsJson) {
  const std::string name = "estimator_restart";
  const fs::path dir = Scratch("hook");
  const fs::path hook_out = dir / "hook_out.jsonl";
  ASSERT_EQ(setenv("HOOK_OUT", hook_out.c_str(), 1), 0);  // read by the hook script
  std::vector<std::string> args = ProcessBagArgs(name, dir);
  args.insert(args.end(),
              {"--site", std::string(SM_SOURCE_DIR) + "/test/replay/process_bag_hook.site.yaml",
               "--output-bag", (dir / "out.bag").string()});
  const int status = Wait(Spawn(args, dir));
  ASSERT_EQ(status, 0) << ReadFile(dir / "stderr");

  const std::vector<hook_json::LevelChange> expected = ChangesInOutputBag(dir / "out.bag");
  ASSERT_GE(expected.size(), 2u) << "the survey raised no alerts: nothing to check";
  const std::vector<std::string> got = Lines(hook_out.string());
  ASSERT_EQ(got.size(), expected.size()) << ReadFile(dir / "stderr");
  for (size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(Field(got[k], "site"), "process_bag_hook") << got[k];
    EXPECT_EQ(Field(got[k], "point"), expected[k].point) << got[k];
    EXPECT_EQ(Field(got[k], "from"), expected[k].from) << got[k];
    EXPECT_EQ(Field(got[k], "level"), expected[k].to) << got[k];
    EXPECT_NEAR(std::stod(Field(got[k], "speed_mm_per_day")), expected[k].speed_mm_per_day, 1e-2)
        << got[k];
  }
  // Each change is also on stderr, as the node logs it.
  const std::string err = ReadFile(dir / "stderr");
  for (const hook_json::LevelChange& c : expected)
    EXPECT_NE(err.find("point " + c.point + ": alert " + c.from + " -> " + c.to), std::string::npos)
        << c.point;
}

}  // namespace
}  // namespace slope_monitor
