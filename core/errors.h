// Error kinds of denoisebench and the exit codes they map to (DESIGN.md, "Command line").
#pragma once

#include <stdexcept>
#include <string>

namespace dnb {

// Bad usage or bad input: a missing or malformed file, key or channel. Exit status 2.
// The message names the file, the key or line where known, and what was expected.
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The work itself failed (a render, a write, a device). Exit status 1.
class WorkError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace dnb
