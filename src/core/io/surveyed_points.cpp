#include "slope_monitor/core/io/surveyed_points.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

// The whole token as a double; false when any character is left over.
bool ParseNumber(const std::string& token, double* value) {
  if (token.empty()) return false;
  const char* begin = token.c_str();
  char* end = nullptr;
  errno = 0;
  *value = std::strtod(begin, &end);
  return end == begin + token.size() && errno != ERANGE;
}

}  // namespace

std::vector<PickedPoint> ParseSurveyedPoints(const std::string& text, const std::string& name,
                                             PixelOrigin origin) {
  static const char* kColumns[5] = {"X", "Y", "Z", "u", "v"};
  std::vector<PickedPoint> points;
  std::istringstream in(text);
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const size_t comment = line.find_first_of("%#");
    if (comment != std::string::npos) line.resize(comment);
    std::istringstream fields(line);
    std::vector<std::string> tokens;
    for (std::string t; fields >> t;) tokens.push_back(t);
    if (tokens.empty()) continue;
    auto where = [&]() { return Message(name, ":", number, ": "); };
    PickedPoint p;
    p.line = number;
    double first;
    size_t k = 0;
    if (!ParseNumber(tokens[0], &first) &&
        !std::isdigit(static_cast<unsigned char>(tokens[0][0])) && tokens[0][0] != '-' &&
        tokens[0][0] != '+' && tokens[0][0] != '.') {
      p.id = tokens[0];
      k = 1;
    } else {
      p.id = Message("#", number);
    }
    const size_t columns = tokens.size() - k;
    if (columns < 5) {
      throw InvalidArgument(Message(where(), "too few columns: ", columns,
                                    " numbers, need 5 (X Y Z u v)",
                                    k ? Message(" after the id '", p.id, "'") : std::string()));
    }
    if (columns > 5) {
      throw InvalidArgument(
          Message(where(), "too many columns: ", columns, " numbers, need 5 (X Y Z u v)"));
    }
    double v[5];
    for (int c = 0; c < 5; ++c) {
      const std::string& t = tokens[k + c];
      if (!ParseNumber(t, &v[c])) {
        throw InvalidArgument(
            Message(where(), "malformed number '", t, "' in column ", kColumns[c]));
      }
      if (!std::isfinite(v[c])) {
        throw InvalidArgument(
            Message(where(), "non-finite value '", t, "' in column ", kColumns[c]));
      }
    }
    const double shift = origin == PixelOrigin::kCorner ? -0.5 : 0.0;
    p.xyz = Eigen::Vector3d(v[0], v[1], v[2]);
    p.pixel = Eigen::Vector2d(v[3] + shift, v[4] + shift);
    points.push_back(p);
  }
  return points;
}

std::vector<PickedPoint> ReadSurveyedPoints(const std::string& path, PixelOrigin origin) {
  std::ifstream in(path);
  if (!in) throw IoError(Message("cannot read point file '", path, "'"));
  std::stringstream text;
  text << in.rdbuf();
  return ParseSurveyedPoints(text.str(), path, origin);
}

}  // namespace io
}  // namespace slope_monitor
