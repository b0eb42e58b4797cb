// `denoisebench denoise METHOD FRAME.exr -o OUT.exr`: one method on one frame file, as a request
// struct and one function (the command only parses arguments into the request and prints).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "denoisers/method.h"

namespace dnb {

struct DenoiseRequest {
  std::string method;                          // registry name
  std::string frame;                           // AOV frame (EXR written by `denoisebench render`)
  std::string output;                          // R,G,B EXR, written atomically
  std::map<std::string, std::string> settings; // parameter overrides, validated before the frame is read
  std::string scene;                           // renderer-type methods: instead of the frame's own
  int threads = 0;                             // 0: all cores (the image does not depend on it)
  std::string input_format = "auto";           // interop/import.h: native, auto, a preset, map:FILE.toml
};

struct DenoiseOutcome {
  Params params;       // every parameter's value, defaults included
  MethodResult result;
  int width = 0, height = 0;
};

// Creates the method (its parameters validated first, so a typo costs no frame read), reads only
// the layers it needs, runs it through run_method and writes the output with the method, its
// parameters and the source frame in the EXR metadata. InputErrors name the frame.
// A frame that lacks a layer the method reads is an InputError naming the layer and the methods
// that can run on the frame.
DenoiseOutcome denoise_file(const DenoiseRequest& request);

// The registered methods (at their defaults) whose layers `frame` has, sorted by name; a
// renderer-type method only when the frame names its scene.
std::vector<std::string> methods_for_frame(const AovFrame& frame);

}  // namespace dnb
