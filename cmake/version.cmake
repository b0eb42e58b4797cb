# Writes the build identity header (core/version.h.in) with the checkout's revision as it is now.
# Run by the dnb_version target at every build, so that a binary built after a commit names that
# commit even when CMake did not configure again; configure_file leaves the header untouched when
# nothing changed, so an unchanged revision rebuilds nothing.
execute_process(COMMAND git rev-parse --short=12 HEAD WORKING_DIRECTORY "${SOURCE_DIR}"
                OUTPUT_VARIABLE DNB_GIT_REVISION OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(NOT DNB_GIT_REVISION)
  set(DNB_GIT_REVISION "unknown")
endif()
configure_file("${SOURCE_DIR}/core/version.h.in" "${OUTPUT}" @ONLY)
