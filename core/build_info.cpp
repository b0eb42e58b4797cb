#include "core/build_info.h"

#include "core/version.h"

namespace dnb {

const char* build_version() { return DNB_VERSION; }
const char* build_revision() { return DNB_GIT_REVISION; }
const char* build_type() { return DNB_BUILD_TYPE; }
const char* build_compiler() { return DNB_COMPILER; }
std::string build_version_and_revision() { return DNB_VERSION " (" DNB_GIT_REVISION ")"; }

}  // namespace dnb
