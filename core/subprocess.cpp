#include "core/subprocess.h"

#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <mutex>
#include <utility>
#include <poll.h>
#include <spawn.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include "core/errors.h"

extern char** environ;

namespace dnb {

namespace {

using Clock = std::chrono::steady_clock;

std::string sys_reason(int err) { return std::strerror(err); }

void close_fd(int& fd) {
  if (fd >= 0) ::close(fd);
  fd = -1;
}

// The remaining milliseconds to `deadline`, at least 0 (rounded up so that a wait never spins).
int remaining_ms(Clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::microseconds>(deadline - Clock::now()).count();
  return left <= 0 ? 0 : int(std::min<long long>((left + 999) / 1000, 1 << 30));
}

Clock::time_point deadline_after(double seconds) {
  const double s = std::min(seconds, 1e7);  // about 115 days: "no limit" without overflow
  return Clock::now() + std::chrono::microseconds(static_cast<long long>(s * 1e6));
}

}  // namespace

std::string ExitStatus::describe() const {
  if (exited) return fmt::format("exited with status {}", code);
  const char* name = ::strsignal(signal);
  return fmt::format("was killed by signal {} ({})", signal, name ? name : "unknown");
}

Subprocess::Subprocess(ProcessOptions options) : opt_(std::move(options)) {
  if (opt_.argv.empty() || opt_.argv[0].empty()) throw WorkError("cannot start a process: empty command");
  // A worker that dies while the harness writes its request must give a failed write, not kill
  // the harness with SIGPIPE. The harness writes no pipes or sockets of its own otherwise.
  static std::once_flag ignore_sigpipe;
  std::call_once(ignore_sigpipe, [] { std::signal(SIGPIPE, SIG_IGN); });

  int in[2] = {-1, -1}, out[2] = {-1, -1}, err[2] = {-1, -1};
  auto fail = [&](const std::string& what, int e) {
    for (int* p : {in, out, err}) close_fd(p[0]), close_fd(p[1]);
    throw WorkError(fmt::format("cannot start '{}': {}: {}", opt_.argv[0], what, sys_reason(e)));
  };
  if (::pipe2(err, O_CLOEXEC) != 0) fail("pipe", errno);
  if (opt_.pipe_stdin && ::pipe2(in, O_CLOEXEC) != 0) fail("pipe", errno);
  if (opt_.pipe_stdout && ::pipe2(out, O_CLOEXEC) != 0) fail("pipe", errno);

  posix_spawn_file_actions_t fa;
  posix_spawnattr_t attr;
  posix_spawn_file_actions_init(&fa);
  posix_spawnattr_init(&attr);
  if (opt_.pipe_stdin) posix_spawn_file_actions_adddup2(&fa, in[0], 0);
  else posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&fa, opt_.pipe_stdout ? out[1] : err[1], 1);
  posix_spawn_file_actions_adddup2(&fa, err[1], 2);
  if (!opt_.cwd.empty()) posix_spawn_file_actions_addchdir_np(&fa, opt_.cwd.c_str());
  // Its own process group (a timeout kills the group: the program and whatever it started), the
  // default disposition of the signals the harness changes, and no blocked signals.
  sigset_t def, mask;
  sigemptyset(&def);
  sigaddset(&def, SIGPIPE);
  sigaddset(&def, SIGINT);
  sigaddset(&def, SIGTERM);
  sigemptyset(&mask);
  posix_spawnattr_setsigdefault(&attr, &def);
  posix_spawnattr_setsigmask(&attr, &mask);
  posix_spawnattr_setpgroup(&attr, 0);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGDEF | POSIX_SPAWN_SETSIGMASK);

  std::vector<std::string> env_strings;
  for (char** e = environ; e && *e; ++e) {
    const std::string kv = *e;
    const std::string key = kv.substr(0, kv.find('='));
    if (!opt_.env.count(key)) env_strings.push_back(kv);
  }
  for (const auto& [k, v] : opt_.env) env_strings.push_back(k + "=" + v);
  std::vector<char*> envp, argv;
  for (auto& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);
  for (auto& s : opt_.argv) argv.push_back(const_cast<char*>(s.c_str()));
  argv.push_back(nullptr);

  const bool search = opt_.argv[0].find('/') == std::string::npos;
  const int rc = search ? ::posix_spawnp(&pid_, argv[0], &fa, &attr, argv.data(), envp.data())
                        : ::posix_spawn(&pid_, argv[0], &fa, &attr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    pid_ = -1;
    fail(opt_.cwd.empty() ? "spawn" : fmt::format("spawn in '{}'", opt_.cwd), rc);
  }
  close_fd(in[0]);
  close_fd(out[1]);
  close_fd(err[1]);
  in_ = in[1];
  out_ = out[0];
  err_ = err[0];
  for (int fd : {out_, err_})
    if (fd >= 0) ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) | O_NONBLOCK);
  // A pidfd makes the end of the process pollable beside its pipes (Linux 5.3); without one
  // the wait polls the process every 10 ms instead.
  pidfd_ = int(::syscall(SYS_pidfd_open, pid_, 0));
}

Subprocess::~Subprocess() {
  close_fd(in_);
  if (running()) kill_group();
  close_fd(out_);
  close_fd(err_);
  close_fd(pidfd_);
}

bool Subprocess::write_line(const std::string& line) {
  if (in_ < 0) return false;
  const std::string data = line + "\n";
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(in_, data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;  // EPIPE: the process closed its stdin or died
    done += std::size_t(n);
  }
  return true;
}

void Subprocess::close_stdin() { close_fd(in_); }

void Subprocess::take_log(std::string& buffer, bool flush) {
  std::size_t start = 0, nl;
  auto emit = [&](std::string line) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (opt_.on_log_line) opt_.on_log_line(line);
    tail_.push_back(std::move(line));
    while (tail_.size() > opt_.tail_lines) tail_.pop_front();
  };
  while ((nl = buffer.find('\n', start)) != std::string::npos) {
    emit(buffer.substr(start, nl - start));
    start = nl + 1;
  }
  buffer.erase(0, start);
  if (flush && !buffer.empty()) {
    emit(buffer);
    buffer.clear();
  }
}

void Subprocess::reap(bool block) {
  if (status_ || pid_ < 0) return;
  int st = 0;
  pid_t r;
  do r = ::waitpid(pid_, &st, block ? 0 : WNOHANG);
  while (r < 0 && errno == EINTR);
  if (r != pid_) return;
  ExitStatus s;
  s.exited = WIFEXITED(st);
  s.code = s.exited ? WEXITSTATUS(st) : 0;
  s.signal = WIFSIGNALED(st) ? WTERMSIG(st) : 0;
  status_ = s;
}

void Subprocess::pump(int timeout_ms) {
  pollfd fds[3];
  int n = 0, out_i = -1, err_i = -1, pid_i = -1;
  if (out_ >= 0) out_i = n, fds[n++] = {out_, POLLIN, 0};
  if (err_ >= 0) err_i = n, fds[n++] = {err_, POLLIN, 0};
  if (running() && pidfd_ >= 0) pid_i = n, fds[n++] = {pidfd_, POLLIN, 0};
  if (running() && pidfd_ < 0) timeout_ms = timeout_ms < 0 ? 10 : std::min(timeout_ms, 10);
  if (n == 0) {
    if (running()) ::usleep(useconds_t(std::max(0, timeout_ms)) * 1000);
  } else if (::poll(fds, nfds_t(n), timeout_ms) < 0 && errno != EINTR) {
    throw WorkError(fmt::format("'{}': poll: {}", opt_.argv[0], sys_reason(errno)));
  }
  auto drain = [&](int& fd, std::string& buf) {
    char chunk[65536];
    for (;;) {
      const ssize_t r = ::read(fd, chunk, sizeof chunk);
      if (r > 0) {
        buf.append(chunk, std::size_t(r));
        continue;
      }
      if (r < 0 && errno == EINTR) continue;
      if (r == 0) close_fd(fd);  // EOF
      return;                    // EAGAIN: nothing more now
    }
  };
  if (out_i >= 0 && (fds[out_i].revents & (POLLIN | POLLHUP | POLLERR))) {
    drain(out_, out_buf_);
    std::size_t start = 0, nl;
    while ((nl = out_buf_.find('\n', start)) != std::string::npos) {
      lines_.push_back(out_buf_.substr(start, nl - start));
      start = nl + 1;
    }
    out_buf_.erase(0, start);
    if (out_ < 0 && !out_buf_.empty()) lines_.push_back(std::exchange(out_buf_, {}));
  }
  if (err_i >= 0 && (fds[err_i].revents & (POLLIN | POLLHUP | POLLERR))) {
    drain(err_, err_buf_);
    take_log(err_buf_, err_ < 0);
  }
  if (pid_i >= 0 ? (fds[pid_i].revents & POLLIN) != 0 : running()) reap(false);
}

Subprocess::Read Subprocess::read_line(std::string& line, double timeout_seconds) {
  const auto deadline = deadline_after(timeout_seconds);
  for (;;) {
    if (!lines_.empty()) {
      line = std::move(lines_.front());
      lines_.pop_front();
      return Read::Line;
    }
    if (out_ < 0) return Read::Eof;
    const int left = remaining_ms(deadline);
    if (left == 0) return Read::Timeout;
    // The process has ended but something it started still holds stdout: do not wait for that.
    if (!running()) {
      pump(0);
      if (lines_.empty() && out_ >= 0) return Read::Eof;
      continue;
    }
    pump(left);
  }
}

std::optional<ExitStatus> Subprocess::wait(double timeout_seconds) {
  const auto deadline = deadline_after(timeout_seconds);
  while (running()) {
    const int left = remaining_ms(deadline);
    if (left == 0) return std::nullopt;
    pump(left);
  }
  // What it wrote just before it ended (whatever it started may keep the pipes open: no wait).
  pump(0);
  take_log(err_buf_, true);
  return status_;
}

ExitStatus Subprocess::kill_group() {
  if (running()) {
    ::kill(-pid_, SIGKILL);
    reap(true);
  }
  pump(0);
  take_log(err_buf_, true);
  return status_ ? *status_ : ExitStatus{};
}

}  // namespace dnb
