// Fuzz target: the AOV frame reader (core/exr_io.h read_frame), a flat OpenEXR frame and the
// deep edge file beside it, and read_rgb on the same frame.
//
// One input is the frame, optionally followed by a separator line and the edge file:
//
//   <f.exr bytes>\n#@@ f.edges.exr\n<f.edges.exr bytes>
//
// written into the private folder as f.exr and f.edges.exr (no edge file when there is no
// separator). The seeds are 8x6 renders of cornell-box (fuzz/corpus/frame/).
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "core/exr_io.h"
#include "fuzz_input.h"

namespace {
constexpr std::string_view kEdgesSeparator = "\n#@@ f.edges.exr\n";
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dnb::fuzz;
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  const std::size_t at = input.find(kEdgesSeparator);
  const std::string path = write_input("f.exr", input.substr(0, at));
  if (at != std::string_view::npos) {
    write_input("f.edges.exr", input.substr(at + kEdgesSeparator.size()));
  } else {
    remove_input("f.edges.exr");
  }
  run_guarded([&] {
    const dnb::AovFrame frame = dnb::read_frame(path);
    (void)frame;
  });
  run_guarded([&] { (void)dnb::read_rgb(path); });
  return 0;
}
