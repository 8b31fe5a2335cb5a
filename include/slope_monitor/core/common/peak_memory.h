// The process's peak resident memory so far (getrusage's ru_maxrss, which
// Linux gives in KiB), for the summaries that report it.
#pragma once

#include <sys/resource.h>

namespace slope_monitor {

// [GiB]; 0 when the kernel does not say.
inline double PeakResidentGb() {
  struct rusage u {};
  if (getrusage(RUSAGE_SELF, &u) != 0) return 0.0;
  return static_cast<double>(u.ru_maxrss) / (1024.0 * 1024.0);
}

}  // namespace slope_monitor
