// `mpirun -np 2 denoisebench run` against one process (experiment/execute_mpi.cpp): the
// same records but for timing and the machine block, every image the same float for float, on a
// matrix with every kind of cell (the plain curve, inputs of two seeds, filters, a renderer, a
// scene read from files with a skipped renderer cell); and a job killed mid-run resumes from the
// cells its ranks had spooled.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <filesystem>
#include <memory>
#include <regex>
#include <thread>

#include <OpenImageIO/imageio.h>
#include <nlohmann/json.hpp>

#include "core/aov_frame.h"
#include "core/exr_io.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;
using test::slurp;

#ifdef DNB_TEST_MPIEXEC
constexpr bool kMpiBuild = true;
const std::string kMpirun = DNB_TEST_MPIEXEC;
#else
constexpr bool kMpiBuild = false;
const std::string kMpirun;
#endif
std::string mpirun() { return kMpirun; }

// The matrix: every kind of cell, small enough for seconds on two shared cores.
constexpr const char* kConfig = R"(name = "ranks"
width = 40
height = 30
seeds = [1, 2]
scenes = ["cornell-box", "conference"]
spp = [4]
methods = ["am", "bilateral", "proposed", "irradiance_cache"]
[reference]
spp = 32
block_spp = 8
[speedup]
spp = [1, 2]
[timing]
repeats = 1
repeat_below_seconds = 0
[[scene]]
frame = "mine/in.exr"
reference = "mine/ref.exr"
label = "box"
)";

// `denoisebench run` (one process), or under `mpirun -np 2`, with one thread per process and its
// own cache; "2>&1" output and exit status.
test::CommandResult run(const test::TempDir& dir, const std::string& out, int ranks) {
  const std::string cmd = "cd '" + dir.path().string() + "' && " +
                          (ranks > 1 ? "'" + mpirun() + "' --oversubscribe -np " + std::to_string(ranks) + " " : "") +
                          test::binary().string() + " run ranks.toml -o " + out + " --cache-dir cache-" + out;
  return test::run_command(cmd);
}

void make_folder(const test::TempDir& dir) {
  test::write(dir.path() / "ranks.toml", kConfig);
  fs::create_directories(dir.path() / "mine");
  for (const char* args : {"render cornell-box --size 40x30 --spp 4 --seed 7 -o mine/in.exr",
                                  "reference cornell-box --size 40x30 --spp 32 --block-spp 8 -o mine/ref.exr"}) {
    auto r = test::run_command("cd '" + dir.path().string() + "' && DENOISEBENCH_CACHE=cache-mine " +
                               test::binary().string() + " " + args);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
}

// Every channel of an EXR file as floats, by name.
std::map<std::string, std::vector<float>> pixels(const std::string& path) {
  auto in = OIIO::ImageInput::open(path);
  EXPECT_TRUE(in) << path;
  if (!in) return {};
  const OIIO::ImageSpec& spec = in->spec();
  std::vector<float> all(spec.image_pixels() * spec.nchannels);
  EXPECT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, all.data())) << path;
  std::map<std::string, std::vector<float>> out;
  for (int c = 0; c < spec.nchannels; ++c) {
    auto& v = out[spec.channelnames[c]];
    for (std::size_t p = 0; p < spec.image_pixels(); ++p) v.push_back(all[p * spec.nchannels + c]);
  }
  return out;
}

// A record without what depends on when and where it ran: its times, phases and the
// reference's render time; with `history`, also whether its input and reference were in the
// cache (a resumed job finds what the killed one rendered there).
json timeless(json r, bool history) {
  r.erase("times");
  r.erase("phases");
  r["reference"].erase("seconds");
  if (history) r.erase("input_cache_hit"), r["reference"].erase("cache_hit");
  return r;
}

// Two results folders of the same config: the same records in the same order but for timing,
// and every file they name (images, error maps, frames, edges, references) with the same pixels.
void expect_same_folder(const fs::path& a, const fs::path& b, bool history = false) {
  const json ja = json::parse(slurp(a / "results.json")), jb = json::parse(slurp(b / "results.json"));
  ASSERT_EQ(ja["records"].size(), jb["records"].size());
  EXPECT_EQ(ja["failures"], jb["failures"]);
  EXPECT_EQ(ja["skipped"], jb["skipped"]);
  int files = 0;
  for (std::size_t i = 0; i < ja["records"].size(); ++i) {
    const json& ra = ja["records"][i];
    EXPECT_EQ(timeless(ra, history), timeless(jb["records"][i], history)) << "record " << i;
    std::vector<std::string> names{ra["reference"]["image"].get<std::string>()};
    for (const auto& [k, f] : ra["files"].items()) names.push_back(f.get<std::string>());
    for (const auto& f : names) {
      ++files;
      if (f.ends_with(".edges.exr")) continue;  // compared with its frame, below
      EXPECT_TRUE(pixels((a / f).string()) == pixels((b / f).string())) << f << " differs";
    }
    if (ra["files"].contains("frame_edges")) {
      // Edge sub-pixels are not an image: compared as the frame reader reads them.
      const std::string f = ra["files"]["frame"].get<std::string>();
      const AovFrame fa = read_frame((a / f).string(), {}, std::vector<std::string>{}),
                   fb = read_frame((b / f).string(), {}, std::vector<std::string>{});
      ASSERT_TRUE(fa.edges && fb.edges) << f;
      EXPECT_TRUE(*fa.edges == *fb.edges) << f << ": edge sub-pixels differ";
    }
  }
  EXPECT_GT(files, 100);  // the matrix above names 130-odd files: a comparison of nothing fails
}

TEST(RunMpi, TwoRanksWriteTheFolderOfOneProcess) {
  if (!kMpiBuild) GTEST_SKIP() << "built with DNB_WITH_MPI=OFF";
  // An MPI build whose launcher is missing cannot distribute anything: a failure, not a skip.
  ASSERT_FALSE(mpirun().empty()) << "built with MPI but CMake found no MPI launcher (MPIEXEC_EXECUTABLE)";
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(make_folder(dir));
  const auto one = run(dir, "one", 1);
  ASSERT_EQ(one.exit_code, 0) << one.output;
  const auto two = run(dir, "two", 2);
  ASSERT_EQ(two.exit_code, 0) << two.output;
  // Both ranks computed method cells (the work really was spread), and rank 0 alone wrote.
  EXPECT_NE(two.output.find("method cells computed per rank: 4, 4"), std::string::npos) << two.output;
  expect_same_folder(dir.path() / "one", dir.path() / "two");
  const json mone = json::parse(slurp(dir.path() / "one/results.json"))["machine"];
  const json mtwo = json::parse(slurp(dir.path() / "two/results.json"))["machine"];
  EXPECT_EQ(mone["ranks"], 1);
  EXPECT_EQ(mtwo["ranks"], 2);
  EXPECT_FALSE(fs::exists(dir.path() / "two/.spool")) << "every spooled cell is stored and its spool removed";
  // A second 2-rank run into the folder computes nothing: every cell is reused.
  const auto again = run(dir, "two", 2);
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_NE(again.output.find("method cells computed per rank: 0, 0"), std::string::npos) << again.output;
  expect_same_folder(dir.path() / "one", dir.path() / "two");
}

// The processes descended from `root` (from /proc's parent links), nearest first.
std::vector<pid_t> descendants(pid_t root) {
  std::map<pid_t, std::vector<pid_t>> children;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator("/proc", ec)) {
    const std::string name = e.path().filename().string();
    if (name.empty() || !std::all_of(name.begin(), name.end(), ::isdigit)) continue;
    // /proc/PID/stat: "PID (COMM) STATE PPID ...", COMM may hold spaces and parentheses.
    const std::string stat = slurp(e.path() / "stat");
    const auto close = stat.rfind(')');
    if (close == std::string::npos) continue;
    char state = 0;
    int ppid = 0;
    if (std::sscanf(stat.c_str() + close + 1, " %c %d", &state, &ppid) == 2) children[ppid].push_back(std::stoi(name));
  }
  std::vector<pid_t> out{root};
  for (std::size_t i = 0; i < out.size(); ++i)
    for (pid_t c : children[out[i]]) out.push_back(c);
  out.erase(out.begin());
  return out;
}

// Whether `pid` still runs (a zombie has ended: it writes nothing).
bool running(pid_t pid) {
  const std::string stat = slurp(fs::path("/proc") / std::to_string(pid) / "stat");
  const auto close = stat.rfind(')');
  return close != std::string::npos && stat.size() > close + 2 && stat[close + 2] != 'Z' && stat[close + 2] != 'X';
}

// Starts `mpirun -np 2 ... run` in a process group of its own, waits until a rank has spooled
// `cells` cells, and kills the whole job with SIGKILL, as a crash or a node's loss would: its
// ranks too, which OpenMPI puts in process groups of their own (a SIGKILL to mpirun alone leaves
// them running on for a moment), and waits until every one has ended. False if it finished first.
bool start_and_kill(const test::TempDir& dir, const std::string& out, int cells) {
  const std::string cmd = "cd '" + dir.path().string() + "' && exec '" + mpirun() + "' --oversubscribe -np 2 " +
                          test::binary().string() + " run ranks.toml -o " + out + " --cache-dir cache-" + out +
                          " > killed.log 2>&1";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::setpgid(0, 0);
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ::setpgid(pid, pid);
  const fs::path spool = dir.path() / out / ".spool";
  bool killed = false;
  for (int i = 0; i < 24000 && !killed; ++i) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) return false;
    std::error_code ec;
    int spooled = 0;
    for (const auto& e : fs::directory_iterator(spool, ec))
      spooled += e.path().extension() == ".json" && e.path().filename().string()[0] != '.';
    if (spooled >= cells) {
      ::kill(pid, SIGSTOP);  // mpirun, so that it neither starts nor reaps anything meanwhile
      const std::vector<pid_t> job = descendants(pid);
      for (pid_t p : job) ::kill(p, SIGKILL);
      ::kill(-pid, SIGKILL);
      killed = true;
      for (pid_t p : job)
        for (int w = 0; w < 2000 && running(p); ++w) std::this_thread::sleep_for(std::chrono::milliseconds(5));
      for (pid_t p : job) EXPECT_FALSE(running(p)) << "process " << p << " of the killed job still runs";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return killed;
}

TEST(RunMpi, AKilledJobResumesFromItsSpooledCells) {
  if (!kMpiBuild) GTEST_SKIP() << "built with DNB_WITH_MPI=OFF";
  // An MPI build whose launcher is missing cannot distribute anything: a failure, not a skip.
  ASSERT_FALSE(mpirun().empty()) << "built with MPI but CMake found no MPI launcher (MPIEXEC_EXECUTABLE)";
  test::TempDir dir;
  ASSERT_NO_FATAL_FAILURE(make_folder(dir));
  ASSERT_TRUE(start_and_kill(dir, "two", 3)) << "the run ended before it could be killed";
  // One spooled cell damaged (a write cut short by a full disk): reported, and computed again.
  std::vector<fs::path> spooled_json;
  for (const auto& e : fs::directory_iterator(dir.path() / "two/.spool"))
    if (e.path().extension() == ".json" && e.path().filename().string()[0] != '.') spooled_json.push_back(e.path());
  ASSERT_GE(spooled_json.size(), 3u);
  std::sort(spooled_json.begin(), spooled_json.end());
  fs::resize_file(spooled_json[0], fs::file_size(spooled_json[0]) / 2);
  const auto resumed = run(dir, "two", 2);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.output;
  EXPECT_NE(resumed.output.find("not a spooled cell of this build"), std::string::npos) << resumed.output;
  EXPECT_NE(resumed.output.find(spooled_json[0].stem().string()), std::string::npos) << resumed.output;
  // The cells spooled before the kill are stored, not computed again.
  const std::regex from_spool(R"((\d+) from an earlier run's spool)");
  int spooled = 0;
  for (auto it = std::sregex_iterator(resumed.output.begin(), resumed.output.end(), from_spool); it != std::sregex_iterator(); ++it)
    spooled += std::stoi((*it)[1]);
  EXPECT_GE(spooled, 3) << resumed.output;  // the damaged one among them: seen, then computed
  const auto one = run(dir, "one", 1);
  ASSERT_EQ(one.exit_code, 0) << one.output;
  expect_same_folder(dir.path() / "one", dir.path() / "two", true);
}

}  // namespace
}  // namespace dnb
