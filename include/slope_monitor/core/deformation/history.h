// Persistent history of the deformation estimator in SQLite (sqlite3 C API).
//
// The file is opened in WAL mode (readers never block the writer, a crash
// never leaves a half-written transaction visible). Every batch of
// observations is committed in one transaction *before* the estimator uses
// it, and its estimates in a second one, so a process killed mid-epoch loses
// nothing: on restart the estimator replays every stored batch in arrival
// order and reaches the state it would have had without the interruption.
//
// A file that is not a SQLite database (or is corrupt, or was written by a
// newer schema) is refused with an IoError naming the file; it is never
// written to or replaced.
//
// One writer per history: the constructor takes an exclusive
// flock() on the sidecar file `<path>.lock` (created beside the database,
// left there; it holds the owner's process id) without waiting. While
// another History, in this or any other process, holds it, the constructor
// throws HistoryInUse before opening the database:
//   history database '/data/slope.db' is in use by process 4242 (process_bag),
//   which holds its writer lock '/data/slope.db.lock'; one writer per history:
//   wait for it to end or use another database
// The lock ends with the History (or its process, however it ends: kill -9
// included); child processes do not inherit it (O_CLOEXEC). Readers
// (evaluation::EvaluateHistory, deformation_summary) take no lock.
//
// Schema (PRAGMA user_version = 2):
//   meta(key TEXT PRIMARY KEY, value TEXT NOT NULL)
//       keys: created (UTC ISO time), datum_stamp [s], reference_epoch,
//             reference_stamp [s]
//   batches(id INTEGER PRIMARY KEY, received TEXT,        -- arrival order
//           epoch INTEGER, stamp REAL)                    -- [s] header stamp
//   observations(id INTEGER PRIMARY KEY,                  -- arrival order = replay order
//           batch_id INTEGER REFERENCES batches(id),
//           point_id TEXT, source INTEGER,                -- PointDisplacement.SOURCE_*
//           source_name TEXT, epoch INTEGER,
//           stamp REAL, reference_stamp REAL,             -- [s]
//           rx REAL, ry REAL, rz REAL,                    -- [m] reference position (site)
//           dx REAL, dy REAL, dz REAL,                    -- [m] displacement (site)
//           covariance BLOB)                              -- 9 doubles, row-major [m^2]
//   estimates(point_id TEXT, stamp REAL, epoch INTEGER, batch_id INTEGER,
//           dx REAL, dy REAL, dz REAL,                    -- [m] from the datum
//           vx REAL, vy REAL, vz REAL,                    -- [m/s]
//           ax REAL, ay REAL, az REAL,                    -- [m/s^2]
//           displacement_covariance BLOB,                 -- 9 doubles [m^2]
//           velocity_covariance BLOB,                     -- 9 doubles [m^2/s^2]
//           alert_level INTEGER,                          -- (v2) DeformationPoint.ALERT_*
//           forecast_time REAL, forecast_sigma REAL,      -- (v2) [s]; NULL when no forecast
//           PRIMARY KEY(point_id, stamp))                 -- the estimate published after each
//           batch
//   reference_offsets(point_id TEXT PRIMARY KEY,          -- (v2) fused displacement at the
//           dx REAL, dy REAL, dz REAL, covariance BLOB)   --   reference epoch, subtracted on
//           output
//   saved_states(key TEXT PRIMARY KEY, stamp REAL,        -- (any version; SavedStates) the
//           value TEXT)                                   --   sources' references, see below
//
// The history belongs to a site: meta `site` names it (a
// recording of another site is refused by the caller), meta
// `reference_recording` the recording the reference epoch came from. The
// references the sources measure from live here too, not in a run's memory:
// the bundle adjuster's reference epoch and the radio network's reference
// solution and tracking state (SavedStates), so a later recording's
// displacements are measured from the site's reference.
//
// Migrations: version 0 (empty file) -> 2 creates everything; 1 -> 2 adds
// the estimates' alert and forecast columns and reference_offsets.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/estimator.h"

struct sqlite3;

namespace slope_monitor {
namespace deformation {

// The history is held by another writer (see above).
class HistoryInUse : public IoError {
 public:
  using IoError::IoError;
};

// What a history holds, read without the writer lock (process_bag's first
// line). `exists` false: no file yet.
struct HistoryInfo {
  bool exists = false;
  std::string site;                 // meta site ("" when not set)
  bool has_reference = false;       // meta reference_stamp set
  uint32_t reference_epoch = 0;     // meta reference_epoch
  double reference_stamp = 0.0;     // [s]
  std::string reference_recording;  // meta reference_recording
  int64_t epochs = 0;               // survey epochs: distinct stamps of its non-radio observations
  int64_t radio_epochs = 0;         // distinct stamps of its radio observations
  int64_t observations = 0;
};
// Throws IoError for a file that is not a history (naming it).
HistoryInfo DescribeHistory(const std::string& path);

// The sources' saved states in a history file (table saved_states), for the
// steps that measure from a reference of their own (the bundle adjuster's
// epoch store, the radio solver). Its own connection, no writer lock: the
// estimator's History holds that, and SQLite serialises the writes. Creates
// the file and the table when absent. Throws IoError naming the file.
class SavedStates {
 public:
  struct Saved {
    std::string key;
    double stamp = 0.0;  // [s] the newest input the state has seen
    std::string value;
  };
  explicit SavedStates(const std::string& path);
  ~SavedStates();
  SavedStates(const SavedStates&) = delete;
  SavedStates& operator=(const SavedStates&) = delete;

  void Put(const std::string& key, double stamp, const std::string& value);
  std::optional<Saved> Get(const std::string& key) const;
  // The state under a key starting with `prefix` with the newest stamp
  // before `stamp` (a recording goes on from the one before it in time).
  std::optional<Saved> LatestBefore(const std::string& prefix, double stamp) const;
  // Every state under `prefix` with a stamp after `stamp`, in stamp order.
  std::vector<Saved> After(const std::string& prefix, double stamp) const;

 private:
  void Exec(const std::string& sql) const;
  std::string path_;
  sqlite3* db_ = nullptr;
};

class History {
 public:
  static constexpr int kSchemaVersion = 2;

  // Takes the writer lock (HistoryInUse if another writer holds it), opens
  // (creating it and its directory if absent) and migrates. Throws IoError naming the file.
  explicit History(const std::string& path);
  ~History();
  History(const History&) = delete;
  History& operator=(const History&) = delete;

  const std::string& path() const { return path_; }
  int schema_version() const;

  struct StoredBatch {
    Batch batch;
    std::vector<uint64_t> sequences;  // observation ids, in measurement order
  };

  // One transaction; returns the observation ids (the replay order).
  std::vector<uint64_t> AppendBatch(const Batch& batch);
  // Replaces the values (reference position, displacement, covariance) of
  // the stored observation with m's identity (point, source, source name,
  // stamp); false when there is none. One transaction per call.
  bool ReviseObservation(const Measurement& m);
  std::vector<StoredBatch> LoadBatches() const;

  // One transaction for all points.
  void StoreEstimates(const std::vector<PointState>& points, uint32_t epoch);

  void SetMeta(const std::string& key, const std::string& value);
  std::optional<std::string> Meta(const std::string& key) const;

  void StoreReferenceOffsets(
      const std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>>& offsets);
  std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>> LoadReferenceOffsets() const;

  int64_t CountRows(const std::string& table) const;

  // The site this history belongs to: a history without one takes `site`;
  // one of another site is refused (ConfigError naming both sites and the
  // file; nothing written). "" checks nothing.
  void CheckSite(const std::string& site);
  // A history holding observations but no reference (meta datum_stamp
  // missing: edited, or written by hand) is refused with an IoError naming
  // the file; nothing is written to it.
  void CheckReference() const;
  // A new reference on request (process_bag --new-reference): the datum and
  // the reference epoch are cleared (the next measurement sets them), the
  // reference offsets and the sources' saved states removed. The
  // observations stay in the history.
  void StartNewReference();

 private:
  void Exec(const std::string& sql) const;
  [[noreturn]] void Fail(const std::string& what) const;
  void Migrate();

  class WriterLock;  // the flock on <path>.lock, released when destroyed

  std::string path_;
  std::unique_ptr<WriterLock> lock_;
  sqlite3* db_ = nullptr;
};

}  // namespace deformation
}  // namespace slope_monitor
