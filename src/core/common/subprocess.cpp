#include "slope_monitor/core/common/subprocess.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "slope_monitor/core/common/error.h"

extern char** environ;

namespace slope_monitor {
namespace {

constexpr size_t kMaxInput = 4096;  // <= PIPE_BUF

struct Fd {
  int fd = -1;
  ~Fd() { Close(); }
  void Close() {
    if (fd >= 0) close(fd);
    fd = -1;
  }
};

}  // namespace

RunResult RunProgram(const std::vector<std::string>& argv, const std::string& input,
                     double timeout) {
  if (argv.empty() || argv[0].empty()) throw InvalidArgument("RunProgram: no program given");
  if (input.size() > kMaxInput)
    throw InvalidArgument(
        Message("RunProgram: input of ", input.size(), " bytes exceeds ", kMaxInput));
  RunResult result;
  int in_fds[2], out_fds[2];
  if (pipe2(in_fds, O_CLOEXEC) != 0)
    return {"", Message("cannot create a pipe: ", std::strerror(errno))};
  Fd in_read{in_fds[0]}, in_write{in_fds[1]};
  if (pipe2(out_fds, O_CLOEXEC) != 0)
    return {"", Message("cannot create a pipe: ", std::strerror(errno))};
  Fd out_read{out_fds[0]}, out_write{out_fds[1]};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in_read.fd, STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, out_write.fd, STDOUT_FILENO);
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  const int spawn_error =
      posix_spawnp(&pid, argv[0].c_str(), &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawn_error != 0) return {"", Message("cannot start it: ", std::strerror(spawn_error))};
  out_write.Close();
  fcntl(out_read.fd, F_SETFL, O_NONBLOCK);  // a grandchild holding stdout open must not stall us
  // The read end of stdin stays open here until the input is in the pipe, so
  // the write cannot raise SIGPIPE even when the program exits without reading.
  const ssize_t written = input.empty() ? 0 : write(in_write.fd, input.data(), input.size());
  in_write.Close();
  in_read.Close();
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout);
  bool open = true;
  int status = 0;
  while (true) {
    if (open) {  // collect stdout while waiting (a full pipe would stall the program)
      pollfd p{out_read.fd, POLLIN, 0};
      if (poll(&p, 1, 10) > 0) {
        char buffer[4096];
        const ssize_t n = read(out_read.fd, buffer, sizeof(buffer));
        if (n > 0) result.output.append(buffer, static_cast<size_t>(n));
        if (n == 0) open = false;
      }
    } else {
      usleep(10000);
    }
    const pid_t r = waitpid(pid, &status, WNOHANG);
    if (r == pid && !open) break;
    if (r == pid) {  // exited: drain what is left
      char buffer[4096];
      ssize_t n;
      while ((n = read(out_read.fd, buffer, sizeof(buffer))) > 0)
        result.output.append(buffer, static_cast<size_t>(n));
      break;
    }
    if (r < 0) return {result.output, Message("waiting for it failed: ", std::strerror(errno))};
    if (std::chrono::steady_clock::now() >= deadline) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      result.failure = Message("no exit within ", timeout, " s (killed)");
      return result;
    }
  }
  if (written != static_cast<ssize_t>(input.size()))
    result.failure = "its input could not be written to its stdin";
  else if (WIFSIGNALED(status))
    result.failure = Message("killed by signal ", WTERMSIG(status));
  else if (WIFEXITED(status) && WEXITSTATUS(status) != 0)
    result.failure = Message("exit status ", WEXITSTATUS(status));
  return result;
}

}  // namespace slope_monitor
