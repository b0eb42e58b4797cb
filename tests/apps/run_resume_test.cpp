// An interrupted `denoisebench run` resumes: the run is killed with SIGKILL
// (its whole process group) as soon as its first cell is finished, run again, and the cells it
// had finished are not computed again (their files keep their inode and modification time),
// while the final results.json and images equal those of a run that was never interrupted:
// metrics exactly, images bit for bit.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <thread>

#include <nlohmann/json.hpp>

#include "core/env.h"
#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using test::slurp;
using test::write;

// Four cells: path tracing at 1 spp (the first cell, cheap), path tracing at 256 spp (about a
// second on two shared cores: the kill lands while it renders), the 2 spp input and bilateral.
const char* kResumeConfig = R"(name = "resume"
width = 48
height = 36
scenes = ["cornell-box"]
spp = [2]
methods = ["bilateral"]
[reference]
spp = 16
block_spp = 8
[speedup]
spp = [1, 256]
[timing]
repeats = 1
)";
constexpr std::size_t kCells = 4;

std::string binary() {
  const char* bin = env::get("BINARY");
  return fs::absolute(bin && *bin ? bin : "./denoisebench").string();
}

std::string run_args(const test::TempDir& dir, const std::string& out, const std::string& cache) {
  return "DENOISEBENCH_CACHE='" + cache + "' '" + binary() + "' run '" + dir.file("resume.toml") + "' -o '" + out + "'";
}

// Starts the run in a process group of its own, waits until `marker` exists and kills the group
// with SIGKILL. Returns false if the run ended before it could be killed.
bool start_and_kill(const std::string& command, const std::string& marker) {
  const std::string cmd = "exec env " + command + " > /dev/null 2>&1";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::setpgid(pid, pid);  // also here: the kill must not race the child's own setpgid
  bool killed = false;
  for (int i = 0; i < 60000 && !killed; ++i) {  // at most a minute
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) return false;  // finished first
    if (fs::exists(marker)) {
      ::kill(-pid, SIGKILL);
      killed = true;
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return killed && WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
}

struct FileStamp {
  ino_t inode = 0;
  std::int64_t mtime_ns = 0;
  bool operator==(const FileStamp&) const = default;
};

FileStamp stamp(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return {};
  return {st.st_ino, std::int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec};
}

TEST(RunCommand, KilledRunResumesWithoutRedoingFinishedCellsAndEqualsAnUninterruptedRun) {
  test::TempDir dir;
  write(dir.path() / "resume.toml", kResumeConfig);

  // The uninterrupted run, with a cache of its own so that nothing it rendered is reused below.
  const std::string whole = dir.file("whole");
  auto r = test::run_command(run_args(dir, whole, dir.file("cache-whole")));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json expected = json::parse(slurp(whole + "/results.json"));
  ASSERT_EQ(expected["records"].size(), kCells);

  // Killed as soon as finished_cells.json exists: the first cell's image is written and its
  // record stored (written atomically, so its existence means it is complete).
  const std::string out = dir.file("out");
  const std::string command = run_args(dir, out, dir.file("cache"));
  ASSERT_TRUE(start_and_kill(command, out + "/finished_cells.json")) << "the run ended before it could be killed";
  const json at_kill = json::parse(slurp(out + "/finished_cells.json"));
  const std::size_t finished = at_kill["records"].size();
  ASSERT_GE(finished, 1u);
  ASSERT_LT(finished, kCells) << "every cell was finished before the kill: nothing was interrupted";
  std::map<std::string, FileStamp> stamps;  // every file of every finished cell
  for (const auto& rec : at_kill["records"])
    for (const auto& [name, rel] : rec["files"].items()) {
      stamps[rel.get<std::string>()] = stamp(out + "/" + rel.get<std::string>());
      ASSERT_NE(stamps[rel.get<std::string>()].inode, 0u) << "a finished cell's file is missing: " << rel;
    }

  auto resumed = test::run_command(command);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  for (const auto& [rel, before] : stamps)
    EXPECT_EQ(stamp(out + "/" + rel), before) << rel << " of a cell finished before the kill was written again";

  const json got = json::parse(slurp(out + "/results.json"));
  ASSERT_EQ(got["records"].size(), kCells);
  for (std::size_t i = 0; i < kCells; ++i) {
    const json &g = got["records"][i], &e = expected["records"][i];
    SCOPED_TRACE(e["method"].get<std::string>() + " " + std::to_string(e["spp"].get<int>()) + " spp");
    EXPECT_EQ(g["method"], e["method"]);
    EXPECT_EQ(g["spp"], e["spp"]);
    EXPECT_EQ(g["cell_key"], e["cell_key"]);
    // The same images scored against the same reference by the same code: the same doubles.
    ASSERT_TRUE(e["metrics"]["mse"].is_number());
    EXPECT_EQ(g["metrics"], e["metrics"]);
    const std::string image = e["files"]["image"].get<std::string>();
    ASSERT_EQ(g["files"]["image"], image);
    const Image a = read_rgb(whole + "/" + image), b = read_rgb(out + "/" + image);
    ASSERT_GT(a.pixel_count(), 0u);
    EXPECT_TRUE(a == b) << image << " differs from the uninterrupted run's";
  }
  EXPECT_TRUE(read_rgb(whole + "/images/cornell-box/reference.exr") == read_rgb(out + "/images/cornell-box/reference.exr"));
}

}  // namespace
}  // namespace dnb
