// The notification hook: run once per alert-level change with that change's
// JSON on stdin; failures retried a bounded number of times; a hung hook
// killed at its time limit.
#include "slope_monitor/core/deformation/alert_hook.h"

#include <sys/stat.h>
#include <unistd.h>

#include <fstream>
#include <map>
#include <sstream>

#include <gtest/gtest.h>

#include "hook_json.h"
#include "slope_monitor/core/common/error.h"
#include "test_scenario.h"

namespace slope_monitor {
namespace deformation {
namespace {

using testing::kDay;
using testing::kMmPerDay;
using testing::kT0;

struct HookTempDir {
  HookTempDir() {
    char tmpl[] = "/tmp/alert_hook_test_XXXXXX";
    path = mkdtemp(tmpl);
  }
  ~HookTempDir() { std::system(("rm -rf '" + path + "'").c_str()); }
  std::string path;
};

std::string WriteScript(const std::string& path, const std::string& body) {
  std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
  chmod(path.c_str(), 0755);
  return path;
}

using hook_json::Field;
using hook_json::Lines;

// Three points on a body accelerating to failure (v0 = 6 mm/day, tf = t0 +
// 6 d: 36 mm/day at 5 d, 144 mm/day at 5.75 d) and three on stable ground;
// radio every 30 min, 4 mm noise; the estimator with its default options.
TEST(AlertHook, RunsOncePerLevelChangeWithThatChangesJson) {
  HookTempDir dir;
  const std::string out = dir.path + "/alerts.jsonl";
  io::NotificationOptions options;
  options.hook = WriteScript(dir.path + "/hook", "cat >> '" + out + "'\necho >> '" + out + "'");
  AlertHook hook(options, [&](bool error, const std::string& m) {
    if (error) ADD_FAILURE() << m;
  });

  const std::vector<std::string> ids = {"body1", "body2", "body3", "stable1", "stable2", "stable3"};
  std::vector<testing::Motion> motions(6);
  for (int i = 0; i < 3; ++i) {
    motions[i].v0 = 6 * kMmPerDay;
    motions[i].accelerating = true;
    motions[i].failure_time = kT0 + 6 * kDay;
  }
  testing::SourceSpec radio;
  radio.sigma = Eigen::Vector3d(0.004, 0.004, 0.004);
  radio.seed = 21;
  Estimator est{EstimatorOptions()};
  AlertChangeTracker tracker;
  std::vector<std::string> expected;
  std::map<std::string, AlertLevel> final_level;
  for (const Batch& b : testing::MakeBatches(radio, ids, motions, kT0 + 5.75 * kDay)) {
    est.AddBatch(b);
    const Snapshot s = est.GetSnapshot();
    for (const AlertChange& c : tracker.Update(s)) {
      for (const PointState& p : s.points) {
        if (p.id != c.point_id) continue;
        expected.push_back(AlertJson("test", p, c));
        hook.Notify(expected.back());
      }
      final_level[c.point_id] = c.to;
    }
  }
  hook.Flush();
  const std::vector<std::string> got = Lines(out);
  ASSERT_EQ(got.size(), expected.size());
  // Each body point rises to alarm (truth 144 mm/day at the end, > 50);
  // stable ground never changes level.
  ASSERT_GE(expected.size(), 3u);
  for (size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k], expected[k]);
    EXPECT_EQ(Field(got[k], "site"), "test");
    EXPECT_EQ(Field(got[k], "point").rfind("body", 0), 0u) << got[k];
    EXPECT_NE(Field(got[k], "from"), Field(got[k], "level"));
  }
  for (const std::string& id : {"body1", "body2", "body3"})
    EXPECT_EQ(final_level[id], AlertLevel::kAlarm) << id;
  // The last change of body1 carries its speed (above the alarm threshold) and a forecast.
  const std::string& last = got.back();
  EXPECT_EQ(Field(last, "level"), "alarm");
  EXPECT_GT(std::stod(Field(last, "speed_mm_per_day")), 50.0);
  const AlertHookSummary s = hook.summary();
  EXPECT_EQ(s.delivered, static_cast<int>(expected.size()));
  EXPECT_EQ(s.failures, 0);
}

TEST(AlertHook, AFailingHookIsRetriedThenGivenUp) {
  HookTempDir dir;
  // Fails on its first run (no marker yet), succeeds on the second.
  const std::string marker = dir.path + "/ran";
  io::NotificationOptions options;
  options.retries = 2;
  options.retry_delay = 0.0;
  options.hook =
      WriteScript(dir.path + "/flaky", "cat > /dev/null\nif [ -e '" + marker +
                                           "' ]; then exit 0; fi\ntouch '" + marker + "'\nexit 3");
  std::vector<std::string> errors;
  {
    AlertHook hook(options, [&](bool error, const std::string& m) {
      if (error) errors.push_back(m);
    });
    hook.Notify("{\"point\": \"p\"}");
    hook.Flush();
    const AlertHookSummary s = hook.summary();
    EXPECT_EQ(s.attempts, 2);
    EXPECT_EQ(s.delivered, 1);
    EXPECT_EQ(s.given_up, 0);
  }
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("exit status 3; retry 1 of 2"), std::string::npos) << errors[0];

  // Never succeeds: 1 + 2 attempts, then given up with the alert in the message.
  errors.clear();
  options.hook = WriteScript(dir.path + "/broken", "exit 1");
  AlertHook hook(options, [&](bool error, const std::string& m) {
    if (error) errors.push_back(m);
  });
  hook.Notify("{\"point\": \"q\"}");
  hook.Flush();
  EXPECT_EQ(hook.summary().attempts, 3);
  EXPECT_EQ(hook.summary().given_up, 1);
  ASSERT_EQ(errors.size(), 3u);
  EXPECT_NE(errors[2].find("given up after 3 attempt(s): {\"point\": \"q\"}"), std::string::npos)
      << errors[2];
}

TEST(AlertHook, AHungHookIsKilledAtItsTimeLimitAndAMissingOneIsReported) {
  HookTempDir dir;
  io::NotificationOptions options;
  options.timeout = 0.2;
  options.retries = 0;
  options.hook = WriteScript(dir.path + "/hang", "exec sleep 30");
  std::vector<std::string> errors;
  {
    AlertHook hook(options, [&](bool error, const std::string& m) {
      if (error) errors.push_back(m);
    });
    hook.Notify("{}");
    hook.Flush();
    EXPECT_EQ(hook.summary().given_up, 1);
  }
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("no exit within 0.2 s (killed)"), std::string::npos) << errors[0];

  options.hook = dir.path + "/does_not_exist";
  errors.clear();
  AlertHook hook(options, [&](bool error, const std::string& m) {
    if (error) errors.push_back(m);
  });
  hook.Notify("{}");
  hook.Flush();
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_NE(errors[0].find("does_not_exist' failed: cannot start it"), std::string::npos)
      << errors[0];
}

TEST(AlertHook, OptionsAreChecked) {
  io::NotificationOptions options;
  EXPECT_THROW(AlertHook(options, nullptr), InvalidArgument);  // no hook
  options.hook = "true";
  options.timeout = 0.0;
  EXPECT_THROW(AlertHook(options, nullptr), InvalidArgument);
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
