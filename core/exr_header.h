// The checks every OpenEXR file passes before OpenImageIO decodes it (core/exr_io.cpp, the
// edge files, textures): the header walked and read with OpenEXR's C core, its sizes held to what
// the file can hold. Internal to core/.
#pragma once

#include <memory>
#include <string>

#include <OpenImageIO/imageio.h>

namespace dnb::exr {

// InputError naming `path` when it is not an OpenEXR file or its header is one no reader should
// act on (an attribute larger than the file, a data window beyond the harness's sides, a chunk
// table the file cannot hold).
void check_exr_header(const std::string& path);
// `path` opened with OpenImageIO's OpenEXR reader only, after check_exr_header; InputError
// naming the file when it is missing or cannot be opened.
std::unique_ptr<OIIO::ImageInput> open_input(const std::string& path);

}  // namespace dnb::exr
