// Numbers and times as text, written the same way in every report, log line
// and file of the package.
#pragma once

#include <string>

namespace slope_monitor {

// `v` with `digits` decimals ("%.*f": 1.25 -> "1.250" at 3; nan -> "nan").
std::string Fixed(double v, int digits);

// A Unix time [s] as ISO 8601 UTC to the second ("2026-11-27T21:53:17Z");
// the fraction is dropped (floor), so 0.999 s before a second is that second.
std::string Utc(double unix_seconds);

// A CSV field in double quotes, a quote inside doubled (RFC 4180).
std::string CsvQuote(const std::string& s);

}  // namespace slope_monitor
