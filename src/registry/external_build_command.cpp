#include "textile_handling/registry/external_build_command.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <stdexcept>

extern char** environ;

namespace textile_handling {
namespace registry {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kMaxLine = 64 * 1024;
constexpr std::size_t kTailLines = 20;

// Splits the bytes read into lines; a line longer than kMaxLine is delivered cut.
class LineSplitter {
 public:
  explicit LineSplitter(const std::function<void(const std::string&)>& on_line, std::vector<std::string>* tail)
      : on_line_(on_line), tail_(tail) {}
  void add(const char* data, std::size_t n) {
    for (std::size_t k = 0; k < n; ++k) {
      if (data[k] == '\n') {
        flush();
      } else if (partial_.size() < kMaxLine) {
        partial_ += data[k];
      }
    }
  }
  void flush() {
    if (on_line_) on_line_(partial_);
    tail_->push_back(partial_);
    if (tail_->size() > kTailLines) tail_->erase(tail_->begin());
    partial_.clear();
  }
  bool pending() const { return !partial_.empty(); }

 private:
  const std::function<void(const std::string&)>& on_line_;
  std::vector<std::string>* tail_;
  std::string partial_;
};

}  // namespace

ExternalCommandOutcome runExternalCommand(const std::vector<std::string>& argv,
                                          const std::function<void(const std::string& line)>& on_line,
                                          const std::function<bool()>& should_stop, double grace_s) {
  if (argv.empty() || argv.front().empty()) throw std::invalid_argument("runExternalCommand: empty command");
  ExternalCommandOutcome out;
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0) {
    out.error = std::string("pipe: ") + std::strerror(errno);
    return out;
  }
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  // A process group of its own: the stop signal reaches mpirun and everything it started here, and a
  // terminal's Ctrl-C to the node does not reach the build.
  posix_spawnattr_setpgroup(&attr, 0);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGTERM);
  sigaddset(&defaults, SIGINT);
  sigaddset(&defaults, SIGPIPE);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = ::posix_spawnp(&pid, args[0], &actions, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    out.error = "cannot run '" + argv.front() + "': " + std::strerror(rc);
    return out;
  }
  out.started = true;

  LineSplitter lines(on_line, &out.tail);
  bool pipe_open = true, ended = false;
  int status = 0;
  Clock::time_point term_sent{}, ended_at{};
  // Reaps the command if it has ended; otherwise sends the stop signals when they are due.
  const auto check = [&] {
    if (ended) return;
    if (::waitpid(pid, &status, WNOHANG) == pid) {
      ended = true;
      ended_at = Clock::now();
      return;
    }
    if (should_stop && !out.stopped && should_stop()) {
      out.stopped = true;
      term_sent = Clock::now();
      ::kill(-pid, SIGTERM);
    }
    if (out.stopped && Clock::now() - term_sent > std::chrono::duration<double>(grace_s)) ::kill(-pid, SIGKILL);
  };
  char buf[8192];
  while (pipe_open) {
    pollfd p{fds[0], POLLIN, 0};
    if (::poll(&p, 1, 100) > 0) {
      const ssize_t n = ::read(fds[0], buf, sizeof buf);
      if (n > 0) {
        lines.add(buf, static_cast<std::size_t>(n));
      } else if (n == 0 || (errno != EINTR && errno != EAGAIN)) {
        pipe_open = false;
      }
    }
    check();
    // A process the command left behind may hold the pipe open: give it a second, then stop reading.
    if (ended && Clock::now() - ended_at > std::chrono::seconds(1)) break;
  }
  ::close(fds[0]);
  if (lines.pending()) lines.flush();
  while (!ended) {  // the output closed before the command ended
    check();
    if (!ended) ::usleep(100 * 1000);
  }
  if (out.stopped) ::kill(-pid, SIGKILL);  // whatever of the group is left
  out.exited = WIFEXITED(status);
  out.exit_code = out.exited ? WEXITSTATUS(status) : -1;
  out.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  return out;
}

std::string describeOutcome(const ExternalCommandOutcome& o) {
  if (!o.started) return o.error;
  if (o.exited) return "exit status " + std::to_string(o.exit_code);
  return "killed by signal " + std::to_string(o.signal) + " (" + strsignal(o.signal) + ")";
}

}  // namespace registry
}  // namespace textile_handling
