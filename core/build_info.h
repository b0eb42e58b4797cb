// The build's identity, from the header CMake generates at every build (core/version.h.in): the
// project's version, the checkout's revision, the build type and the compiler. Only
// build_info.cpp includes that header, so a commit (a new revision) recompiles this one file, and
// the per-method code identities (cmake/code_ids.py) leave its object out: it holds strings that
// name the build, no code that a cell runs.
#pragma once

#include <string>

namespace dnb {

const char* build_version();   // the project's version, "0.1.0"
const char* build_revision();  // the checkout's short git revision, or "unknown"
const char* build_type();      // CMAKE_BUILD_TYPE
const char* build_compiler();  // compiler id and version
// "0.1.0 (<revision>)", as frames and denoised files record it.
std::string build_version_and_revision();

}  // namespace dnb
