// Renderer back-ends: another renderer (Mitsuba 3, Blender Cycles, pbrt-v4, ...) renders a scene
// file of its own for `denoisebench run` (a config's [[scene]] renderer = "NAME", file = "..."),
// one request per render, answered with a frame (docs/renderers.md is the user's guide and the
// protocol's definition). A back-end is a folder with a TOML manifest beside its program:
//
//   [renderer]
//   name = "mitsuba"                  the name a config's `renderer` gives
//   description = "one line"
//   command = ["/usr/bin/python3", "mitsuba_backend.py"]   argv, no shell; relative: the folder's
//   version = ["/usr/bin/python3", "mitsuba_backend.py", "--version"]   prints one line
//   protocol = "worker"               one process per run, one JSON request per line
//   format = "native"                 how its EXR is read: the harness's channel names, a preset
//                                     of configs/import/ ("cycles", "pbrt", ...) or map:FILE.toml
//   layers = ["color", "direct", ...] the frame layers it makes (docs/design.md's names)
//   timeout_seconds = 3600            per render, and for the worker's start-up
//
// The worker protocol is core/line_worker.h's: a ready line; then per render the request
//   {"scene": "/abs/scene.xml", "width": W, "height": H, "spp": N, "seed": S, "max_depth": D,
//    "threads": T, "output": "/tmp/.../out.exr", "layers": ["color", ...]}
// answered {"ok": true, "render_seconds": S} (the render alone, start-up and scene loading
// left out where the renderer can tell them apart) or {"ok": false, "error": "..."}, which names
// the scene file. A worker that cannot run here ({"ready": false, "unavailable": why}) fails
// every render with `why`: unlike a plug-in's cells, a scene's cells have no other source.
//
// What a render is keyed by in the render cache is the back-end's identity (its name, its
// version line and the content of its folder) with the scene file's content and the request.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/aov_frame.h"

namespace dnb {
class LineWorker;  // core/line_worker.h
}

namespace dnb::interop {

struct RendererManifest {
  std::string path;    // the manifest file
  std::string folder;  // its folder: the program's working directory, hashed into the identity
  std::string name, description;
  std::vector<std::string> command;          // argv with relative paths resolved
  std::vector<std::string> version_command;  // argv; prints the version line
  std::string format = "native";             // how its output is read (interop/import.h's formats)
  std::vector<std::string> layers;           // the frame layers it makes
  double timeout_seconds = 3600;
};

// Reads and checks one manifest: unknown keys, a missing program, a bad layer name or format are
// InputErrors naming the file, the line and the key.
RendererManifest load_renderer_manifest(const std::string& path);

// The folders searched for back-ends, in order: `extra` (a config's `renderers`), then
// $DENOISEBENCH_RENDERERS (colon-separated), then the repository's renderers/ folder.
std::vector<std::string> renderer_search_dirs(const std::vector<std::string>& extra = {});

// Every back-end found in `dirs` (manifests DIR/*.toml and DIR/*/*.toml that have a [renderer]
// table), by name. Two manifests of one name are an InputError naming both; a folder the user
// named that does not exist is one too.
std::map<std::string, RendererManifest> find_renderers(const std::vector<std::string>& dirs);

// One render a back-end is asked for.
struct RenderRequest {
  std::string scene;  // the scene file, absolute
  int width = 0, height = 0, spp = 0;
  std::uint32_t seed = 0;  // renderers take 32-bit seeds (Mitsuba's and Cycles' are)
  int max_depth = 8;       // path length in segments, the camera ray included
  int threads = 0;         // 0: every core
  std::vector<std::string> layers = {"color"};  // at least these (a back-end may write more)
};

// A back-end of this process: its worker (started on the first render, kept for the run) and its
// version. Thread-safe: renders are sent one at a time.
class RendererBackend {
 public:
  explicit RendererBackend(RendererManifest manifest);
  ~RendererBackend();
  const RendererManifest& manifest() const { return m_; }

  // The version line (the version command's first line of output), run once. WorkError naming
  // the back-end and the command's output when it fails (a missing .venv, say).
  const std::string& version();
  // The SHA-256 of the name, the version line and the back-end folder's files (and the Python
  // helper's beside them): what its renders are keyed by. Calls version().
  const std::string& identity();

  // One render: the frame (meta: scene, spp, seed, render_seconds as the back-end reports them,
  // tracer_version "<name>: <version>"). WorkError (core/line_worker.h's WorkerError when the
  // worker failed, with its stderr's last lines) naming the back-end; the back-end's own error
  // names the scene file. An output of the wrong size, without a requested layer, or with NaN or
  // Inf is refused the same way.
  AovFrame render(const RenderRequest& request);
  // The worker's start-up seconds (0 before the first render).
  double setup_seconds() const;
  void stop(bool log);

 private:
  RendererManifest m_;
  std::unique_ptr<LineWorker> worker_;
  std::string version_, identity_, version_error_;
  std::string work_dir_;
};

// The back-end named `name` among those of `dirs` (find_renderers), one instance per process and
// manifest, so that a run's renders share one worker. InputError listing the back-ends found
// and the folders searched when there is none of that name.
std::shared_ptr<RendererBackend> renderer_backend(const std::string& name, const std::vector<std::string>& dirs);

// Ends every back-end's worker (closes its stdin, waits briefly, then kills its process group).
// Called when a command finishes.
void shutdown_renderer_workers();

}  // namespace dnb::interop
