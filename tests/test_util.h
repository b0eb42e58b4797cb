// Helpers shared by the tests: a fresh temporary folder per test, and running the program.
#pragma once

#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace dnb::test {

// A new empty folder under the system temp dir, removed when the object dies.
class TempDir {
 public:
  TempDir();
  ~TempDir();
  const std::filesystem::path& path() const { return path_; }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  std::filesystem::path path_;
};

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together (the *_stdout runners: stdout only)
  std::string errors;  // the *_stdout runners: stderr, kept apart for failure messages
};

// Runs the built denoisebench ($DENOISEBENCH_BINARY) with the given arguments through the shell.
CommandResult run_denoisebench(const std::string& args);
// Runs any shell command, capturing stdout and stderr together.
CommandResult run_command(const std::string& command);

// Why the tests that need Blender (the Cycles back-end) cannot run here, or "" when they can:
// $DENOISEBENCH_BLENDER names one, else `blender` must be on PATH (DNB_SETUP_BLENDER=1
// scripts/setup installs Debian's).
std::string blender_missing();
// The same with stdout alone in `output` and stderr in `errors`: for output that is parsed
// (--json), which a log line on stderr must not break.
CommandResult run_denoisebench_stdout(const std::string& args);
CommandResult run_command_stdout(const std::string& command);
// The program as an absolute path: $DENOISEBENCH_BINARY, else ./denoisebench (ctest runs in the build folder).
std::filesystem::path binary();
// Runs the program with its own render cache in `dir` (DENOISEBENCH_CACHE=dir/cache).
CommandResult run_in(const TempDir& dir, const std::string& args);
// The source tree ($DENOISEBENCH_SOURCE_DIR).
std::string source_dir();

// The message of the exception of type E (InputError, WorkError) that `f` throws, or "(no error)"
// when it throws none: for asserting on what an error says.
template <class E>
std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  return "(no error)";
}

// A whole file as a string ("" when it cannot be read), and a file written from a string.
std::string slurp(const std::filesystem::path& p);
void write(const std::filesystem::path& p, const std::string& text);

// An OpenEXR file with exactly these channels (name -> width * height floats, in this order) and
// string attributes, as another renderer writes one: no denoisebench metadata.
using Channels = std::vector<std::pair<std::string, std::vector<float>>>;
void write_exr(const std::string& path, int width, int height, const Channels& channels,
               const std::map<std::string, std::string>& attributes = {});

}  // namespace dnb::test
