// What every fuzz target shares: a private folder for inputs that the API reads from a path,
// and the one rule of what counts as a finding.
//
// A loader may reject any input, but only the project's way: dnb::InputError (bad input) or
// dnb::WorkError (a fault). Any other exception escaping it, a crash, a leak or UB (the
// sanitizers) is a finding. run_guarded() turns an escaping std::exception into an abort that
// names its type and message, so libFuzzer keeps the input as a crash.
#pragma once

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <typeinfo>

#include "core/env.h"
#include "core/errors.h"

namespace dnb::fuzz {

// A folder of this process only (mkdtemp under $TMPDIR), removed at exit.
inline const std::filesystem::path& private_dir() {
  static const std::filesystem::path dir = [] {
    std::string tmpl = (std::filesystem::temp_directory_path() / "dnb-fuzz-XXXXXX").string();
    if (!mkdtemp(tmpl.data())) {
      std::perror("mkdtemp");
      std::abort();
    }
    std::atexit([] { std::error_code ec; std::filesystem::remove_all(private_dir(), ec); });
    // The readers refuse a decode larger than the memory the process may use
    // (core/memory_budget.h memory_budget_bytes()). Under libFuzzer that is its -rss_limit_mb of
    // 2048 MB (scripts/fuzz), not the machine's memory. 128 MB: well below it with ASan's own
    // overhead, and small enough that an input declaring an image just under the budget does
    // not take seconds to zero-fill (at 512 MB such inputs took 12 s and the target ran at 9
    // inputs/s). Without this a small file declaring a large image is refused only on the
    // machine and reported as an out-of-memory here. Kept when set.
    setenv("DENOISEBENCH_MEMORY_LIMIT", "128M", 0);
    return std::filesystem::path(tmpl);
  }();
  return dir;
}

// Writes `bytes` to `name` in the private folder (replacing it) and returns its path.
inline std::string write_input(const std::string& name, std::string_view bytes) {
  const std::filesystem::path path = private_dir() / name;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  out.close();
  if (!out) {
    std::perror(path.c_str());
    std::abort();
  }
  return path.string();
}

// Removes `name` from the private folder, so that one input never sees another's files.
inline void remove_input(const std::string& name) {
  std::error_code ec;
  std::filesystem::remove(private_dir() / name, ec);
}

// Runs `f`; InputError and WorkError are correct rejections, any other exception a finding.
// DENOISEBENCH_FUZZ_VERBOSE=1 prints each rejection (to see why a seed is refused).
template <class F>
void run_guarded(F&& f) {
  static const bool verbose = env::get("FUZZ_VERBOSE") != nullptr;
  try {
    f();
    if (verbose) std::fprintf(stderr, "accepted\n");
  } catch (const dnb::InputError& e) {
    if (verbose) std::fprintf(stderr, "InputError: %s\n", e.what());
  } catch (const dnb::WorkError& e) {
    if (verbose) std::fprintf(stderr, "WorkError: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "==FINDING== uncaught %s: %s\n", typeid(e).name(), e.what());
    std::abort();
  }
}

}  // namespace dnb::fuzz
