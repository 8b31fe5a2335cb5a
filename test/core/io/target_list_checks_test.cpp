// Target lists that the reader accepted without a word (issue 22): absurd
// coordinates or sigmas, two targets at one position, no `targets:` key.
// Each is refused naming the file, the key and the target.
#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace io {
namespace {

std::string ChecksErrorOf(const std::string& yaml) {
  try {
    TargetList::FromYaml(yaml, "site.targets.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(TargetListChecks, AbsurdCoordinatesNamed) {
  const std::string e =
      ChecksErrorOf("targets:\n  - {id: 4, size: 0.5, role: control, position: [1e300, 2, 3]}\n");
  EXPECT_NE(e.find("site.targets.yaml"), std::string::npos) << e;
  EXPECT_NE(e.find("tag36h11/4"), std::string::npos) << e;
  EXPECT_NE(e.find("position"), std::string::npos) << e;
  // 100 km is the bound; 99 km is a (large) site.
  EXPECT_EQ(
      ChecksErrorOf("targets:\n  - {id: 4, size: 0.5, role: control, position: [99000, 2, 3]}\n"),
      "");
}

TEST(TargetListChecks, AbsurdSigmaNamed) {
  std::string e = ChecksErrorOf(
      "targets:\n  - {id: 5, size: 0.5, role: check, position: [1, 2, 3], sigma: [1e300, 0.01]}\n");
  EXPECT_NE(e.find("tag36h11/5"), std::string::npos) << e;
  EXPECT_NE(e.find("sigma"), std::string::npos) << e;
  e = ChecksErrorOf(
      "targets:\n  - {id: 5, size: 0.5, role: check, position: [1, 2, 3], sigma: [0.01, 1e-9]}\n");
  EXPECT_NE(e.find("tag36h11/5"), std::string::npos) << e;
  EXPECT_EQ(ChecksErrorOf("targets:\n  - {id: 5, size: 0.5, role: check, position: [1, 2, 3], "
                          "sigma: [0.002, 0.004]}\n"),
            "");
}

TEST(TargetListChecks, DuplicatePositionsNameBothTargets) {
  const std::string e = ChecksErrorOf(
      "targets:\n"
      "  - {id: 1, size: 0.5, role: control, position: [10, 20, 30]}\n"
      "  - {id: 2, size: 0.5, role: control, position: [40, 20, 30]}\n"
      "  - {id: 3, size: 0.5, role: control, position: [10, 20, 30]}\n");
  EXPECT_NE(e.find("tag36h11/1 and tag36h11/3 have the same position"), std::string::npos) << e;
}

TEST(TargetListChecks, MissingTargetsKey) {
  const std::string e = ChecksErrorOf("frame: site\n");
  EXPECT_NE(e.find("targets"), std::string::npos) << e;
  EXPECT_NE(e.find("is missing"), std::string::npos) << e;
  EXPECT_EQ(ChecksErrorOf("frame: site\ntargets: []\n"), "");
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
