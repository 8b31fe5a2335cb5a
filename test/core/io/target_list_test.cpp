#include "slope_monitor/core/io/target_list.h"

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

std::string ErrorOf(const std::string& yaml) {
  try {
    TargetList::FromYaml(yaml, "test.yaml");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(TargetList, ParsesAndRoundTrips) {
  const TargetList list = TargetList::FromYaml(
      "frame: site\n"
      "targets:\n"
      "  - {id: 3, family: tag36h11, size: 0.6, role: control, position: [1, 2, 3], sigma: [0.03, "
      "0.01]}\n"
      "  - {id: 3, family: circle, size: 0.2, role: monitoring}\n",
      "test.yaml");
  ASSERT_EQ(list.targets().size(), 2u);
  const TargetSpec* t = list.Find("tag36h11", 3);
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->role, TargetRole::kControl);
  EXPECT_DOUBLE_EQ(t->position->z(), 3.0);
  EXPECT_DOUBLE_EQ(t->sigma.x(), 0.03);
  EXPECT_FALSE(list.Find("circle", 3)->position.has_value());
  const TargetList back = TargetList::FromYaml(list.ToYaml(), "roundtrip");
  EXPECT_EQ(back.targets().size(), 2u);
  EXPECT_DOUBLE_EQ(back.Find("tag36h11", 3)->position->y(), 2.0);
}

TEST(TargetList, BadInputNamesTheKey) {
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 0.5}\n  - {id: 1, size: 0.5}\n")
                .find("duplicates target tag36h11/1"),
            std::string::npos);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 0.5, role: control}\n").find("'position'"),
            std::string::npos);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 0.5, colour: red}\n").find("unknown key 'colour'"),
            std::string::npos);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: -2}\n").find("'size'"), std::string::npos);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 1, family: tag99}\n").find("tag99"),
            std::string::npos);
}

TEST(TargetList, RingMarkerRadiiAreReadOverTheOuterAndChecked) {
  const TargetList list = TargetList::FromYaml(
      "targets:\n  - {id: 5, family: circle, size: 0.2, rings: [45, 55, 65, 78, 88, 100]}\n",
      "test.yaml");
  const std::vector<double> want{0.45, 0.55, 0.65, 0.78, 0.88, 1.0};
  ASSERT_EQ(list.Find("circle", 5)->rings.size(), want.size());
  for (size_t k = 0; k < want.size(); ++k)
    EXPECT_DOUBLE_EQ(list.Find("circle", 5)->rings[k], want[k]);
  const TargetList back = TargetList::FromYaml(list.ToYaml(), "roundtrip");
  EXPECT_DOUBLE_EQ(back.Find("circle", 5)->rings[1], 0.55);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 1, rings: [1, 2, 3, 4, 5, 6]}\n")
                .find("only circles have rings"),
            std::string::npos);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 1, family: circle, rings: [1, 2, 3, 4]}\n")
                .find("three rings at least"),
            std::string::npos);
  EXPECT_NE(ErrorOf("targets:\n  - {id: 1, size: 1, family: circle, rings: [1, 3, 2, 4, 5, 6]}\n")
                .find("must be positive and increase"),
            std::string::npos);
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
