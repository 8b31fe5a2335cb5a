// deformation_summary's reader (EvaluateHistory) refuses a history that
// fails PRAGMA integrity_check or carries an unknown schema version, naming
// the file, and modifies neither (issue 22: it printed a table and exited 0).
#include <sqlite3.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/evaluation/deformation_truth.h"

namespace slope_monitor {
namespace evaluation {
namespace {

std::string Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// A rollback-journal SQLite file with an index over 2000 rows (several
// pages) and the given user_version.
std::string MakeDb(const std::string& name, int user_version) {
  const std::string path = "/tmp/sm_history_checks_" + std::to_string(getpid()) + "_" + name;
  std::remove(path.c_str());
  sqlite3* db = nullptr;
  EXPECT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
  std::string sql =
      "PRAGMA page_size = 1024; CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT); BEGIN;";
  for (int i = 0; i < 2000; ++i)
    sql += "INSERT INTO meta VALUES('key_" + std::to_string(i) + "', 'value " +
           std::to_string(i * 7) + "');";
  sql += "COMMIT; PRAGMA user_version = " + std::to_string(user_version) + ";";
  EXPECT_EQ(sqlite3_exec(db, sql.c_str(), nullptr, nullptr, nullptr), SQLITE_OK);
  sqlite3_close(db);
  return path;
}

std::string Refusal(const std::string& path) {
  try {
    EvaluateHistory(path, sim::SurveyTruth());
  } catch (const IoError& e) {
    return e.what();
  }
  return "";
}

TEST(HistoryChecks, UnknownSchemaVersionIsRefused) {
  const std::string path = MakeDb("v-3.db", -3);
  const std::string before = Bytes(path);
  const std::string why = Refusal(path);
  EXPECT_NE(why.find(path), std::string::npos) << why;
  EXPECT_NE(why.find("schema version -3"), std::string::npos) << why;
  EXPECT_EQ(Bytes(path), before);
  std::remove(path.c_str());
}

TEST(HistoryChecks, IntegrityCheckFailureIsRefused) {
  const std::string path = MakeDb("damaged.db", 2);
  std::string bytes = Bytes(path);
  ASSERT_GT(bytes.size(), 20u * 1024);
  // Overwrite the cell area of page 10 (a b-tree page) with a pattern:
  // the header stays valid, the tree does not.
  for (size_t k = 9 * 1024 + 200; k < 10 * 1024; ++k) bytes[k] = static_cast<char>(k * 37);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
  const std::string why = Refusal(path);
  EXPECT_NE(why.find(path), std::string::npos) << why;
  EXPECT_NE(why.find("integrity_check"), std::string::npos) << why;
  EXPECT_EQ(Bytes(path), bytes);
  std::remove(path.c_str());
}

}  // namespace
}  // namespace evaluation
}  // namespace slope_monitor
