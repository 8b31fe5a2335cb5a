#include "slope_monitor/core/deformation/history.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <fstream>
#include <thread>

#include <sqlite3.h>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace deformation {
namespace {

// Statement with automatic finalisation.
class Statement {
 public:
  Statement(sqlite3* db, const std::string& sql, const std::string& path) : path_(path) {
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK) {
      throw IoError(Message("history database '", path, "': cannot prepare '", sql,
                            "': ", sqlite3_errmsg(db)));
    }
  }
  ~Statement() { sqlite3_finalize(stmt_); }
  sqlite3_stmt* get() const { return stmt_; }
  void Bind(int i, double v) { sqlite3_bind_double(stmt_, i, v); }
  void Bind(int i, int64_t v) { sqlite3_bind_int64(stmt_, i, v); }
  void Bind(int i, const std::string& v) {
    sqlite3_bind_text(stmt_, i, v.c_str(), -1, SQLITE_TRANSIENT);
  }
  void BindMatrix(int i, const Eigen::Matrix3d& m) {
    double a[9];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) a[3 * r + c] = m(r, c);
    sqlite3_bind_blob(stmt_, i, a, sizeof(a), SQLITE_TRANSIENT);
  }
  void BindNull(int i) { sqlite3_bind_null(stmt_, i); }
  // SQLITE_ROW -> true, SQLITE_DONE -> false, else IoError.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw IoError(
        Message("history database '", path_, "': ", sqlite3_errmsg(sqlite3_db_handle(stmt_))));
  }
  void Reset() {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }
  double Double(int i) const { return sqlite3_column_double(stmt_, i); }
  int64_t Int(int i) const { return sqlite3_column_int64(stmt_, i); }
  std::string Text(int i) const {
    const unsigned char* t = sqlite3_column_text(stmt_, i);
    return t ? reinterpret_cast<const char*>(t) : "";
  }
  Eigen::Matrix3d Matrix(int i) const {
    Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
    const void* b = sqlite3_column_blob(stmt_, i);
    if (b && sqlite3_column_bytes(stmt_, i) == 9 * static_cast<int>(sizeof(double))) {
      double a[9];
      std::memcpy(a, b, sizeof(a));
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m(r, c) = a[3 * r + c];
    }
    return m;
  }

 private:
  sqlite3_stmt* stmt_ = nullptr;
  std::string path_;
};

std::string UtcNow() {
  char buf[32];
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

const char* kSchemaV1 =
    "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT NOT NULL);"
    "CREATE TABLE batches(id INTEGER PRIMARY KEY, received TEXT, epoch INTEGER, stamp REAL);"
    "CREATE TABLE observations(id INTEGER PRIMARY KEY, batch_id INTEGER REFERENCES batches(id),"
    " point_id TEXT NOT NULL, source INTEGER, source_name TEXT, epoch INTEGER, stamp REAL, "
    "reference_stamp REAL,"
    " rx REAL, ry REAL, rz REAL, dx REAL, dy REAL, dz REAL, covariance BLOB);"
    "CREATE INDEX observations_batch ON observations(batch_id);"
    "CREATE TABLE estimates(point_id TEXT NOT NULL, stamp REAL NOT NULL, epoch INTEGER, batch_id "
    "INTEGER,"
    " dx REAL, dy REAL, dz REAL, vx REAL, vy REAL, vz REAL, ax REAL, ay REAL, az REAL,"
    " displacement_covariance BLOB, velocity_covariance BLOB, PRIMARY KEY(point_id, stamp));";

const char* kMigrate1To2 =
    "ALTER TABLE estimates ADD COLUMN alert_level INTEGER NOT NULL DEFAULT 0;"
    "ALTER TABLE estimates ADD COLUMN forecast_time REAL;"
    "ALTER TABLE estimates ADD COLUMN forecast_sigma REAL;"
    "CREATE TABLE reference_offsets(point_id TEXT PRIMARY KEY, dx REAL, dy REAL, dz REAL, "
    "covariance BLOB);";

// Opens (creating when `create`) a SQLite file, waiting up to `busy_ms` for
// another connection's lock; IoError naming it.
sqlite3* OpenDatabase(const std::string& path, bool create, int busy_ms) {
  sqlite3* db = nullptr;
  const int flags = create ? SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE : SQLITE_OPEN_READONLY;
  if (sqlite3_open_v2(path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
    const std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw IoError(Message("cannot open history database '", path, "': ", msg));
  }
  sqlite3_busy_timeout(db, busy_ms);
  return db;
}

// The process id a lock file holds ("" when none is written yet) and, when
// /proc knows it, the process' name: "4242 (process_bag)".
std::string LockOwner(int fd) {
  char buf[32] = {0};
  const ssize_t n = pread(fd, buf, sizeof(buf) - 1, 0);
  if (n <= 0) return "";
  std::string pid(buf, static_cast<size_t>(n));
  pid = pid.substr(0, pid.find_first_not_of("0123456789"));
  if (pid.empty()) return "";
  std::string name;
  std::getline(std::ifstream("/proc/" + pid + "/comm"), name);
  return name.empty() ? pid : pid + " (" + name + ")";
}

}  // namespace

class History::WriterLock {
 public:
  explicit WriterLock(const std::string& path) {
    const std::string lock_path = path + ".lock";
    fd_ = open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd_ < 0)
      throw IoError(Message("history database '", path, "': cannot open its writer lock '",
                            lock_path, "': ", std::strerror(errno)));
    if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int error = errno;
      std::string owner;
      if (error == EWOULDBLOCK) {
        // The owner writes its pid right after it locks: give it a moment.
        for (int i = 0; i < 20 && (owner = LockOwner(fd_)).empty(); ++i)
          std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      close(fd_);
      if (error != EWOULDBLOCK)
        throw IoError(Message("history database '", path, "': cannot lock '", lock_path,
                              "': ", std::strerror(error)));
      throw HistoryInUse(Message(
          "history database '", path, "' is in use by process ",
          owner.empty() ? "(pid not known)" : owner, ", which holds its writer lock '", lock_path,
          "'; one writer per history: wait for it to end or use another database"));
    }
    const std::string pid = std::to_string(getpid()) + "\n";
    if (ftruncate(fd_, 0) != 0 ||
        pwrite(fd_, pid.data(), pid.size(), 0) != static_cast<ssize_t>(pid.size())) {
      const int error = errno;
      close(fd_);
      throw IoError(Message("history database '", path, "': cannot write its writer lock '",
                            lock_path, "': ", std::strerror(error)));
    }
  }
  ~WriterLock() { close(fd_); }  // releases the flock
  WriterLock(const WriterLock&) = delete;
  WriterLock& operator=(const WriterLock&) = delete;

 private:
  int fd_ = -1;
};

History::History(const std::string& path) : path_(path) {
  if (path.empty()) throw IoError("history database path is empty");
  // Create the parent directories of a new file (mkdir -p).
  for (size_t pos = path.find('/', 1); pos != std::string::npos; pos = path.find('/', pos + 1)) {
    const std::string dir = path.substr(0, pos);
    if (mkdir(dir.c_str(), 0755) != 0 && errno != EEXIST)
      throw IoError(Message("cannot create the directory '", dir, "' of history database '", path,
                            "': ", std::strerror(errno)));
  }
  // The writer lock first: a second writer is refused before the database is opened.
  lock_ = std::make_unique<WriterLock>(path);
  db_ = OpenDatabase(path, true, 5000);
  try {
    // Reading the header first: a non-SQLite file fails here, before any write.
    int version = schema_version();
    if (version > 0) {
      Statement check(db_, "PRAGMA quick_check", path_);
      if (!check.Step() || check.Text(0) != "ok")
        Fail(Message("integrity check failed (", check.Text(0), "); the file is left untouched"));
    }
    if (version < 0)
      Fail(Message("unknown schema version ", version, " (this program knows 0..", kSchemaVersion,
                   "); the file is left untouched"));
    if (version > kSchemaVersion)
      Fail(Message("schema version ", version, " is newer than this program's ", kSchemaVersion,
                   "; the file is left untouched"));
    Exec("PRAGMA journal_mode=WAL");
    Exec("PRAGMA synchronous=FULL");
    Migrate();
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

History::~History() {
  if (db_) sqlite3_close(db_);
}

void History::Fail(const std::string& what) const {
  throw IoError(Message("history database '", path_, "': ", what));
}

void History::Exec(const std::string& sql) const {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string msg = err ? err : sqlite3_errmsg(db_);
    sqlite3_free(err);
    const int code = sqlite3_errcode(db_);
    if (code == SQLITE_NOTADB || code == SQLITE_CORRUPT)
      Fail(Message("not a SQLite database or corrupt (", msg, "); the file is left untouched"));
    Fail(msg);
  }
}

int History::schema_version() const {
  sqlite3_stmt* s = nullptr;
  if (sqlite3_prepare_v2(db_, "PRAGMA user_version", -1, &s, nullptr) != SQLITE_OK) {
    const std::string msg = sqlite3_errmsg(db_);
    sqlite3_finalize(s);
    Fail(Message("not a SQLite database or corrupt (", msg, "); the file is left untouched"));
  }
  const int rc = sqlite3_step(s);
  if (rc != SQLITE_ROW) {
    const std::string msg = sqlite3_errmsg(db_);
    sqlite3_finalize(s);
    Fail(Message("not a SQLite database or corrupt (", msg, "); the file is left untouched"));
  }
  const int v = sqlite3_column_int(s, 0);
  sqlite3_finalize(s);
  return v;
}

namespace {

const char* kSavedStates =
    "CREATE TABLE IF NOT EXISTS saved_states(key TEXT PRIMARY KEY, stamp REAL NOT NULL, "
    "value TEXT NOT NULL)";

}  // namespace

HistoryInfo DescribeHistory(const std::string& path) {
  HistoryInfo info;
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return info;
  info.exists = true;
  sqlite3* db = OpenDatabase(path, false, 10000);
  try {
    auto meta = [&](const std::string& key) -> std::optional<std::string> {
      Statement q(db, "SELECT value FROM meta WHERE key = ?", path);
      q.Bind(1, key);
      if (!q.Step()) return std::nullopt;
      return q.Text(0);
    };
    Statement tables(db, "SELECT count(*) FROM sqlite_master WHERE name = 'meta'", path);
    if (tables.Step() && tables.Int(0) > 0) {
      info.site = meta("site").value_or("");
      if (auto s = meta("reference_stamp"); s && !s->empty()) {
        info.has_reference = true;
        info.reference_stamp = std::stod(*s);
        info.reference_epoch =
            static_cast<uint32_t>(std::stoul(meta("reference_epoch").value_or("0")));
      }
      info.reference_recording = meta("reference_recording").value_or("");
      Statement e(db,
                  "SELECT count(DISTINCT CASE WHEN source != 3 THEN stamp END), "
                  "count(DISTINCT CASE WHEN source = 3 THEN stamp END) FROM observations",
                  path);
      if (e.Step()) {
        info.epochs = e.Int(0);
        info.radio_epochs = e.Int(1);
      }
      Statement o(db, "SELECT count(*) FROM observations", path);
      if (o.Step()) info.observations = o.Int(0);
    }
  } catch (...) {
    sqlite3_close(db);
    throw;
  }
  sqlite3_close(db);
  return info;
}

SavedStates::SavedStates(const std::string& path) : path_(path) {
  db_ = OpenDatabase(path, true, 10000);
  try {
    Exec(kSavedStates);
  } catch (...) {
    sqlite3_close(db_);
    db_ = nullptr;
    throw;
  }
}

SavedStates::~SavedStates() {
  if (db_) sqlite3_close(db_);
}

void SavedStates::Exec(const std::string& sql) const {
  char* err = nullptr;
  if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    const std::string msg = err ? err : sqlite3_errmsg(db_);
    sqlite3_free(err);
    throw IoError(Message("history database '", path_, "': ", msg));
  }
}

void SavedStates::Put(const std::string& key, double stamp, const std::string& value) {
  Statement q(db_, "INSERT OR REPLACE INTO saved_states(key, stamp, value) VALUES(?, ?, ?)", path_);
  q.Bind(1, key);
  q.Bind(2, stamp);
  q.Bind(3, value);
  q.Step();
}

std::optional<SavedStates::Saved> SavedStates::Get(const std::string& key) const {
  Statement q(db_, "SELECT key, stamp, value FROM saved_states WHERE key = ?", path_);
  q.Bind(1, key);
  if (!q.Step()) return std::nullopt;
  return Saved{q.Text(0), q.Double(1), q.Text(2)};
}

std::optional<SavedStates::Saved> SavedStates::LatestBefore(const std::string& prefix,
                                                            double stamp) const {
  Statement q(db_,
              "SELECT key, stamp, value FROM saved_states WHERE substr(key, 1, length(?1)) = ?1 "
              "AND stamp < ?2 ORDER BY stamp DESC LIMIT 1",
              path_);
  q.Bind(1, prefix);
  q.Bind(2, stamp);
  if (!q.Step()) return std::nullopt;
  return Saved{q.Text(0), q.Double(1), q.Text(2)};
}

std::vector<SavedStates::Saved> SavedStates::After(const std::string& prefix, double stamp) const {
  Statement q(db_,
              "SELECT key, stamp, value FROM saved_states WHERE substr(key, 1, length(?1)) = ?1 "
              "AND stamp > ?2 ORDER BY stamp, key",
              path_);
  q.Bind(1, prefix);
  q.Bind(2, stamp);
  std::vector<Saved> out;
  while (q.Step()) out.push_back({q.Text(0), q.Double(1), q.Text(2)});
  return out;
}

void History::Migrate() {
  int version = schema_version();
  if (version == kSchemaVersion) return;
  Exec("BEGIN IMMEDIATE");
  try {
    if (version == 0) {
      Exec(kSchemaV1);
      Exec(Message("INSERT INTO meta(key, value) VALUES('created', '", UtcNow(), "')"));
      version = 1;
    }
    if (version == 1) {
      Exec(kMigrate1To2);
      version = 2;
    }
    Exec(Message("PRAGMA user_version = ", version));
    Exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

bool History::ReviseObservation(const Measurement& m) {
  Statement q(db_,
              "UPDATE observations SET rx = ?, ry = ?, rz = ?, dx = ?, dy = ?, dz = ?, "
              "covariance = ?, reference_stamp = ? WHERE point_id = ? AND source = ? AND "
              "source_name = ? AND stamp = ?",
              path_);
  for (int k = 0; k < 3; ++k) q.Bind(1 + k, m.reference_position(k));
  for (int k = 0; k < 3; ++k) q.Bind(4 + k, m.displacement(k));
  q.BindMatrix(7, m.covariance);
  q.Bind(8, m.reference_stamp);
  q.Bind(9, m.point_id);
  q.Bind(10, static_cast<int64_t>(m.source));
  q.Bind(11, m.source_name);
  q.Bind(12, m.stamp);
  q.Step();
  return sqlite3_changes(db_) > 0;
}

std::vector<uint64_t> History::AppendBatch(const Batch& batch) {
  std::vector<uint64_t> ids;
  Exec("BEGIN IMMEDIATE");
  try {
    Statement b(db_, "INSERT INTO batches(received, epoch, stamp) VALUES(?, ?, ?)", path_);
    b.Bind(1, UtcNow());
    b.Bind(2, static_cast<int64_t>(batch.epoch));
    b.Bind(3, batch.stamp);
    b.Step();
    const int64_t batch_id = sqlite3_last_insert_rowid(db_);
    Statement o(db_,
                "INSERT INTO observations(batch_id, point_id, source, source_name, epoch, stamp, "
                "reference_stamp,"
                " rx, ry, rz, dx, dy, dz, covariance) VALUES(?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
                path_);
    for (const Measurement& m : batch.measurements) {
      o.Reset();
      o.Bind(1, batch_id);
      o.Bind(2, m.point_id);
      o.Bind(3, static_cast<int64_t>(m.source));
      o.Bind(4, m.source_name);
      o.Bind(5, static_cast<int64_t>(m.epoch));
      o.Bind(6, m.stamp);
      o.Bind(7, m.reference_stamp);
      for (int k = 0; k < 3; ++k) o.Bind(8 + k, m.reference_position(k));
      for (int k = 0; k < 3; ++k) o.Bind(11 + k, m.displacement(k));
      o.BindMatrix(14, m.covariance);
      o.Step();
      ids.push_back(static_cast<uint64_t>(sqlite3_last_insert_rowid(db_)));
    }
    Exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
  return ids;
}

std::vector<History::StoredBatch> History::LoadBatches() const {
  std::vector<StoredBatch> out;
  std::map<int64_t, size_t> index;
  Statement b(db_, "SELECT id, epoch, stamp FROM batches ORDER BY id", path_);
  while (b.Step()) {
    index[b.Int(0)] = out.size();
    StoredBatch sb;
    sb.batch.epoch = static_cast<uint32_t>(b.Int(1));
    sb.batch.stamp = b.Double(2);
    out.push_back(sb);
  }
  Statement o(db_,
              "SELECT id, batch_id, point_id, source, source_name, epoch, stamp, reference_stamp, "
              "rx, ry, rz,"
              " dx, dy, dz, covariance FROM observations ORDER BY id",
              path_);
  while (o.Step()) {
    auto it = index.find(o.Int(1));
    if (it == index.end())
      Fail(Message("observation ", o.Int(0), " refers to a missing batch ", o.Int(1)));
    Measurement m;
    m.point_id = o.Text(2);
    m.source = SourceFromInt(static_cast<int>(o.Int(3)));
    m.source_name = o.Text(4);
    m.epoch = static_cast<uint32_t>(o.Int(5));
    m.stamp = o.Double(6);
    m.reference_stamp = o.Double(7);
    m.reference_position = Eigen::Vector3d(o.Double(8), o.Double(9), o.Double(10));
    m.displacement = Eigen::Vector3d(o.Double(11), o.Double(12), o.Double(13));
    m.covariance = o.Matrix(14);
    out[it->second].batch.measurements.push_back(m);
    out[it->second].sequences.push_back(static_cast<uint64_t>(o.Int(0)));
  }
  return out;
}

void History::StoreEstimates(const std::vector<PointState>& points, uint32_t epoch) {
  if (points.empty()) return;
  Exec("BEGIN IMMEDIATE");
  try {
    Statement s(
        db_,
        "INSERT OR REPLACE INTO estimates(point_id, stamp, epoch, batch_id, dx, dy, dz, vx, vy, "
        "vz, ax, ay, az,"
        " displacement_covariance, velocity_covariance, alert_level, forecast_time, forecast_sigma)"
        " VALUES(?,?,?,(SELECT MAX(id) FROM batches),?,?,?,?,?,?,?,?,?,?,?,?,?,?)",
        path_);
    for (const PointState& p : points) {
      s.Reset();
      s.Bind(1, p.id);
      s.Bind(2, p.stamp);
      s.Bind(3, static_cast<int64_t>(epoch));
      for (int k = 0; k < 3; ++k) s.Bind(4 + k, p.displacement(k));
      for (int k = 0; k < 3; ++k) s.Bind(7 + k, p.velocity(k));
      for (int k = 0; k < 3; ++k) s.Bind(10 + k, p.acceleration(k));
      s.BindMatrix(13, p.displacement_covariance);
      s.BindMatrix(14, p.velocity_covariance);
      s.Bind(15, static_cast<int64_t>(p.alert));
      if (p.forecast.valid) {
        s.Bind(16, p.forecast.failure_time);
        s.Bind(17, p.forecast.sigma);
      } else {
        s.BindNull(16);
        s.BindNull(17);
      }
      s.Step();
    }
    Exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

void History::SetMeta(const std::string& key, const std::string& value) {
  Statement s(db_, "INSERT OR REPLACE INTO meta(key, value) VALUES(?, ?)", path_);
  s.Bind(1, key);
  s.Bind(2, value);
  s.Step();
}

std::optional<std::string> History::Meta(const std::string& key) const {
  Statement s(db_, "SELECT value FROM meta WHERE key = ?", path_);
  s.Bind(1, key);
  if (!s.Step()) return std::nullopt;
  return s.Text(0);
}

void History::StoreReferenceOffsets(
    const std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>>& offsets) {
  Exec("BEGIN IMMEDIATE");
  try {
    Exec("DELETE FROM reference_offsets");
    Statement s(db_,
                "INSERT INTO reference_offsets(point_id, dx, dy, dz, covariance) VALUES(?,?,?,?,?)",
                path_);
    for (const auto& [id, o] : offsets) {
      s.Reset();
      s.Bind(1, id);
      for (int k = 0; k < 3; ++k) s.Bind(2 + k, o.first(k));
      s.BindMatrix(5, o.second);
      s.Step();
    }
    Exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>> History::LoadReferenceOffsets()
    const {
  std::map<std::string, std::pair<Eigen::Vector3d, Eigen::Matrix3d>> out;
  Statement s(db_, "SELECT point_id, dx, dy, dz, covariance FROM reference_offsets", path_);
  while (s.Step())
    out[s.Text(0)] = {Eigen::Vector3d(s.Double(1), s.Double(2), s.Double(3)), s.Matrix(4)};
  return out;
}

int64_t History::CountRows(const std::string& table) const {
  if (table != "batches" && table != "observations" && table != "estimates" && table != "meta" &&
      table != "reference_offsets")
    throw InvalidArgument(Message("unknown history table '", table, "'"));
  Statement s(db_, "SELECT COUNT(*) FROM " + table, path_);
  s.Step();
  return s.Int(0);
}

void History::CheckSite(const std::string& site) {
  if (site.empty()) return;
  const std::optional<std::string> held = Meta("site");
  if (!held || held->empty()) {
    SetMeta("site", site);
    return;
  }
  if (*held != site)
    throw ConfigError(
        Message("the recording is of site '", site, "' but the history '", path_, "' is of site '",
                *held, "'; nothing written (--database names the history of site '", site, "')"));
}

void History::CheckReference() const {
  const int64_t observations = CountRows("observations");
  if (observations > 0 && !Meta("datum_stamp"))
    Fail(Message("holds ", observations,
                 " observations but no reference epoch (meta datum_stamp missing); refused, "
                 "nothing written (process_bag --new-reference starts a new reference)"));
}

void History::StartNewReference() {
  Exec("BEGIN IMMEDIATE");
  try {
    Exec("INSERT OR REPLACE INTO meta(key, value) VALUES('datum_stamp', '')");
    Exec(
        "DELETE FROM meta WHERE key IN ('reference_epoch', 'reference_stamp', "
        "'reference_recording')");
    Exec("DELETE FROM reference_offsets");
    Exec(kSavedStates);
    Exec("DELETE FROM saved_states");
    Exec("COMMIT");
  } catch (...) {
    sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
    throw;
  }
}

}  // namespace deformation
}  // namespace slope_monitor
