// Plug-in denoisers: any program, in any language, described by a TOML manifest, run by the
// harness behind the one method interface and scored like a built-in (docs/plugins.md is the
// user's guide and the protocol's definition; docs/design.md, "Plug-ins").
//
//   [plugin]
//   name = "boxblur"                  the method name; must not clash with a built-in
//   description = "one line"
//   command = ["/usr/bin/python3", "boxblur.py"]   argv, no shell; relative paths: the manifest's folder
//   protocol = "frame"                "frame" (a process per frame) or "worker" (one process per run)
//   layers = ["color", "albedo"]      frame layers it reads (docs/design.md's names)
//   timeout_seconds = 600             per frame (and for a worker's start-up)
//   [params.radius]                   typed parameters, like a built-in's ParamSpec
//   type = "int"  default = "2"  min = 0  max = 64  doc = "box radius in pixels"
//
// A plug-in is registered into the method registry (MethodInfo::origin names its manifest), so
// `denoise`, `run`, `list`, the tables, the report and the nightly gates see it as a method.
// Its cells' keys include a hash of its folder, so editing it reruns its cells and nothing else.
#pragma once

#include <string>
#include <vector>

#include "core/errors.h"
#include "core/line_worker.h"
#include "denoisers/method.h"

namespace dnb {

enum class PluginProtocol { Frame, Worker };

struct PluginManifest {
  std::string path;    // the manifest file
  std::string folder;  // its folder: the program's working directory, hashed into cell keys
  std::string name, description;
  std::vector<std::string> command;  // argv with relative paths resolved
  PluginProtocol protocol = PluginProtocol::Frame;
  std::vector<std::string> layers;
  // `optional_layers`: layers passed where the frame has them and left out where it does not (a
  // tracer frame's reflection levels, which an imported frame lacks); the program checks.
  std::vector<std::string> optional_layers;
  // `temporal = true` (worker protocol only): the plug-in keeps history between the frames of a
  // sequence (Method::temporal()); its requests carry "sequence" {id, index, count}, and `motion`
  // among its layers is passed where the frame has it.
  bool temporal = false;
  double timeout_seconds = 600;
  std::vector<ParamSpec> params;
};

// A plug-in failed on a frame (it exited non-zero, crashed, timed out, wrote nothing or a wrong
// image, a worker answered an error or died). The message names the plug-in and the reason;
// log_tail holds the last lines it printed on stderr (core/line_worker.h's WorkerError, which a
// worker plug-in's failures are).
class PluginError : public WorkerError {
 public:
  using WorkerError::WorkerError;
};

// Reads and checks one manifest: unknown keys, a missing program, a bad layer name or a bad
// parameter spec are InputErrors naming the file, the line and the key. `builtins` are the
// names a plug-in may not take.
PluginManifest load_plugin_manifest(const std::string& path, const std::vector<std::string>& builtins = {});

// The folders searched for plug-ins, in order: `extra` (--plugins, a config's `plugins`), then
// $DENOISEBENCH_PLUGINS (colon-separated), then the repository's plugins/ folder.
std::vector<std::string> plugin_search_dirs(const std::vector<std::string>& extra = {});

// Registers every plug-in found in `dirs` (manifests DIR/*.toml and DIR/*/*.toml that have a
// [plugin] table) into the global registry. The same manifest found twice is registered once;
// two manifests of one name, or a plug-in named like a built-in, are InputErrors naming both.
// Safe to call again with more folders. Returns the names registered by this call.
std::vector<std::string> register_plugins(const std::vector<std::string>& dirs);
// register_plugins(plugin_search_dirs(extra)).
std::vector<std::string> load_plugins(const std::vector<std::string>& extra = {});

// Ends every worker plug-in (closes its stdin, waits briefly, then kills its process group).
// Called when a command finishes; also done at exit.
void shutdown_plugin_workers();

// The hash of the plug-in's folder (every file, by relative path and content, and the harness's
// Python helper module) that goes into its MethodInfo::content_hash.
std::string plugin_content_hash(const PluginManifest& manifest);

}  // namespace dnb
