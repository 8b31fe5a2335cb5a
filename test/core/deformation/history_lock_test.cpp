// One writer per history (issue 38): a second History on the same file, in
// another process or in this one, is refused at once with HistoryInUse
// naming the database, the lock file and the holder's process id; the lock
// ends with its History, also when the database itself is refused.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/deformation/history.h"

namespace slope_monitor {
namespace deformation {
namespace {

namespace fs = std::filesystem;

class HistoryLockTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("sm_history_lock_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    db_ = (dir_ / "history.db").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  // The HistoryInUse text of opening db_, "" when it opened.
  std::string InUse() const {
    try {
      History h(db_);
    } catch (const HistoryInUse& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
  std::string db_;
};

TEST_F(HistoryLockTest, SecondWriterInThisProcessIsRefused) {
  {
    History first(db_);
    const auto start = std::chrono::steady_clock::now();
    const std::string why = InUse();
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 0.5);
    EXPECT_NE(
        why.find("history database '" + db_ + "' is in use by process " + std::to_string(getpid())),
        std::string::npos)
        << why;
    EXPECT_NE(why.find("writer lock '" + db_ + ".lock'"), std::string::npos) << why;
    EXPECT_EQ(first.CountRows("batches"), 0);
  }
  EXPECT_EQ(InUse(), "") << "the lock outlived its History";
}

TEST_F(HistoryLockTest, WriterInAnotherProcessIsNamedByItsPid) {
  int ready[2], release[2];
  ASSERT_EQ(pipe(ready), 0);
  ASSERT_EQ(pipe(release), 0);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    int status = 0;
    try {
      History h(db_);
      char c = 1;
      if (write(ready[1], &c, 1) != 1) status = 2;
      if (read(release[0], &c, 1) < 0) status = 3;
    } catch (...) {
      status = 1;
    }
    _exit(status);
  }
  char c = 0;
  ASSERT_EQ(read(ready[0], &c, 1), 1) << "the child could not open the history";
  const std::string why = InUse();
  EXPECT_NE(why.find("is in use by process " + std::to_string(child) + " ("), std::string::npos)
      << why;
  std::ifstream lock(db_ + ".lock");
  int pid = 0;
  lock >> pid;
  EXPECT_EQ(pid, child);
  // kill -9: the kernel releases the lock with the process.
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  EXPECT_EQ(InUse(), "");
  History after(db_);  // and this process now holds it
  EXPECT_EQ(after.schema_version(), History::kSchemaVersion);
}

TEST_F(HistoryLockTest, RefusedDatabaseReleasesTheLock) {
  std::ofstream(db_) << "this is not an SQLite database, and it is long enough to be read as one\n";
  for (int attempt = 0; attempt < 2; ++attempt) {
    try {
      History h(db_);
      FAIL() << "a text file was opened as a history";
    } catch (const HistoryInUse& e) {
      FAIL() << "the refused first attempt kept the lock: " << e.what();
    } catch (const IoError& e) {
      EXPECT_NE(std::string(e.what()).find("not a SQLite database"), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace deformation
}  // namespace slope_monitor
