// Argument values shared by several sub-commands, parsed one way everywhere.
#pragma once

#include <string>
#include <utility>

namespace dnb::app {

// "WIDTHxHEIGHT" (e.g. 1024x768): each side 1..65536 and at most 2^28 pixels in all (the
// frame's planes are addressed with 32-bit indices, and 2^28 pixels of every AOV layer already
// take tens of GiB). InputError naming the option and what was expected otherwise.
std::pair<int, int> parse_size(const std::string& value, const std::string& option = "--size");

}  // namespace dnb::app
