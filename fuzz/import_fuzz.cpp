// Fuzz target: the importers of other renderers' frames (interop/import.h): a mapping file,
// the detection of a file's format, and the import itself through the mapping and through
// every preset.
//
// One input is a mapping, a separator line and the foreign EXR:
//
//   <mapping TOML, may be empty>\n#@@ f.exr\n<f.exr bytes>
//
// The mapping is parsed (parse_mapping); when it is accepted the EXR is imported through it.
// The EXR is also read as `--input-format auto` would read it (detect_format, read_frame_as)
// and through each preset, so a mutated file reaches every preset's rules whatever its header
// says. The seeds (fuzz/corpus/import/, made by fuzz/make_import_seeds.py) are 4x3 files with
// Cycles', pbrt-v4's and Mitsuba 3's channel names, each with a preset or a hand-written mapping.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include <spdlog/spdlog.h>

#include "fuzz_input.h"
#include "interop/import.h"

namespace {
constexpr std::string_view kExrSeparator = "\n#@@ f.exr\n";
}

// read_frame_as logs the format it detected for every input: silenced, so that the log holds
// libFuzzer's progress and findings and the run is not slowed by it.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dnb::fuzz;
  namespace interop = dnb::interop;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t at = input.find(kExrSeparator);
  // Without the separator the whole input is the mapping (and there is no file to import).
  const std::string_view mapping_text = input.substr(0, at);
  const std::string path =
      write_input("f.exr", at == std::string_view::npos ? std::string_view() : input.substr(at + kExrSeparator.size()));
  run_guarded([&] {
    const interop::ImportMapping mapping = interop::parse_mapping(std::string(mapping_text), "fuzz.toml");
    (void)interop::import_frame(path, mapping);
    (void)interop::import_frame(path, mapping, {.spp = 16});
  });
  if (at == std::string_view::npos) return 0;
  run_guarded([&] { (void)interop::detect_format(path); });
  run_guarded([&] {
    interop::ImportReport report;
    (void)interop::read_frame_as(path, "auto", {}, {}, &report);
  });
  for (const std::string& name : interop::preset_names()) {
    run_guarded([&] { (void)interop::import_frame(path, interop::preset(name)); });
  }
  return 0;
}
