// BAL reader against a header that lies (issue 22): a 28-byte file claiming
// huge counts is refused with a message naming the file before anything is
// allocated; the smallest honest file still loads.
#include <unistd.h>

#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/adjustment/bal.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {
namespace {

std::string Write(const std::string& name, const std::string& content) {
  const std::string path = "/tmp/sm_bal_counts_" + std::to_string(getpid()) + "_" + name;
  std::ofstream(path, std::ios::binary) << content;
  return path;
}

TEST(BalDeclaredCounts, HugeCountsInATinyFileAreRefused) {
  const std::string content = "2000000000 2000000000 2000000";
  ASSERT_EQ(content.size(), 29u);
  const std::string path = Write("huge.bal", content.substr(0, 28));  // 28 bytes
  try {
    BalProblem::Load(path);
    FAIL() << "no exception";
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find("bytes"), std::string::npos) << what;
  }
  std::remove(path.c_str());
}

TEST(BalDeclaredCounts, SmallestHonestFileLoads) {
  // 1 camera, 1 point, 1 observation: 4 + 9 + 3 one-digit numbers, no final newline.
  const std::string path = Write("min.bal", "1 1 1\n0 0 1 2\n1 0 0 0 0 0 1 0 0\n4 5 6");
  const BalProblem p = BalProblem::Load(path);
  ASSERT_EQ(p.observations.size(), 1u);
  EXPECT_EQ(p.observations[0].y, 2.0);
  EXPECT_EQ(p.cameras[0][0], 1.0);
  EXPECT_EQ(p.points[0][2], 6.0);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
