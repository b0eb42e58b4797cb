#include "core/exr_header.h"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <OpenEXR/openexr.h>
#include <fmt/format.h>

#include "core/bounds.h"
#include "core/errors.h"

namespace dnb::exr {
namespace fs = std::filesystem;

namespace {

// Walks the OpenEXR header(s) of `path` (magic, version, then attributes: name, type name,
// int32 size, value; an empty name ends a header, and an empty header the list of a multi-part
// file) and refuses a value size that is negative or runs past the end of the file: OpenEXR
// 3.1's C++ reader allocates an attribute at its declared size before reading it, and its C
// core (below) did not refuse every such header. What this walk cannot follow (a name without
// its terminator) is left to OpenEXR, which reports it.
void check_attribute_sizes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::error_code ec;
  const auto file_size = fs::file_size(path, ec);
  if (!f || ec) return;  // OIIO reports it
  char magic[4];
  std::uint32_t version = 0;
  if (!f.read(magic, 4) || !f.read(reinterpret_cast<char*>(&version), 4)) return;
  const bool multipart = version & 0x1000;
  auto read_name = [&](std::string& name) -> bool {
    name.clear();
    for (char c; f.get(c);) {
      if (c == '\0') return true;
      if (name.size() == 255) return false;  // the longest name OpenEXR writes
      name += c;
    }
    return false;
  };
  std::string name, type;
  for (bool header_empty = true;;) {
    if (!read_name(name)) return;
    if (name.empty()) {  // the end of a header; a multi-part file lists headers up to an empty one
      if (!multipart || header_empty) return;
      header_empty = true;
      continue;
    }
    header_empty = false;
    if (!read_name(type)) return;
    std::int32_t size = 0;
    if (!f.read(reinterpret_cast<char*>(&size), 4)) return;
    const auto at = std::uint64_t(f.tellg());
    if (size < 0 || std::uint64_t(size) > file_size - std::min<std::uint64_t>(at, file_size))
      throw InputError(fmt::format("'{}': OpenEXR header attribute '{}' ({}) declares {} bytes, more than the "
                                   "{}-byte file holds after it",
                                   path, name, type, size, file_size - std::min<std::uint64_t>(at, file_size)));
    if (type == "chlist") {
      // OpenEXR's C++ reader reads channels up to an empty name, whatever the declared size, and
      // goes on reading attributes from there: the list must end exactly at the declared size.
      const auto end = at + std::uint64_t(size);
      std::string channel;
      while (read_name(channel) && !channel.empty()) f.seekg(16, std::ios::cur);  // type, linear, sampling
      if (!f || std::uint64_t(f.tellg()) != end)
        throw InputError(fmt::format("'{}': OpenEXR channel list does not end at its declared size ({} bytes)", path, size));
      continue;
    }
    f.seekg(size, std::ios::cur);
  }
}

// Reads the OpenEXR header(s) of `path` with OpenEXR's C core (openexr.h) before OIIO opens it
// with the C++ library. The C++ library of OpenEXR 3.1 allocates an attribute at the size the
// file declares before reading it, and reads fixed-size attributes whatever size is declared (so
// later attributes are read out of step): a 5 KB frame that declares a 2 GB string took 4 GB of
// memory (found by fuzz/frame_fuzz.cpp). The C core checks each attribute's size against its
// type and the file's size; its allocations are capped here as well, so a header it accepts is
// one the C++ library reads in step, with allocations bounded by the file.
struct ExrHeaderCheck {
  std::uint64_t limit = 0;
  std::string error;
};

// What the header's layout promises that no file of this size can hold, or "": every part's data
// window must be non-empty and within the harness's image sides, and the file must hold at
// least the part's chunk offset table (8 bytes a chunk): a header no reader should act on.
std::string layout_error(exr_const_context_t ctx, std::uint64_t file_size) {
  int parts = 0;
  if (exr_get_count(ctx, &parts) != EXR_ERR_SUCCESS || parts < 1) return "no image part in its header";
  for (int p = 0; p < parts; ++p) {
    exr_attr_box2i_t dw{};
    if (exr_get_data_window(ctx, p, &dw) != EXR_ERR_SUCCESS) return fmt::format("part {} has no dataWindow", p);
    const std::int64_t w = std::int64_t(dw.max.x) - dw.min.x + 1, h = std::int64_t(dw.max.y) - dw.min.y + 1;
    if (w < bounds::kSide.min || h < bounds::kSide.min || w > bounds::kSide.max || h > bounds::kSide.max)
      return fmt::format("dataWindow ({}, {}) - ({}, {}) of part {} is {}x{} pixels: expected {}..{} on each side ({})",
                         dw.min.x, dw.min.y, dw.max.x, dw.max.y, p, w, h, bounds::kSide.min, bounds::kSide.max,
                         bounds::kSide.why);
    std::int32_t chunks = 0;
    if (exr_get_chunk_count(ctx, p, &chunks) == EXR_ERR_SUCCESS && std::uint64_t(chunks) * 8 > file_size)
      return fmt::format("part {}'s offset table alone needs {} bytes ({} chunks) and the file has {}: truncated",
                         p, std::uint64_t(chunks) * 8, chunks, file_size);
  }
  return {};
}

}  // namespace

void check_exr_header(const std::string& path) {
  {
    std::ifstream f(path, std::ios::binary);
    char magic[4] = {};
    if (f.read(magic, 4) && std::memcmp(magic, "\x76\x2f\x31\x01", 4) != 0)
      throw InputError(fmt::format("'{}': not an OpenEXR file (frames and images are read as OpenEXR only)", path));
  }
  check_attribute_sizes(path);
  std::error_code ec;
  const auto file_size = fs::file_size(path, ec);
  if (ec) return;  // OIIO reports it
  // A header never needs more than the file holds; 1 MiB over it leaves room for the core's
  // own tables.
  static thread_local ExrHeaderCheck* check = nullptr;
  ExrHeaderCheck state{file_size + (std::uint64_t(1) << 20), {}};
  check = &state;
  exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
  init.error_handler_fn = [](exr_const_context_t, exr_result_t code, const char* msg) {
    if (check && check->error.empty()) check->error = msg ? msg : exr_get_default_error_message(code);
  };
  init.alloc_fn = [](std::size_t bytes) -> void* { return check && bytes > check->limit ? nullptr : std::malloc(bytes); };
  init.free_fn = [](void* p) { std::free(p); };
  exr_context_t ctx = nullptr;
  const exr_result_t rv = exr_start_read(&ctx, path.c_str(), &init);
  const std::string layout = rv == EXR_ERR_SUCCESS ? layout_error(ctx, file_size) : std::string();
  exr_finish(&ctx);
  check = nullptr;
  // Any complaint counts, also one the core reports and reads past (an attribute whose size
  // disagrees with its type: the C++ reader then reads the rest out of step).
  if (rv != EXR_ERR_SUCCESS || !state.error.empty())
    throw InputError(fmt::format("'{}': not a readable OpenEXR header: {}", path,
                                 state.error.empty() ? exr_get_default_error_message(rv) : state.error));
  if (!layout.empty()) throw InputError(fmt::format("'{}': {}", path, layout));
}

std::unique_ptr<OIIO::ImageInput> open_input(const std::string& path) {
  if (!fs::exists(path)) throw InputError(fmt::format("'{}': no such file", path));
  check_exr_header(path);
  // The OpenEXR reader only: ImageInput::open(path) tries every other format's reader when the
  // OpenEXR one refuses a file, so a damaged frame reached every decoder OIIO links.
  auto in = OIIO::ImageInput::create("openexr");
  OIIO::ImageSpec spec;
  if (!in || !in->open(path, spec))
    throw InputError(fmt::format("'{}': cannot open as an OpenEXR image: {}", path, in ? in->geterror() : OIIO::geterror()));
  return in;
}

}  // namespace dnb::exr
