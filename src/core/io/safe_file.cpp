#include "slope_monitor/core/io/safe_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#include "slope_monitor/core/common/error.h"

namespace slope_monitor {
namespace io {
namespace {

constexpr size_t kMaxNameBytes = 255;  // NAME_MAX on Linux file systems

// Closes a file descriptor when it leaves scope.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() { Reset(-1); }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  void Reset(int fd) {
    if (fd_ >= 0) close(fd_);
    fd_ = fd;
  }

 private:
  int fd_;
};

std::string Errno() { return std::strerror(errno); }

// Escapes control characters so a refusal message stays on one line.
std::string Printable(const std::string& s) {
  std::string out;
  for (unsigned char c : s) {
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

std::string RealPath(const std::string& path) {
  char buf[PATH_MAX];
  if (!realpath(path.c_str(), buf))
    throw IoError(Message("cannot resolve '", path, "': ", Errno()));
  return buf;
}

void MakeDirectories(const std::string& path) {
  for (size_t pos = 1; pos <= path.size(); ++pos) {
    if (pos != path.size() && path[pos] != '/') continue;
    const std::string d = path.substr(0, pos);
    if (mkdir(d.c_str(), 0755) != 0 && errno != EEXIST)
      throw IoError(Message("cannot create folder '", d, "': ", Errno()));
  }
}

}  // namespace

std::string IdProblem(const std::string& id) {
  if (id.empty()) return "is empty";
  if (id.size() > kMaxIdLength)
    return Message("has ", id.size(), " characters (at most ", kMaxIdLength, ")");
  for (unsigned char c : id) {
    if (c < 0x20 || c > 0x7e) {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "0x%02x", c);
      return Message("contains the non-printable character ", buf);
    }
  }
  return "";
}

void CheckFileName(const std::string& name, const std::string& what) {
  const std::string shown = Printable(name);
  if (name.empty()) throw InvalidArgument(Message(what, " is empty"));
  if (name == "." || name == "..")
    throw InvalidArgument(
        Message(what, " '", shown, "' is refused: '.' and '..' could leave the folder"));
  if (name.size() > kMaxNameBytes)
    throw InvalidArgument(Message(what, " '", shown.substr(0, 40), "...' has ", name.size(),
                                  " bytes (at most ", kMaxNameBytes, ")"));
  for (unsigned char c : name) {
    if (c == '/') throw InvalidArgument(Message(what, " '", shown, "' contains '/'"));
    if (c < 0x20 || c == 0x7f)
      throw InvalidArgument(
          Message(what, " '", shown, "' contains a control character (newline, tab, ...)"));
  }
}

std::string ResolveSubfolder(const std::string& root, const std::string& subfolder) {
  if (root.empty()) throw InvalidArgument("the report folder (root) is empty");
  MakeDirectories(root);
  std::string real_root = RealPath(root);
  if (subfolder.empty()) return real_root;
  const std::string what = Message("subfolder '", Printable(subfolder), "'");
  if (subfolder.front() == '/')
    throw InvalidArgument(
        Message(what, " is an absolute path; name a folder inside '", real_root, "'"));
  std::vector<std::string> parts;
  for (size_t a = 0; a <= subfolder.size();) {
    const size_t b = std::min(subfolder.find('/', a), subfolder.size());
    if (b > a) parts.push_back(subfolder.substr(a, b - a));
    a = b + 1;
  }
  for (const std::string& part : parts) CheckFileName(part, Message(what, ": name"));

  Fd dir(open(real_root.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dir.get() < 0)
    throw IoError(Message("cannot open report folder '", real_root, "': ", Errno()));
  std::string walked = real_root;
  for (const std::string& part : parts) {
    walked += "/" + part;
    if (mkdirat(dir.get(), part.c_str(), 0755) != 0 && errno != EEXIST)
      throw IoError(Message(what, ": cannot create '", walked, "': ", Errno()));
    const int next =
        openat(dir.get(), part.c_str(), O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (next < 0) {
      struct stat st;
      if (fstatat(dir.get(), part.c_str(), &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode))
        throw InvalidArgument(
            Message(what, ": '", walked, "' is a symbolic link; links are not followed"));
      throw InvalidArgument(Message(what, ": '", walked, "' is not a folder: ", Errno()));
    }
    dir.Reset(next);
  }
  // Checked again after resolution: the folder really lies inside the root.
  std::string resolved = RealPath(real_root + "/" + subfolder);
  if (resolved.compare(0, real_root.size() + 1, real_root + "/") != 0)
    throw InvalidArgument(
        Message(what, " resolves to '", resolved, "', outside '", real_root, "'"));
  return resolved;
}

void CheckFolderWritable(const std::string& folder, const std::string& what) {
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec)
    throw IoError(Message(what, " '", Printable(folder), "' cannot be created: ", ec.message()));
  std::string probe = folder + "/.write_probe.XXXXXX";
  std::vector<char> buf(probe.begin(), probe.end());
  buf.push_back('\0');
  Fd fd(mkstemp(buf.data()));
  if (fd.get() < 0)
    throw IoError(Message(what, " '", Printable(folder), "' is not writable: ", Errno()));
  const bool wrote = write(fd.get(), "x", 1) == 1;
  const std::string why = wrote ? "" : Errno();
  unlink(buf.data());
  if (!wrote) throw IoError(Message(what, " '", Printable(folder), "' is not writable: ", why));
}

void WriteFileAtomically(const std::string& path, const std::string& content) {
  const size_t slash = path.rfind('/');
  const std::string folder =
      slash == std::string::npos ? "." : path.substr(0, slash == 0 ? 1 : slash);
  const std::string name = slash == std::string::npos ? path : path.substr(slash + 1);
  CheckFileName(name, Message("file name of '", Printable(path), "'"));
  // mkstemp opens with O_CREAT|O_EXCL and a random suffix: never a planted link.
  std::string tmp = folder + "/." + name.substr(0, 200) + ".XXXXXX";
  std::vector<char> buf(tmp.begin(), tmp.end());
  buf.push_back('\0');
  Fd fd(mkstemp(buf.data()));
  if (fd.get() < 0)
    throw IoError(
        Message("cannot create a temporary file in '", folder, "' for '", path, "': ", Errno()));
  tmp = buf.data();
  auto fail = [&](const std::string& step) {
    const std::string why = Errno();
    unlink(tmp.c_str());
    throw IoError(Message("cannot write '", path, "' (", step, " of '", tmp, "'): ", why));
  };
  if (fchmod(fd.get(), 0644) != 0) fail("chmod");
  for (size_t done = 0; done < content.size();) {
    const ssize_t n = write(fd.get(), content.data() + done, content.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) fail("write");
    done += static_cast<size_t>(n);
  }
  if (fsync(fd.get()) != 0) fail("fsync");
  fd.Reset(-1);
  if (std::rename(tmp.c_str(), path.c_str()) != 0) fail("rename");
}

}  // namespace io
}  // namespace slope_monitor
