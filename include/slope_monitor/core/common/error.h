// Errors of the core library. The core throws these for bad input or states
// it cannot continue from; ROS callbacks catch them, log (throttled) and drop
// the message. Every message names what is wrong: the key, file, topic or value.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>

namespace slope_monitor {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A value (parameter, argument, image) that the callee cannot use.
class InvalidArgument : public Error {
 public:
  using Error::Error;
};

// A configuration key that is unknown, missing, of the wrong type or out of range.
class ConfigError : public Error {
 public:
  using Error::Error;
};

// A file that cannot be read or written, or whose content is malformed.
class IoError : public Error {
 public:
  using Error::Error;
};

// Builds a message from streamable parts: Message("key '", key, "' must be > 0").
template <typename... Args>
std::string Message(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}

// Throws ConfigError "<options> option '<key>' <what>" unless `ok`:
// RequireOption("rectify", x > 0, "scale", "must be > 0").
inline void RequireOption(const char* options, bool ok, const char* key, const std::string& what) {
  if (!ok) throw ConfigError(Message(options, " option '", key, "' ", what));
}

}  // namespace slope_monitor
