// Deterministic mutation fuzz of the BAL reader (issue 22): 2000 mutated
// copies of a small real BAL problem (test/data/bal/dubrovnik-1-1-pre.txt,
// fixed seed). Every input loads or throws slope_monitor::Error naming the
// file; std::bad_alloc (a header claiming huge counts), any other
// exception, a crash or a hang fails the test.
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "../../fuzz/mutator.h"
#include "slope_monitor/core/adjustment/bal.h"
#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace adjustment {
namespace {

TEST(BalFuzz, LoadsOrThrowsError) {
  std::ifstream in(std::string(SM_TEST_DATA_DIR) + "/bal/dubrovnik-1-1-pre.txt");
  std::stringstream seed;
  seed << in.rdbuf();
  ASSERT_GT(seed.str().size(), 50u);
  const std::string path = "/tmp/sm_bal_fuzz_" + std::to_string(getpid()) + ".txt";
  fuzz::Mutator m(fuzz::Seed());
  const int n = fuzz::Iterations(2000);
  int loaded = 0, refused = 0;
  for (int i = 0; i < n; ++i) {
    const std::string input = m.Mutate(seed.str());
    std::ofstream(path, std::ios::binary | std::ios::trunc) << input;
    try {
      BalProblem::Load(path);
      ++loaded;
    } catch (const Error& e) {
      ++refused;
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos)
          << "input " << i << ": " << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "input " << i << " escaped as " << typeid(e).name() << ": " << e.what()
                    << "\n"
                    << input.substr(0, 200);
    }
  }
  std::remove(path.c_str());
  EXPECT_GT(loaded, n / 100);
  EXPECT_GT(refused, n / 10);
}

}  // namespace
}  // namespace adjustment
}  // namespace slope_monitor
