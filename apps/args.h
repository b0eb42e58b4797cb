// Argument values shared by several sub-commands, parsed one way everywhere. The bounds
// themselves are core/bounds.h's, the ones the config files use.
#pragma once

#include <string>
#include <utility>

#include <CLI/CLI.hpp>

#include "core/bounds.h"

namespace dnb::app {

// "WIDTHxHEIGHT" (e.g. 1024x768): each side within bounds::kSide and at most bounds::kMaxPixels
// pixels in all (the frame's planes are addressed with 32-bit indices, and 2^28 pixels of every
// AOV layer already take tens of GiB). InputError naming the option, what was typed and what
// was expected otherwise.
std::pair<int, int> parse_size(const std::string& value, const std::string& option = "--size");

// A CLI11 check that the option's text is a whole number within b, before CLI11 converts it (so
// "-5" never wraps into an unsigned seed and 100000 threads never start):
//   cmd->add_option("--threads", threads, "...")->check(in_bounds(bounds::kThreads));
// The message names the option, what was typed, the bound and its reason; exit status 2.
CLI::Validator in_bounds(const Bound& b);

// The worker-thread option of every command (0: all cores), one rule for all of them.
CLI::Option* add_threads_option(CLI::App& cmd, int& threads, const std::string& help);

}  // namespace dnb::app
