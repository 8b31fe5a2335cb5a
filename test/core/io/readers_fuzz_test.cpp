// Deterministic mutation fuzz of the target-list reader (issue 22): 3000
// mutated copies of a valid list (fixed seed). Every input either loads or
// throws slope_monitor::Error (a message naming the file); any other
// exception, a crash or a hang fails the test. The seed list must load.
#include <gtest/gtest.h>

#include "../../fuzz/mutator.h"
#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/target_list.h"

namespace slope_monitor {
namespace io {
namespace {

const char* kSeedList =
    "# fuzz seed\n"
    "frame: site\n"
    "targets:\n"
    "  - {id: 1, family: tag36h11, size: 0.6, role: control, position: [10.5, 20.25, 301.0], "
    "sigma: [0.01, 0.02]}\n"
    "  - {id: 2, family: tag36h11, size: 0.6, role: check, position: [40.0, -12.0, 310.5]}\n"
    "  - id: 7\n"
    "    family: circle\n"
    "    size: 0.2\n"
    "    role: monitoring\n"
    "    position: [25.0, 5.0, 305.0]\n"
    "    normal: [0, 0.5, 0.8]\n";

TEST(ReadersFuzz, TargetListLoadsOrThrowsError) {
  ASSERT_EQ(TargetList::FromYaml(kSeedList, "seed").targets().size(), 3u);
  fuzz::Mutator m(fuzz::Seed());
  const int n = fuzz::Iterations(3000);
  int loaded = 0, refused = 0;
  for (int i = 0; i < n; ++i) {
    const std::string input = m.Mutate(kSeedList);
    try {
      TargetList::FromYaml(input, "fuzz.yaml");
      ++loaded;
    } catch (const Error& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find("fuzz.yaml"), std::string::npos)
          << "input " << i << ": " << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "input " << i << " escaped as " << typeid(e).name() << ": " << e.what()
                    << "\n"
                    << input;
    }
  }
  // Both outcomes occur: the mutations reach past the parser into the checks.
  EXPECT_GT(loaded, n / 60);
  EXPECT_GT(refused, n / 6);
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
