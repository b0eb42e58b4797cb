// The program's environment variables: one prefix, DENOISEBENCH_ (DENOISEBENCH_SOURCE_DIR,
// DENOISEBENCH_OPENCL_PLATFORM, ...). The older DNB_ spelling of the same name is still read
// where the new one is unset, as a documented alias (docs/design.md, "Environment"), and will
// go in a later release. Header-only: the fuzz targets and the benchmarks read it too.
#pragma once

#include <cstdlib>
#include <string>

namespace dnb::env {

// The value of DENOISEBENCH_<name>, else of DNB_<name>, else null.
inline const char* get(const std::string& name) {
  if (const char* v = std::getenv(("DENOISEBENCH_" + name).c_str())) return v;
  return std::getenv(("DNB_" + name).c_str());
}

}  // namespace dnb::env
