// A child process with pipes and deadlines, for plug-in denoisers (methods/plugins.h): started
// in its own process group (so a timeout kills everything it started), stdout read by lines
// with a deadline, stderr forwarded line by line and its last lines kept for error messages.
//
// Written by hand on posix_spawn and poll because the one packaged library for this in Debian
// 12, Boost.Process 1.74, has timed waits that block for the whole timeout or forever
// (github.com/boostorg/process/issues/69, /107, /204) and are not thread-safe (/347: a
// process-wide SIGCHLD handler); everything here is plain POSIX, about two hundred lines.
//
//   Subprocess p({.argv = {"/usr/bin/python3", "x.py"}, .pipe_stdin = true, .pipe_stdout = true});
//   p.write_line("{...}");
//   std::string answer;
//   if (p.read_line(answer, 60.0) != Subprocess::Read::Line) ... p.kill_group();
#pragma once

#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <sys/types.h>
#include <vector>

namespace dnb {

struct ProcessOptions {
  std::vector<std::string> argv;               // argv[0] is run as given (PATH searched when it has no '/')
  std::string cwd = {};                        // empty: the harness's own
  std::map<std::string, std::string> env = {}; // set in the child's environment (the rest inherited)
  bool pipe_stdin = false;                     // false: /dev/null
  bool pipe_stdout = false;                    // false: stdout goes where stderr goes (the log)
  // Called with every complete stderr line (and stdout lines when pipe_stdout is false), as they
  // arrive while the harness waits or reads.
  std::function<void(const std::string& line)> on_log_line = {};
  std::size_t tail_lines = 20;  // log lines kept for error messages
};

// How a process ended.
struct ExitStatus {
  bool exited = false;  // exited normally with `code`
  int code = 0;
  int signal = 0;       // killed by this signal when !exited
  bool ok() const { return exited && code == 0; }
  std::string describe() const;  // "exited with status 3", "was killed by signal 11 (Segmentation fault)"
};

class Subprocess {
 public:
  // Starts the process; WorkError naming argv[0] and the system's reason when it cannot.
  explicit Subprocess(ProcessOptions options);
  ~Subprocess();  // kills the process group if it still runs, and reaps the process
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  pid_t pid() const { return pid_; }

  // Writes `line` and a newline to stdin. False when the process closed its stdin (it died).
  bool write_line(const std::string& line);
  void close_stdin();

  enum class Read { Line, Eof, Timeout };
  // The next line of stdout (without its newline), waiting at most `timeout_seconds`.
  Read read_line(std::string& line, double timeout_seconds);

  // Waits at most `timeout_seconds` for the process to end (forwarding its output meanwhile);
  // nullopt on timeout.
  std::optional<ExitStatus> wait(double timeout_seconds);
  // SIGKILL to the whole process group, then reaps the process. Returns how it ended.
  ExitStatus kill_group();
  bool running() const { return !status_; }
  void set_on_log_line(std::function<void(const std::string&)> f) { opt_.on_log_line = std::move(f); }

  // The last log lines (stderr, and stdout when not piped), oldest first.
  const std::deque<std::string>& log_tail() const { return tail_; }

 private:
  // Polls the open pipes and the process for at most `timeout_ms` (-1: no limit); reads what is
  // there; reaps the process when it has ended.
  void pump(int timeout_ms);
  void take_log(std::string& buffer, bool flush);
  void reap(bool block);

  ProcessOptions opt_;
  pid_t pid_ = -1;
  int pidfd_ = -1;
  int in_ = -1, out_ = -1, err_ = -1;
  std::string out_buf_, err_buf_;
  std::deque<std::string> lines_;  // complete stdout lines not yet read
  std::deque<std::string> tail_;
  std::optional<ExitStatus> status_;
};

}  // namespace dnb
