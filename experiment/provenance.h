// Provenance of a results file: which machine ran it and which build computed it.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

namespace dnb::experiment {

// hostname, cpu (model name), hardware_threads.
nlohmann::json machine_info();
// version, git_revision, build_type, compiler, tracer_version, build_id.
nlohmann::json build_info();
// The SHA-256 of the running program's own file: it changes with any rebuild that changes
// code, so a finished method cell is reused only when the very same build computed it. (The
// git revision is fixed at configure time and misses uncommitted edits, so it cannot serve.)
// Input frames and references keep their own cache keys (scene, settings, tracer version) and
// are not re-rendered by a rebuild.
const std::string& build_id();

}  // namespace dnb::experiment
