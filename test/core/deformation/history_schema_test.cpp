// A history with an unknown (negative) schema version is refused and left
// byte for byte untouched (issue 22: user_version = -3 was accepted and
// migrated).
#include <sqlite3.h>
#include <unistd.h>

#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/history.h"

namespace slope_monitor {
namespace deformation {
namespace {

std::string Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

TEST(HistorySchema, NegativeUserVersionIsRefusedUntouched) {
  const std::string path = "/tmp/sm_history_schema_" + std::to_string(getpid()) + ".db";
  std::remove(path.c_str());
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(path.c_str(), &db), SQLITE_OK);
    ASSERT_EQ(
        sqlite3_exec(
            db, "CREATE TABLE meta(key TEXT PRIMARY KEY, value TEXT); PRAGMA user_version = -3;",
            nullptr, nullptr, nullptr),
        SQLITE_OK);
    sqlite3_close(db);
  }
  const std::string before = Bytes(path);
  try {
    History h(path);
    FAIL() << "user_version -3 was accepted";
  } catch (const IoError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(path), std::string::npos) << what;
    EXPECT_NE(what.find("unknown schema version -3"), std::string::npos) << what;
  }
  EXPECT_EQ(Bytes(path), before);
  std::ifstream wal(path + "-wal");
  EXPECT_FALSE(wal.good()) << "a WAL file was created";
  std::remove(path.c_str());
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
