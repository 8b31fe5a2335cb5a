// Confinement of written files (issue 22): a requested subfolder with "..",
// an absolute path, a symbolic link on the way, or a control character is
// refused with the reason, and nothing is created outside the root; an
// atomic write replaces a link at the final name instead of following it
// and leaves no temporary behind.
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "slope_monitor/core/common/error.h"
#include "slope_monitor/core/io/safe_file.h"

namespace slope_monitor {
namespace io {
namespace {

namespace fs = std::filesystem;

class SafeFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    base_ = fs::temp_directory_path() /
            ("sm_safe_file_" + std::to_string(getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(base_);
    fs::create_directories(base_ / "outside");
    root_ = (base_ / "reports").string();
    fs::create_directories(root_);
  }
  void TearDown() override { fs::remove_all(base_); }

  // The refusal's text, or "" when nothing was thrown.
  std::string Refusal(const std::string& subfolder) {
    try {
      ResolveSubfolder(root_, subfolder);
    } catch (const InvalidArgument& e) {
      return e.what();
    }
    return "";
  }
  size_t EntriesUnder(const fs::path& p) {
    size_t n = 0;
    for (auto it = fs::recursive_directory_iterator(p); it != fs::recursive_directory_iterator();
         ++it)
      ++n;
    return n;
  }
  static std::string Read(const fs::path& p) {
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }

  fs::path base_;
  std::string root_;
};

TEST_F(SafeFileTest, PlainSubfoldersAreCreatedInside) {
  const std::string dir = ResolveSubfolder(root_, "typhoon/day2");
  EXPECT_EQ(dir, fs::canonical(root_).string() + "/typhoon/day2");
  EXPECT_TRUE(fs::is_directory(dir));
  EXPECT_EQ(ResolveSubfolder(root_, ""), fs::canonical(root_).string());
  EXPECT_EQ(ResolveSubfolder(root_, "typhoon//day2/"), dir);  // empty names are skipped
}

TEST_F(SafeFileTest, DotDotIsRefused) {
  const std::string why = Refusal("../outside/x");
  EXPECT_NE(why.find("'..'"), std::string::npos) << why;
  EXPECT_NE(Refusal("a/../../outside").find("'..'"), std::string::npos);
  EXPECT_NE(Refusal("./a").find("'.'"), std::string::npos);
  EXPECT_FALSE(fs::exists(base_ / "outside" / "x"));
  EXPECT_FALSE(
      fs::exists(fs::path(root_) / "a"));  // names are all checked before anything is created
  EXPECT_EQ(EntriesUnder(base_ / "outside"), 0u);
}

TEST_F(SafeFileTest, AbsolutePathIsRefused) {
  const std::string target = (base_ / "outside" / "abs").string();
  const std::string why = Refusal(target);
  EXPECT_NE(why.find("absolute path"), std::string::npos) << why;
  EXPECT_FALSE(fs::exists(target));
}

TEST_F(SafeFileTest, SymlinkedFolderIsRefused) {
  fs::create_directory_symlink(base_ / "outside", fs::path(root_) / "link");
  std::string why = Refusal("link");
  EXPECT_NE(why.find("symbolic link"), std::string::npos) << why;
  why = Refusal("link/deeper");
  EXPECT_NE(why.find("symbolic link"), std::string::npos) << why;
  EXPECT_EQ(EntriesUnder(base_ / "outside"), 0u);
  // A link to a folder inside the root is refused as well: links are never followed.
  fs::create_directory(fs::path(root_) / "real");
  fs::create_directory_symlink(fs::path(root_) / "real", fs::path(root_) / "alias");
  EXPECT_NE(Refusal("alias").find("symbolic link"), std::string::npos);
}

TEST_F(SafeFileTest, NewlineAndControlCharactersAreRefused) {
  std::string why = Refusal("evil\nname");
  EXPECT_NE(why.find("control character"), std::string::npos) << why;
  EXPECT_EQ(why.find('\n'), std::string::npos) << "the refusal must stay on one line";
  EXPECT_NE(Refusal("tab\there").find("control character"), std::string::npos);
  EXPECT_NE(Refusal(std::string(300, 'a')).find("300 bytes"), std::string::npos);
  EXPECT_EQ(EntriesUnder(root_), 0u);
  EXPECT_THROW(WriteFileAtomically(root_ + "/bad\nname.csv", "x"), InvalidArgument);
  EXPECT_EQ(EntriesUnder(root_), 0u);
}

TEST_F(SafeFileTest, AtomicWriteReplacesAPlantedLinkAndLeavesNoTemporary) {
  const fs::path victim = base_ / "outside" / "victim.txt";
  std::ofstream(victim) << "precious";
  const fs::path file = fs::path(root_) / "deformation.csv";
  fs::create_symlink(victim, file);  // a link planted at the final name
  // ... and at the name the old writer used for its temporary.
  fs::create_symlink(victim, fs::path(root_) / ("deformation.csv.tmp-" + std::to_string(getpid())));
  WriteFileAtomically(file.string(), "id,x\n");
  EXPECT_EQ(Read(victim), "precious");
  EXPECT_FALSE(fs::is_symlink(file));
  EXPECT_EQ(Read(file), "id,x\n");
  EXPECT_EQ((fs::status(file).permissions() & fs::perms::others_read), fs::perms::others_read);
  EXPECT_EQ(EntriesUnder(root_), 2u);  // the file and the old-style planted link: no temporary left
}

TEST_F(SafeFileTest, MissingFolderNamesThePath) {
  const std::string path = root_ + "/no_such_dir/x.csv";
  try {
    WriteFileAtomically(path, "x");
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

// Fail early (issue 38): a folder that can be written is created and left
// empty; one that cannot (under a regular file: refused even for root) is
// named with the option and the reason.
TEST_F(SafeFileTest, CheckFolderWritableCreatesOrNamesTheFolder) {
  const std::string ok = root_ + "/a/b";
  CheckFolderWritable(ok, "--report-dir");
  EXPECT_TRUE(fs::is_directory(ok));
  EXPECT_EQ(EntriesUnder(ok), 0u) << "the probe file was left behind";
  std::ofstream(root_ + "/file") << "x";
  const std::string bad = root_ + "/file/reports";
  try {
    CheckFolderWritable(bad, "--report-dir");
    FAIL() << "no exception";
  } catch (const IoError& e) {
    EXPECT_EQ(std::string(e.what()),
              "--report-dir '" + bad + "' cannot be created: Not a directory");
  }
}

TEST(IdProblem, SixtyFourPrintableCharactersAtMost) {
  EXPECT_EQ(IdProblem("tag36h11/5"), "");
  EXPECT_EQ(IdProblem(std::string(64, 'p')), "");
  EXPECT_EQ(IdProblem(std::string(65, 'p')), "has 65 characters (at most 64)");
  EXPECT_EQ(IdProblem(""), "is empty");
  EXPECT_EQ(IdProblem("a\nb"), "contains the non-printable character 0x0a");
  EXPECT_EQ(IdProblem("caf\xc3\xa9"), "contains the non-printable character 0xc3");
}

}  // namespace
}  // namespace io
}  // namespace slope_monitor
