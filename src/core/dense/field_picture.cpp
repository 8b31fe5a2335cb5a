#include "slope_monitor/core/dense/field_picture.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/numeric.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace dense {
namespace {

const cv::Scalar kUsable(0, 200, 0);
const cv::Scalar kStable(255, 255, 0);
const cv::Scalar kGrazing(0, 140, 255);
const cv::Scalar kLineOfSight(255, 0, 255);
const cv::Scalar kOtherFlag(0, 255, 255);
const cv::Scalar kNoMatch(0, 0, 255);

// LSC gave this probe a match (xb): every flag but these.
bool Matched(const FieldPoint& p) { return p.flag != "off_image" && p.flag.rfind("lsc_", 0) != 0; }

cv::Scalar ColourOf(const FieldPoint& p) {
  if (p.IsUsable()) return p.stable ? kStable : kUsable;
  if (p.flag == "grazing") return kGrazing;
  if (p.flag == "line_of_sight") return kLineOfSight;
  return kOtherFlag;
}

// The largest of 1, 2, 5 x 10^k not above x (x > 0).
double RoundDown125(double x) {
  const double p = std::pow(10.0, std::floor(std::log10(x)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * p <= x) return m * p;
  return p;
}

std::string Format(const char* format, double a, double b = 0.0, double c = 0.0) {
  char s[160];
  std::snprintf(s, sizeof(s), format, a, b, c);
  return s;
}

// Legend box at the top left: the scale bar and the colours.
void DrawLegend(const FieldPictureSummary& s, int thick, cv::Mat* out) {
  const double font = 0.5 * thick;
  const int line = 22 * thick, x0 = 10 * thick;
  const std::vector<std::pair<std::string, cv::Scalar>> rows = {
      {"usable", kUsable},        {"stable check", kStable},
      {"grazing", kGrazing},      {"line of sight", kLineOfSight},
      {"other flag", kOtherFlag}, {"no match", kNoMatch}};
  const int bar = cvRound(s.bar_motion_px * s.exaggeration);
  const int width = std::max(bar + 2 * x0, 330 * thick);
  const cv::Rect box(0, 0, std::min(width, out->cols),
                     std::min(line * (3 + static_cast<int>(rows.size())), out->rows));
  (*out)(box) *= 0.3;
  int y = line;
  const std::string label = s.bar_metres > 0 ? Format("%g px motion = %.3g m across the view",
                                                      s.bar_motion_px, s.bar_metres)
                                             : Format("%g px motion", s.bar_motion_px);
  cv::putText(*out, label, cv::Point(x0, y), cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar::all(255),
              thick, cv::LINE_AA);
  y += line / 2;
  cv::line(*out, cv::Point(x0, y), cv::Point(x0 + bar, y), cv::Scalar::all(255), 2 * thick);
  for (int x : {x0, x0 + bar})
    cv::line(*out, cv::Point(x, y - 4 * thick), cv::Point(x, y + 4 * thick), cv::Scalar::all(255),
             thick);
  y += line;
  for (const auto& [name, colour] : rows) {
    cv::line(*out, cv::Point(x0, y - 5 * thick), cv::Point(x0 + 20 * thick, y - 5 * thick), colour,
             2 * thick);
    cv::putText(*out, name, cv::Point(x0 + 28 * thick, y), cv::FONT_HERSHEY_SIMPLEX, font,
                cv::Scalar::all(255), thick, cv::LINE_AA);
    y += line;
  }
}

}  // namespace

void FieldPictureOptions::Check() const {
  if (!(longest_arrow_px > 0))
    throw InvalidArgument(
        Message("field picture: longest_arrow_px must be > 0, got ", longest_arrow_px));
}

bool ArrowTail(const camera::CameraModel& model, const camera::ExteriorOrientation& current,
               const FieldPoint& p, Eigen::Vector2d* tail) {
  return model.Project(current, p.x_ref, tail);
}

cv::Mat DrawDisplacementField(const cv::Mat& photo, const DisplacementField& field,
                              const camera::CameraModel& model,
                              const camera::ExteriorOrientation& current,
                              const FieldPictureOptions& options, FieldPictureSummary* summary) {
  options.Check();
  const camera::Sensor& sensor = model.sensor();
  if (photo.cols != sensor.width || photo.rows != sensor.height || photo.depth() != CV_8U ||
      (photo.channels() != 1 && photo.channels() != 3))
    throw InvalidArgument(Message("field picture: the photo is ", photo.cols, "x", photo.rows, "x",
                                  photo.channels(), " of depth ", photo.depth(), ", the camera ",
                                  sensor.width, "x", sensor.height, ", 8-bit"));
  cv::Mat out;
  if (photo.channels() == 1)
    cv::cvtColor(photo, out, cv::COLOR_GRAY2BGR);
  else
    out = photo.clone();

  // Tails, motions, the exaggeration and the metres per pixel.
  FieldPictureSummary s;
  std::vector<Eigen::Vector2d> tails(field.points.size());
  std::vector<bool> has_tail(field.points.size(), false);
  double longest = 0.0;
  std::vector<double> ranges;
  for (size_t i = 0; i < field.points.size(); ++i) {
    const FieldPoint& p = field.points[i];
    if (!Matched(p) || !ArrowTail(model, current, p, &tails[i])) continue;
    has_tail[i] = true;
    if (!p.IsUsable()) continue;
    ranges.push_back((p.x_ref - current.position).norm());
    if (!p.stable) longest = std::max(longest, (p.xb - tails[i]).norm());
  }
  // Lines, text and arrows grow with the photo: x1 up to 1999 px wide, x2 from 2000, ...
  const int thick = std::max(1, photo.cols / 1000);
  s.bar_motion_px = RoundDown125(longest > 0 ? longest : 1.0);
  s.exaggeration = thick * options.longest_arrow_px / std::max(longest, s.bar_motion_px);
  s.metres_per_px = UpperMedian(ranges) * sensor.pixel_size / model.principal_distance();
  s.bar_metres = s.bar_motion_px * s.metres_per_px;

  // The legend first: the arrows stay visible where they cross it.
  DrawLegend(s, thick, &out);
  for (size_t i = 0; i < field.points.size(); ++i) {
    const FieldPoint& p = field.points[i];
    if (!has_tail[i]) {
      const Eigen::Vector2d& x = Matched(p) ? p.xb : p.xa;
      cv::circle(out, cv::Point(cvRound(x.x()), cvRound(x.y())), 2 * thick, kNoMatch, cv::FILLED);
      ++s.dots;
      continue;
    }
    const Eigen::Vector2d head = tails[i] + s.exaggeration * (p.xb - tails[i]);
    const cv::Point a(cvRound(tails[i].x()), cvRound(tails[i].y()));
    const cv::Scalar colour = ColourOf(p);
    cv::circle(out, a, 2 * thick, colour, cv::FILLED);
    cv::arrowedLine(out, a, cv::Point(cvRound(head.x()), cvRound(head.y())), colour, thick,
                    cv::LINE_AA, 0, 0.25);
    ++s.arrows;
  }
  if (summary) *summary = s;
  return out;
}

FieldPictureSummary WriteDisplacementFieldPng(const std::string& path, const cv::Mat& photo,
                                              const DisplacementField& field,
                                              const camera::CameraModel& model,
                                              const camera::ExteriorOrientation& current,
                                              const FieldPictureOptions& options) {
  FieldPictureSummary s;
  const cv::Mat out = DrawDisplacementField(photo, field, model, current, options, &s);
  // Encoded in memory, then written whole (a temporary in the folder, renamed): a full disk
  // leaves the previous picture as it was.
  std::vector<uchar> png;
  bool ok = false;
  try {
    ok = cv::imencode(".png", out, png);
  } catch (const cv::Exception& e) {
    throw IoError(Message("cannot encode the field picture '", path, "': ", e.what()));
  }
  if (!ok) throw IoError(Message("cannot encode the field picture '", path, "'"));
  io::WriteFileAtomically(path, std::string(png.begin(), png.end()));
  return s;
}

std::string FieldPictureFileName(const std::string& camera, int epoch) {
  char b[32];
  std::snprintf(b, sizeof b, "_field_e%02d.png", epoch);
  return camera + b;
}

}  // namespace dense
}  // namespace slope_monitor
