// Helpers shared by the tests: a fresh temporary folder per test, and running the program.
#pragma once

#include <filesystem>
#include <string>

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
  std::string output;  // stdout and stderr together
};

// Runs the built denoisebench ($DNB_BINARY) with the given arguments through the shell.
CommandResult run_denoisebench(const std::string& args);
// Runs any shell command, capturing stdout and stderr together.
CommandResult run_command(const std::string& command);
// The source tree ($DNB_SOURCE_DIR).
std::string source_dir();

// A whole file as a string ("" when it cannot be read), and a file written from a string.
std::string slurp(const std::filesystem::path& p);
void write(const std::filesystem::path& p, const std::string& text);

}  // namespace dnb::test
