// How much memory a decode may plan on, and the refusal of an image whose decoding would need
// more: a small file may declare an enormous image (core/exr_io.cpp, tracer/texture.cpp).
#pragma once

#include <string>

namespace dnb {

// Refuses (InputError naming the file) an image whose decoding would need more than
// `available_bytes`: the readers of a whole image hold its channels as floats, interleaved and
// then as layers, about 2 x width x height x channels x 4 bytes (read_frame, which decodes a
// strip at a time, counts its layers and one strip instead). A small file may declare the
// largest size Image::check_size allows (2^28 pixels, 1024 channels: 2 TiB), which a compressed
// EXR of zeros can even hold. The readers pass memory_budget_bytes().
void check_decode_memory(const std::string& path, int width, int height, int channels, double available_bytes);
// The same for a decode that needs `need` bytes, counted by its caller (read_frame's layers and
// one strip).
void refuse_decode_beyond(const std::string& path, int width, int height, int channels, double need,
                          double available_bytes);
double physical_memory_bytes();  // 0 when unknown (then nothing is refused)
// The memory a decode may plan on: the machine's physical memory, lowered by the memory limit
// of the cgroup the process runs in (a container, a Slurm job: cgroup v2 memory.max along the
// process's path, or v1 memory.limit_in_bytes) and by $DENOISEBENCH_MEMORY_LIMIT when set (bytes,
// or a number with K, M, G or T: "4G"; the fuzz targets set it below libFuzzer's limit). 0 when
// none is known. InputError naming the variable when it is not such a number.
double memory_budget_bytes();
// "4G" -> 4 * 2^30 and the like (K, M, G, T; no suffix: bytes): for $DENOISEBENCH_MEMORY_LIMIT.
// InputError naming `what` and the text otherwise.
double parse_memory_size(const std::string& text, const std::string& what);

}  // namespace dnb
