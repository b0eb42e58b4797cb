// Provenance of a results file: which machine ran it and which build computed it.
#pragma once

#include <map>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace dnb::experiment {

// hostname, cpu (model name), hardware_threads.
nlohmann::json machine_info();
// version, git_revision, build_type, compiler, tracer_version, build_id, code_identity.
nlohmann::json build_info();
// The SHA-256 of the running program's own file: it changes with any rebuild that changes
// code. (The git revision misses uncommitted edits, so it cannot serve.) Input frames and
// references keep their own cache keys (scene, settings, tracer version) and are not
// re-rendered by a rebuild.
const std::string& build_id();

// Per-method code identities (cmake/code_ids.py, written by the build beside the program as
// `<program>.code-ids.json`): `shared` hashes every object file of the program but the built-in
// methods' own files (one each, the file of its factory, used by nothing else) and the
// build-identity strings; `methods[m]` hashes shared code plus m's own file. So a change to one
// method's file changes that method's identity only, and a change anywhere else changes all.
struct CodeIds {
  std::string shared;
  std::map<std::string, std::string> methods;
};
// The identities in `file` when it is a code-ids file written for the program whose SHA-256 is
// `program_sha256`; nothing when the file is missing, malformed, or was written for another build
// (a program copied away from its build folder, a file left from an earlier build).
std::optional<CodeIds> read_code_ids(const std::string& file, const std::string& program_sha256);

// The identity of the code that computes a cell of `method` (a built-in method, a plug-in or a
// renderer): the method's own identity where the build wrote one, else the code every cell shares
// (a plug-in's own code is hashed by its content), else, without a code-ids file for this very
// program, the whole program's hash. Finished cells are reused only under the same identity.
std::string method_code_id(const std::string& method);
// The identity of the code every cell runs (frames, metrics, results): what an input cell's
// record depends on.
std::string shared_code_id();

}  // namespace dnb::experiment
