#include "slope_monitor/core/common/state_text.h"

#include <cstdio>
#include <cstdlib>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {

StateWriter::StateWriter(const std::string& kind, int version) {
  Put(kind);
  Put(version);
}

StateWriter& StateWriter::Put(double v) {
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "d%a ", v);
  out_ << buffer;
  return *this;
}

StateWriter& StateWriter::Put(int64_t v) {
  out_ << 'i' << v << ' ';
  return *this;
}

StateWriter& StateWriter::Put(const std::string& v) {
  out_ << 's' << v.size() << ':' << v << ' ';
  return *this;
}

StateReader::StateReader(const std::string& text, const std::string& kind, int version)
    : text_(text), kind_(kind) {
  std::string k;
  int64_t v = -1;
  try {
    k = String();
    v = Int64();
  } catch (const InvalidArgument&) {
  }
  if (k != kind || v != version)
    throw InvalidArgument(Message("saved state is not a '", kind, "' state of version ", version,
                                  " (found '", k, "' version ", v, ")"));
}

std::string StateReader::Token(char type) {
  if (pos_ >= text_.size() || text_[pos_] != type)
    throw InvalidArgument(Message("saved '", kind_, "' state: expected a value of type '", type,
                                  "' at character ", pos_));
  const size_t end = text_.find(' ', pos_);
  if (end == std::string::npos)
    throw InvalidArgument(Message("saved '", kind_, "' state ends at character ", pos_));
  std::string token = text_.substr(pos_ + 1, end - pos_ - 1);
  pos_ = end + 1;
  return token;
}

double StateReader::Double() {
  const std::string t = Token('d');
  char* end = nullptr;
  const double v = std::strtod(t.c_str(), &end);
  if (t.empty() || *end != '\0')
    throw InvalidArgument(Message("saved '", kind_, "' state: '", t, "' is not a number"));
  return v;
}

int64_t StateReader::Int64() {
  const std::string t = Token('i');
  char* end = nullptr;
  const long long v = std::strtoll(t.c_str(), &end, 10);
  if (t.empty() || *end != '\0')
    throw InvalidArgument(Message("saved '", kind_, "' state: '", t, "' is not an integer"));
  return v;
}

std::string StateReader::String() {
  if (pos_ >= text_.size() || text_[pos_] != 's')
    throw InvalidArgument(
        Message("saved '", kind_, "' state: expected a string at character ", pos_));
  const size_t colon = text_.find(':', pos_);
  if (colon == std::string::npos)
    throw InvalidArgument(Message("saved '", kind_, "' state ends at character ", pos_));
  const size_t n = std::strtoull(text_.substr(pos_ + 1, colon - pos_ - 1).c_str(), nullptr, 10);
  if (colon + 1 + n + 1 > text_.size())
    throw InvalidArgument(Message("saved '", kind_, "' state ends inside a string"));
  std::string v = text_.substr(colon + 1, n);
  pos_ = colon + 1 + n + 1;
  return v;
}

}  // namespace slope_monitor
