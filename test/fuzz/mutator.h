// Deterministic input mutation for the fuzz tests (issue 22): from a valid
// seed text, each call applies 1..4 random edits (flip a byte, insert or
// delete a run, duplicate a chunk, replace a number by an extreme one, cut
// the tail). Same seed, same inputs: a failure is reproducible by its index.
#pragma once

#include <cstdlib>
#include <random>
#include <string>
#include <vector>

namespace slope_monitor {
namespace fuzz {

// The suite runs the defaults; scripts/fuzz_long sets SM_FUZZ_ITERATIONS and
// SM_FUZZ_SEED for deeper runs.
inline int Iterations(int suite_default) {
  const char* v = std::getenv("SM_FUZZ_ITERATIONS");
  return v ? std::atoi(v) : suite_default;
}
inline unsigned Seed() {
  const char* v = std::getenv("SM_FUZZ_SEED");
  return v ? static_cast<unsigned>(std::strtoul(v, nullptr, 10)) : 22u;
}

class Mutator {
 public:
  explicit Mutator(unsigned seed) : rng_(seed) {}

  std::string Mutate(const std::string& seed_text) {
    std::string s = seed_text;
    const int edits = 1 + static_cast<int>(Below(4));
    for (int e = 0; e < edits; ++e) Edit(&s);
    return s;
  }

 private:
  size_t Below(size_t n) {
    return n == 0 ? 0 : std::uniform_int_distribution<size_t>(0, n - 1)(rng_);
  }

  void Edit(std::string* s) {
    static const std::vector<std::string> kExtremes = {"1e300",
                                                       "-1e300",
                                                       "1e-300",
                                                       "nan",
                                                       "inf",
                                                       "-inf",
                                                       "4294967295",
                                                       "-1",
                                                       "2147483648",
                                                       "-2147483649",
                                                       "99999999999999999999",
                                                       "0",
                                                       "-0",
                                                       "0x7fffffff",
                                                       "\"\"",
                                                       "[]",
                                                       "{}",
                                                       "~",
                                                       "\n",
                                                       ":",
                                                       "- ",
                                                       "[[[[",
                                                       "'"};
    const size_t pos = Below(s->size() + 1);
    switch (Below(7)) {
      case 0:  // flip a byte
        if (!s->empty()) (*s)[Below(s->size())] = static_cast<char>(Below(256));
        break;
      case 1:  // insert random bytes
        for (size_t k = 0, n = 1 + Below(8); k < n; ++k)
          s->insert(s->begin() + pos, static_cast<char>(Below(256)));
        break;
      case 2:  // delete a run
        s->erase(pos, 1 + Below(16));
        break;
      case 3: {  // duplicate a chunk
        const size_t from = Below(s->size() + 1);
        s->insert(pos, s->substr(from, 1 + Below(64)));
        break;
      }
      case 4: {  // replace a number with an extreme value
        const size_t start = s->find_first_of("0123456789", pos);
        if (start == std::string::npos) break;
        const size_t end = s->find_first_not_of("0123456789.e-", start);
        s->replace(start, (end == std::string::npos ? s->size() : end) - start,
                   kExtremes[Below(kExtremes.size())]);
        break;
      }
      case 5:  // insert an extreme token
        s->insert(pos, kExtremes[Below(kExtremes.size())]);
        break;
      default:  // cut the tail
        s->resize(pos);
    }
  }

  std::mt19937 rng_;
};

}  // namespace fuzz
}  // namespace slope_monitor
