#include "test_util.h"

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <random>

#include <OpenImageIO/imageio.h>

namespace dnb::test {
namespace fs = std::filesystem;

// The environment every test expects, set before any test runs (and before OpenCL or MPI is
// touched), unless the caller already set it: the source tree, the built program, PoCL's kernel
// cache inside the build tree, and the switches that let mpirun run as root (containers, CI).
// Done here rather than through ctest's ENVIRONMENT so that a test program run by hand behaves
// exactly as under ctest (and because gtest_discover_tests forwards only the first variable of
// an ENVIRONMENT list).
namespace {
const bool environment_set = [] {
  ::setenv("DENOISEBENCH_SOURCE_DIR", DNB_TEST_SOURCE_DIR, 0);
  ::setenv("DENOISEBENCH_BINARY", DNB_TEST_BINARY_DIR "/denoisebench", 0);
  ::setenv("POCL_CACHE_DIR", DNB_TEST_BINARY_DIR "/pocl-cache", 0);
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 0);
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 0);
  return true;
}();
}  // namespace

TempDir::TempDir() {
  std::random_device rd;
  path_ = fs::temp_directory_path() / ("dnb-test-" + std::to_string(rd()) + std::to_string(rd()));
  fs::create_directories(path_);
}

TempDir::~TempDir() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

namespace {
// Runs `command` with `redirect` appended (how stderr is routed), capturing stdout.
CommandResult run_with(const std::string& command, const std::string& redirect) {
  CommandResult r;
  FILE* p = ::popen((command + redirect).c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  std::size_t n;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  int status = ::pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}
}  // namespace

CommandResult run_command(const std::string& command) { return run_with(command, " 2>&1"); }

std::string blender_missing() {
  if (const char* b = std::getenv("DENOISEBENCH_BLENDER"); b && *b) return fs::exists(b) ? "" : std::string("no ") + b;
  if (run_command("command -v blender >/dev/null").exit_code != 0)
    return "Blender is not installed (no 'blender' on PATH): DNB_SETUP_BLENDER=1 scripts/setup installs Debian's blender";
  return "";
}

CommandResult run_command_stdout(const std::string& command) {
  TempDir dir;
  const std::string err = dir.file("stderr");
  // The command is grouped so that a redirection inside it (cmd 2>x) cannot be overridden.
  CommandResult r = run_with("{ " + command + "; }", " 2>'" + err + "'");
  r.errors = slurp(err);
  return r;
}

static std::string env_or(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v ? v : fallback;
}

CommandResult run_denoisebench(const std::string& args) {
  return run_command(env_or("DENOISEBENCH_BINARY", "./denoisebench") + " " + args);
}

CommandResult run_denoisebench_stdout(const std::string& args) {
  return run_command_stdout(env_or("DENOISEBENCH_BINARY", "./denoisebench") + " " + args);
}

fs::path binary() { return fs::absolute(env_or("DENOISEBENCH_BINARY", "./denoisebench")); }

CommandResult run_in(const TempDir& dir, const std::string& args) {
  return run_command("DENOISEBENCH_CACHE='" + dir.file("cache") + "' '" + binary().string() + "' " + args);
}

std::string source_dir() { return env_or("DENOISEBENCH_SOURCE_DIR", "."); }

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const fs::path& p, const std::string& text) {
  if (p.has_parent_path()) fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

void write_exr(const std::string& path, int width, int height, const Channels& channels,
               const std::map<std::string, std::string>& attributes) {
  OIIO::ImageSpec spec(width, height, int(channels.size()), OIIO::TypeDesc::FLOAT);
  spec.channelnames.clear();
  for (const auto& [name, plane] : channels) spec.channelnames.push_back(name);
  for (const auto& [k, v] : attributes) spec.attribute(k, v);
  std::vector<float> buf(std::size_t(width) * height * channels.size());
  for (std::size_t c = 0; c < channels.size(); ++c)
    for (std::size_t i = 0; i < std::size_t(width) * height; ++i) buf[i * channels.size() + c] = channels[c].second.at(i);
  auto out = OIIO::ImageOutput::create(path);
  if (!out || !out->open(path, spec) || !out->write_image(OIIO::TypeDesc::FLOAT, buf.data()) || !out->close())
    throw std::runtime_error("write_exr: cannot write " + path);
}

}  // namespace dnb::test
