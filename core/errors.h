// Error kinds of denoisebench and the exit codes they map to (docs/design.md, "Command line").
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

// A method that cannot run on this machine, for a reason that is no fault of the run (a
// plug-in whose package or trained weights are not installed): an experiment records its cells
// as skipped with the message, which says how to make the method available. Exit status 1
// where a single command needed it (`denoise`).
class MethodUnavailable : public WorkError {
 public:
  using WorkError::WorkError;
};

}  // namespace dnb
