// Surveyed points picked in one photo: the point file of resect_camera.
//
// One point per line, `X Y Z u v` (site or projected-CRS coordinates [m],
// pixel column and row), with an optional id first when the first field is
// not a number. `%` and `#` start a comment (to the end of the line); blank
// lines are skipped. Pixels follow OpenCV's convention ((0, 0) is the centre
// of the top-left pixel) unless the file uses the corner convention ((0, 0) is
// the top-left corner of the image), which is shifted by -0.5 px on reading.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace slope_monitor {
namespace io {

// A surveyed point and where it was picked in one photo (a ground control
// point of a resection). Targets of a site's list are io::SurveyedPoint
// (target_csv.h).
struct PickedPoint {
  std::string id;         // the file's id, or "#<line>" when the line has none
  Eigen::Vector3d xyz;    // [m]
  Eigen::Vector2d pixel;  // [px], OpenCV convention
  int line = 0;           // line number in the file (1-based)
};

enum class PixelOrigin { kOpenCv, kCorner };

// Throws InvalidArgument naming the file, the line number and what is wrong
// (a malformed number such as "1951+9", too few or too many columns, a
// non-finite value); IoError when the file cannot be read.
std::vector<PickedPoint> ReadSurveyedPoints(const std::string& path, PixelOrigin origin);
// The same from text already read (`name` is used in the messages).
std::vector<PickedPoint> ParseSurveyedPoints(const std::string& text, const std::string& name,
                                             PixelOrigin origin);

}  // namespace io
}  // namespace slope_monitor
