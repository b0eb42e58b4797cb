// A long-lived helper program spoken to one JSON line at a time: the "worker" protocol of the
// denoiser plug-ins (methods/plugins.h, docs/plugins.md) and of the renderer back-ends
// (interop/renderers.h, docs/renderers.md). Both speak it the same way:
//
//   start     the program prints one line: {"ready": true} (optionally with "info": {...}), or
//             {"ready": false, "unavailable": "why"} when it cannot run on this machine
//   request   one JSON object per line on its stdin; one line back on its stdout,
//             {"ok": true, ...} or {"ok": false, "error": "..."}
//   stop      its stdin is closed; it is killed (its whole process group) 5 s later
//
// Started on the first request, in its own process group; restarted once when it dies (the
// request that found it dead fails, the next one starts it again), then every request fails.
// stderr goes to the log, its last lines into the errors.
//
//   LineWorker w({.what = "plug-in 'oidn' (/x/oidn.toml)", .short_name = "plug-in 'oidn'",
//                 .argv = {"/usr/bin/python3", "oidn_worker.py"}, .cwd = "/x"});
//   nlohmann::json answer = w.request({{"input", in}, {"output", out}});
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/errors.h"

namespace dnb {

class Subprocess;  // core/subprocess.h

struct LineWorkerOptions {
  std::string what;        // how failures name the program: "plug-in 'oidn' (/path/oidn.toml)"
  std::string short_name;  // how "not available here" names it: "plug-in 'oidn'"
  std::vector<std::string> argv;
  std::string cwd = {};
  std::map<std::string, std::string> env = {};  // set in the program's environment
  double timeout_seconds = 600;                 // per request, and for the start-up
  std::string log_name = {};                    // prefix of its log lines (default: short_name)
};

// The program failed (it died, timed out, answered garbage or {"ok": false}). what() is the
// reason and the last lines of its stderr; reason() the reason alone.
class WorkerError : public WorkError {
 public:
  WorkerError(const std::string& reason, std::vector<std::string> log_tail, const std::string& message)
      : WorkError(message), reason_(reason), log_tail_(std::move(log_tail)) {}
  const std::string& reason() const { return reason_; }
  const std::vector<std::string>& log_tail() const { return log_tail_; }

 private:
  std::string reason_;
  std::vector<std::string> log_tail_;
};

// The program answered its start with {"ready": false, "unavailable": why}: it cannot run on
// this machine. what(): "<short_name> is not available on this machine: <why>". Every later
// request throws it again without starting the program.
class WorkerUnavailable : public WorkError {
 public:
  using WorkError::WorkError;
};

class LineWorker {
 public:
  explicit LineWorker(LineWorkerOptions options);
  ~LineWorker();
  LineWorker(const LineWorker&) = delete;
  LineWorker& operator=(const LineWorker&) = delete;

  // Sends one request (starting the program when it is not running); returns the answer, an
  // object whose "ok" is true. `seconds`, when given, gets the round trip's wall time (the
  // start-up is setup_seconds(), apart). WorkerError or WorkerUnavailable on failure.
  nlohmann::json request(const nlohmann::json& req, double* seconds = nullptr);

  double setup_seconds() const { return setup_seconds_; }
  // The ready line's "info" object, values as strings (JSON text for non-strings).
  const std::map<std::string, std::string>& info() const { return info_; }

  // Closes stdin and waits for the program to end; kills its group after a grace period.
  // `log` false: its last output is not logged (at exit the log may already be gone).
  void stop(bool log);

 private:
  void start();
  void end_process();
  [[noreturn]] void fail(const std::string& reason, std::vector<std::string> tail = {}) const;
  [[noreturn]] void died(const std::string& when);
  std::vector<std::string> keep_tail();

  LineWorkerOptions opt_;
  std::mutex mutex_;
  std::unique_ptr<Subprocess> proc_;
  int starts_ = 0;
  double setup_seconds_ = 0;
  std::map<std::string, std::string> info_;
  std::string unavailable_;  // set once the program said it cannot run here
  std::vector<std::string> last_tail_;
};

// ---- What plug-ins and back-ends share about their programs ----

// "a:b::c" -> a, b, c (empty entries dropped), for PATH-like lists.
std::vector<std::string> split_path_list(const std::string& list);

// A manifest's program as it will be run: absolute, relative to the manifest's `folder`, or a
// name found on PATH (returned as it is). InputError "WHERE: program ..." when there is none.
std::string resolve_program(const std::string& program, const std::filesystem::path& folder, const std::string& where);

// The environment of a Python worker: `helper_dir` (the harness's helper module) on PYTHONPATH
// before any inherited one; no bytecode written into the folders (they are hashed); stderr
// unbuffered, line by line.
std::map<std::string, std::string> python_worker_env(const std::filesystem::path& helper_dir);

// Every regular file under `root` (`recurse`: in sub-folders too) as lines "label/rel:sha256",
// sorted, appended to `parts`; hidden entries and Python caches are left out (they do not change
// what a program does). What a worker's content hash is made of.
void hash_folder(const std::filesystem::path& root, const std::string& label, bool recurse, std::vector<std::string>& parts);

// The manifests (*.toml) in `dir` and in its sub-folders one level down (hidden ones left out),
// sorted: where plug-ins and back-ends are found.
std::vector<std::filesystem::path> manifest_files_in(const std::filesystem::path& dir);

}  // namespace dnb
