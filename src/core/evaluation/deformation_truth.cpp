#include "slope_monitor/core/evaluation/deformation_truth.h"

#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <sstream>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/common/format.h"
#include "slope_monitor/core/deformation/history.h"
#include "slope_monitor/core/sim/survey.h"

namespace slope_monitor {
namespace evaluation {
namespace {

// Read-only access to the history file.
class Db {
 public:
  explicit Db(const std::string& path) : path_(path) {
    if (sqlite3_open_v2(path.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
      const std::string why = db_ ? sqlite3_errmsg(db_) : "cannot open";
      sqlite3_close(db_);
      throw IoError(Message("cannot open deformation history '", path, "': ", why));
    }
    // A damaged file or one written by an unknown schema is refused, not read.
    const std::string integrity = Scalar("PRAGMA integrity_check");
    if (integrity != "ok")
      throw IoError(
          Message("deformation history '", path, "' fails PRAGMA integrity_check: ", integrity));
    const std::string version = Scalar("PRAGMA user_version");
    if (version != std::to_string(deformation::History::kSchemaVersion))
      throw IoError(Message("deformation history '", path, "' has schema version ", version,
                            "; this program reads ", deformation::History::kSchemaVersion));
  }
  ~Db() { sqlite3_close(db_); }

  // The first column of the first row of `sql` as text ("" without a row).
  std::string Scalar(const std::string& sql) const {
    sqlite3_stmt* s = Prepare(sql);
    std::string out;
    if (sqlite3_step(s) == SQLITE_ROW && sqlite3_column_text(s, 0))
      out = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
    sqlite3_finalize(s);
    return out;
  }
  Db(const Db&) = delete;
  Db& operator=(const Db&) = delete;

  sqlite3_stmt* Prepare(const std::string& sql) const {
    sqlite3_stmt* s = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &s, nullptr) != SQLITE_OK) {
      throw IoError(
          Message("deformation history '", path_, "': ", sqlite3_errmsg(db_), " in: ", sql));
    }
    return s;
  }

 private:
  std::string path_;
  sqlite3* db_ = nullptr;
};

Eigen::Matrix3d BlobToMatrix(sqlite3_stmt* s, int col) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  if (sqlite3_column_bytes(s, col) == 9 * static_cast<int>(sizeof(double))) {
    double v[9];
    std::memcpy(v, sqlite3_column_blob(s, col), sizeof(v));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = v[3 * r + c];
  }
  return m;
}

}  // namespace

std::string SourceName(int source) {
  switch (source) {
    case 1:
      return "target";
    case 2:
      return "feature";
    case 3:
      return "radio";
    case 4:
      return "surface";
    case 5:
      return "fused";
    default:
      return "other";
  }
}

std::string AlertName(int level) {
  switch (level) {
    case 0:
      return "none";
    case 1:
      return "watch";
    case 2:
      return "warning";
    case 3:
      return "alarm";
    default:
      return "?";
  }
}

double PointEvaluation::NormalisedError() const {
  const Eigen::Vector3d e = Error();
  const double n = e.norm();
  if (n == 0.0) return 0.0;
  const Eigen::Vector3d u = e / n;
  const double var = u.dot(covariance * u);
  return var > 0.0 ? n / std::sqrt(var) : std::numeric_limits<double>::infinity();
}

const PointEvaluation* DeformationEvaluation::Find(const std::string& id) const {
  for (const auto& p : points)
    if (p.id == id) return &p;
  return nullptr;
}

DeformationEvaluation EvaluateHistory(const std::string& database, const sim::SurveyTruth& truth) {
  Db db(database);
  DeformationEvaluation out;
  out.true_failure_time = truth.landslide.velocity == sim::LandslideModel::Velocity::kAccelerating
                              ? truth.landslide.failure_time
                              : 0.0;

  {
    sqlite3_stmt* s = db.Prepare("SELECT value FROM meta WHERE key = 'datum_stamp'");
    if (sqlite3_step(s) == SQLITE_ROW)
      out.reference_stamp = std::atof(reinterpret_cast<const char*>(sqlite3_column_text(s, 0)));
    sqlite3_finalize(s);
  }

  // Reference positions: the truth's (targets, transmitters) where known, else the first
  // observation's.
  std::map<std::string, Eigen::Vector3d> reference;
  std::map<std::string, std::string> role;
  for (const auto& t : truth.targets) {
    if (!t.positions.empty()) reference[t.key] = t.positions.front();
    role[t.key] = io::TargetRoleName(t.role);
  }
  for (const auto& t : truth.radio.transmitters) {
    if (!t.positions.empty()) reference[t.id] = t.positions.front();
    role[t.id] = "radio";
  }
  struct Obs {
    std::string id;
    int source;
    double stamp;
    Eigen::Vector3d d;
  };
  std::vector<Obs> observations;
  std::map<std::string, std::map<int, int>> counts;
  {
    sqlite3_stmt* s = db.Prepare(
        "SELECT point_id, source, stamp, rx, ry, rz, dx, dy, dz FROM observations ORDER BY id");
    while (sqlite3_step(s) == SQLITE_ROW) {
      Obs o;
      o.id = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
      o.source = sqlite3_column_int(s, 1);
      o.stamp = sqlite3_column_double(s, 2);
      o.d = Eigen::Vector3d(sqlite3_column_double(s, 6), sqlite3_column_double(s, 7),
                            sqlite3_column_double(s, 8));
      if (!reference.count(o.id)) {
        reference[o.id] = Eigen::Vector3d(sqlite3_column_double(s, 3), sqlite3_column_double(s, 4),
                                          sqlite3_column_double(s, 5));
      }
      observations.push_back(o);
    }
    sqlite3_finalize(s);
  }
  auto true_displacement = [&](const std::string& id, double t) {
    const Eigen::Vector3d x = reference.count(id) ? reference[id] : Eigen::Vector3d::Zero();
    return truth.DisplacementAt(x, t) - truth.DisplacementAt(x, out.reference_stamp);
  };

  // Every stored fused estimate, by point and time.
  std::map<std::string, std::map<double, Eigen::Vector3d>> fused;
  {
    sqlite3_stmt* s = db.Prepare("SELECT point_id, stamp, dx, dy, dz FROM estimates");
    while (sqlite3_step(s) == SQLITE_ROW) {
      fused[reinterpret_cast<const char*>(sqlite3_column_text(s, 0))][sqlite3_column_double(s, 1)] =
          Eigen::Vector3d(sqlite3_column_double(s, 2), sqlite3_column_double(s, 3),
                          sqlite3_column_double(s, 4));
    }
    sqlite3_finalize(s);
  }

  // Measurements per estimated point and source. A measured id the estimator
  // fused under another point's id (an alias: a transmitter on a target's
  // post, as the simulator's site overlay declares) counts for that point.
  {
    std::map<std::string, std::string> fused_as;
    for (const auto& [tx, key] : sim::ColocatedPoints(truth, 0.5)) fused_as[tx] = key;
    for (const Obs& o : observations) {
      std::string id = o.id;
      if (!fused.count(id) && fused_as.count(id) && fused.count(fused_as[id])) id = fused_as[id];
      ++counts[id][o.source];
    }
  }

  // Latest estimate of each point.
  {
    sqlite3_stmt* s = db.Prepare(
        "SELECT e.point_id, e.stamp, e.dx, e.dy, e.dz, e.vx, e.vy, e.vz, "
        "e.displacement_covariance, e.alert_level, "
        "e.forecast_time, e.forecast_sigma FROM estimates e JOIN (SELECT point_id, MAX(stamp) AS s "
        "FROM estimates "
        "GROUP BY point_id) m ON e.point_id = m.point_id AND e.stamp = m.s ORDER BY e.point_id");
    double sum2 = 0.0;
    while (sqlite3_step(s) == SQLITE_ROW) {
      PointEvaluation p;
      p.id = reinterpret_cast<const char*>(sqlite3_column_text(s, 0));
      p.role = role.count(p.id) ? role[p.id] : "unknown";
      p.stamp = sqlite3_column_double(s, 1);
      p.estimate = Eigen::Vector3d(sqlite3_column_double(s, 2), sqlite3_column_double(s, 3),
                                   sqlite3_column_double(s, 4));
      p.velocity = Eigen::Vector3d(sqlite3_column_double(s, 5), sqlite3_column_double(s, 6),
                                   sqlite3_column_double(s, 7));
      p.covariance = BlobToMatrix(s, 8);
      p.alert_level = sqlite3_column_int(s, 9);
      p.forecast_valid = sqlite3_column_type(s, 10) != SQLITE_NULL;
      if (p.forecast_valid) {
        p.forecast_time = sqlite3_column_double(s, 10);
        p.forecast_sigma = sqlite3_column_double(s, 11);
      }
      p.reference_position = reference.count(p.id) ? reference[p.id] : Eigen::Vector3d::Zero();
      p.truth = true_displacement(p.id, p.stamp);
      const double dt = 60.0;
      p.true_speed =
          (true_displacement(p.id, p.stamp) - true_displacement(p.id, p.stamp - dt)).norm() / dt;
      p.measurements = counts[p.id];
      if (p.role == "monitoring" || p.role == "radio") {
        sum2 += p.Error().squaredNorm();
        ++out.fused_count;
      }
      out.points.push_back(p);
    }
    sqlite3_finalize(s);
    out.fused_rms = out.fused_count ? std::sqrt(sum2 / out.fused_count) : 0.0;
  }

  // Raw measurements of each source against truth, and the fused estimate of
  // the same point at the same time (the estimate stored with that batch).
  std::map<int, std::pair<double, double>> sums;  // source -> (raw sum2, fused sum2)
  std::map<int, int> n;
  for (const Obs& o : observations) {
    const std::string r = role.count(o.id) ? role[o.id] : "unknown";
    if (r != "monitoring" && r != "radio") continue;
    auto fp = fused.find(o.id);
    if (fp == fused.end()) continue;
    auto it = fp->second.lower_bound(o.stamp - 1e-3);
    if (it == fp->second.end() || std::abs(it->first - o.stamp) > 1.0) continue;
    const Eigen::Vector3d t = true_displacement(o.id, o.stamp);
    sums[o.source].first += (o.d - t).squaredNorm();
    sums[o.source].second += (it->second - t).squaredNorm();
    ++n[o.source];
  }
  for (const auto& [source, s] : sums) {
    SourceEvaluation e;
    e.source = source;
    e.name = SourceName(source);
    e.count = n[source];
    e.rms = std::sqrt(s.first / e.count);
    e.fused_rms = std::sqrt(s.second / e.count);
    out.sources.push_back(e);
  }
  return out;
}

std::string FormatTable(const DeformationEvaluation& e) {
  std::ostringstream o;
  o << std::left << std::setw(14) << "point" << std::setw(11) << "role" << std::right
    << std::setw(9) << "|d| mm" << std::setw(27) << "d (x, y, z) mm" << std::setw(10) << "v mm/d"
    << std::setw(9) << "sigma mm" << std::setw(9) << "alert" << std::setw(10) << "true mm"
    << std::setw(10) << "err mm" << std::setw(8) << "err/s"
    << "  sources\n";
  for (const auto& p : e.points) {
    std::string d = Fixed(p.estimate.x() * 1e3, 1) + ", " + Fixed(p.estimate.y() * 1e3, 1) + ", " +
                    Fixed(p.estimate.z() * 1e3, 1);
    std::string sources;
    for (const auto& [s, c] : p.measurements)
      sources += (sources.empty() ? "" : " ") + SourceName(s) + "x" + std::to_string(c);
    o << std::left << std::setw(14) << p.id << std::setw(11) << p.role << std::right << std::setw(9)
      << Fixed(p.estimate.norm() * 1e3, 1) << std::setw(27) << d << std::setw(10)
      << Fixed(p.velocity.norm() * 86400e3, 1) << std::setw(9) << Fixed(p.Sigma() * 1e3, 2)
      << std::setw(9) << AlertName(p.alert_level) << std::setw(10) << Fixed(p.truth.norm() * 1e3, 1)
      << std::setw(10) << Fixed(p.Error().norm() * 1e3, 2) << std::setw(8)
      << Fixed(p.NormalisedError(), 2) << "  " << sources << "\n";
  }
  o << "fused RMS error of moving points (latest estimate): " << Fixed(e.fused_rms * 1e3, 2)
    << " mm over " << e.fused_count << " points\n";
  for (const auto& s : e.sources) {
    o << "source " << s.name << ": raw RMS " << Fixed(s.rms * 1e3, 2)
      << " mm, fused RMS at the same times " << Fixed(s.fused_rms * 1e3, 2) << " mm (" << s.count
      << " measurements)\n";
  }
  for (const auto& p : e.points) {
    if (!p.forecast_valid) continue;
    o << "forecast " << p.id << ": failure at t0 + "
      << Fixed((p.forecast_time - e.reference_stamp) / 3600.0, 2) << " h +- "
      << Fixed(p.forecast_sigma / 3600.0, 2) << " h";
    if (e.true_failure_time > 0.0)
      o << " (truth t0 + " << Fixed((e.true_failure_time - e.reference_stamp) / 3600.0, 2) << " h)";
    o << "\n";
  }
  return o.str();
}

}  // namespace evaluation
}  // namespace slope_monitor
