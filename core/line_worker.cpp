#include "core/line_worker.h"

#include <unistd.h>

#include <algorithm>
#include <cstdlib>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "core/hash.h"
#include "core/subprocess.h"
#include "core/timer.h"

using nlohmann::json;

namespace dnb {

namespace {

std::vector<std::string> tail_of(const Subprocess& p) { return {p.log_tail().begin(), p.log_tail().end()}; }

}  // namespace

LineWorker::LineWorker(LineWorkerOptions options) : opt_(std::move(options)) {
  if (opt_.log_name.empty()) opt_.log_name = opt_.short_name;
}

LineWorker::~LineWorker() { stop(false); }

void LineWorker::fail(const std::string& reason, std::vector<std::string> tail) const {
  const std::string what = fmt::format("{}: {}", opt_.what, reason);
  std::string msg = what;
  if (!tail.empty()) msg += fmt::format("; the last lines of its stderr:\n  {}", fmt::join(tail, "\n  "));
  throw WorkerError(what, std::move(tail), msg);
}

json LineWorker::request(const json& req, double* seconds) {
  std::lock_guard<std::mutex> lock(mutex_);
  start();
  Stopwatch sw;
  if (!proc_->write_line(req.dump())) died("closed its stdin before the request");
  std::string answer;
  const auto r = proc_->read_line(answer, opt_.timeout_seconds);
  if (seconds) *seconds = sw.seconds();
  if (r == Subprocess::Read::Timeout) {
    proc_->kill_group();
    fail(fmt::format("no answer within timeout_seconds = {} (its process group was killed)", opt_.timeout_seconds),
         tail_of(*proc_));
  }
  if (r == Subprocess::Read::Eof) died("ended before answering");
  json a;
  try {
    a = json::parse(answer);
  } catch (const json::exception&) {
    fail(fmt::format("answered '{}', expected one JSON line {{\"ok\": true}} or {{\"ok\": false, \"error\": ...}}",
                     answer.substr(0, 200)),
         tail_of(*proc_));
  }
  if (!a.is_object() || !a.contains("ok") || !a["ok"].is_boolean())
    fail(fmt::format("answered {}, expected an object with a boolean \"ok\"", a.dump().substr(0, 200)), tail_of(*proc_));
  if (!a["ok"].get<bool>())
    fail(fmt::format("reported an error: {}", a.value("error", json("(no \"error\" given)")).dump()), tail_of(*proc_));
  return a;
}

void LineWorker::stop(bool log) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!proc_) return;
  if (!log) proc_->set_on_log_line({});
  end_process();
}

// The caller holds mutex_.
void LineWorker::end_process() {
  proc_->close_stdin();
  if (!proc_->wait(5.0)) proc_->kill_group();
  proc_.reset();
}

void LineWorker::start() {
  if (!unavailable_.empty()) throw WorkerUnavailable(unavailable_);
  if (proc_ && proc_->running()) return;
  if (proc_) proc_->kill_group();  // a dead one's leftovers
  if (starts_ >= 2) fail("the worker died twice; its remaining requests are not run", last_tail_);
  ++starts_;
  Stopwatch sw;
  const std::string log_name = opt_.log_name;
  proc_ = std::make_unique<Subprocess>(ProcessOptions{
      .argv = opt_.argv, .cwd = opt_.cwd, .env = opt_.env, .pipe_stdin = true, .pipe_stdout = true,
      .on_log_line = [log_name](const std::string& line) { spdlog::info("[{}] {}", log_name, line); }});
  std::string line;
  const auto r = proc_->read_line(line, opt_.timeout_seconds);
  if (r == Subprocess::Read::Timeout) {
    proc_->kill_group();
    fail(fmt::format("not ready within timeout_seconds = {} (its process group was killed)", opt_.timeout_seconds),
         keep_tail());
  }
  if (r == Subprocess::Read::Eof) died("ended during start-up, before its ready line");
  json ready;
  try {
    ready = json::parse(line);
  } catch (const json::exception&) {
  }
  if (ready.is_object() && ready.value("ready", true) == false && ready.contains("unavailable")) {
    const std::string why = ready["unavailable"].is_string() ? ready["unavailable"].get<std::string>()
                                                              : ready["unavailable"].dump();
    unavailable_ = fmt::format("{} is not available on this machine: {}", opt_.short_name, why);
    end_process();
    throw WorkerUnavailable(unavailable_);
  }
  if (!ready.is_object() || ready.value("ready", false) != true) {
    proc_->kill_group();
    fail(fmt::format("printed '{}' as its first line, expected {{\"ready\": true}}", line.substr(0, 200)), keep_tail());
  }
  setup_seconds_ = sw.seconds();
  info_.clear();
  if (ready.contains("info") && ready["info"].is_object())
    for (const auto& [k, v] : ready["info"].items()) info_[k] = v.is_string() ? v.get<std::string>() : v.dump();
  spdlog::info("{}: worker {} ready in {:.3f} s", opt_.short_name, proc_->pid(), setup_seconds_);
}

std::vector<std::string> LineWorker::keep_tail() { return last_tail_ = tail_of(*proc_); }

void LineWorker::died(const std::string& when) {
  auto st = proc_->wait(2.0);
  if (!st) st = proc_->kill_group();
  fail(fmt::format("the worker {} ({}){}", when, st->describe(), starts_ < 2 ? "; it is restarted for the next request" : ""),
       keep_tail());
}

std::vector<std::string> split_path_list(const std::string& list) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t end = std::min(list.find(':', start), list.size());
    if (end > start) out.push_back(list.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

namespace {
bool executable(const std::filesystem::path& p) {
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
}
}  // namespace

std::string resolve_program(const std::string& program, const std::filesystem::path& folder, const std::string& where) {
  namespace fs = std::filesystem;
  if (program.empty()) throw InputError(fmt::format("{}: the program (first element) is empty", where));
  if (program.find('/') != std::string::npos) {
    const fs::path p = fs::path(program).is_absolute() ? fs::path(program) : folder / program;
    if (!executable(p))
      throw InputError(fmt::format("{}: program '{}' {}", where, p.string(),
                                   fs::exists(p) ? "is not an executable file" : "does not exist"));
    return fs::absolute(p).lexically_normal().string();
  }
  const char* path = std::getenv("PATH");
  const std::string dirs = path ? path : "/usr/local/bin:/usr/bin:/bin";
  for (const std::string& d : split_path_list(dirs))
    if (executable(fs::path(d) / program)) return program;
  throw InputError(fmt::format("{}: program '{}' is not on PATH ({})", where, program, dirs));
}

std::map<std::string, std::string> python_worker_env(const std::filesystem::path& helper_dir) {
  std::string pp = helper_dir.string();
  if (const char* old = std::getenv("PYTHONPATH"); old && *old) pp += std::string(":") + old;
  return {{"PYTHONPATH", pp}, {"PYTHONDONTWRITEBYTECODE", "1"}, {"PYTHONUNBUFFERED", "1"}};
}

void hash_folder(const std::filesystem::path& root, const std::string& label, bool recurse, std::vector<std::string>& parts) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return;
  std::vector<std::pair<std::string, std::string>> files;
  for (auto it = fs::recursive_directory_iterator(root, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    const std::string leaf = it->path().filename().string();
    if (leaf.front() == '.' || leaf == "__pycache__" || (it->is_directory() && !recurse)) {
      if (it->is_directory()) it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file()) files.emplace_back(fs::relative(it->path(), root).string(), sha256_file(it->path().string()));
  }
  std::sort(files.begin(), files.end());
  for (const auto& [rel, h] : files) parts.push_back(label + "/" + rel + ":" + h);
}

std::vector<std::filesystem::path> manifest_files_in(const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  std::vector<fs::path> out;
  std::error_code ec;
  auto add_from = [&](const fs::path& d) {
    for (const auto& e : fs::directory_iterator(d, ec))
      if (e.is_regular_file() && e.path().extension() == ".toml") out.push_back(e.path());
  };
  add_from(dir);
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.is_directory() && e.path().filename().string().front() != '.') add_from(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace dnb
