// SHA-256 digests (OpenSSL's EVP interface) as 64 lowercase hex digits: the checksums of the
// render cache and of checkpoints (tracer/), and the build and cell ids of experiment runs.
//
//   sha256_hex("abc") == "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
#pragma once

#include <cstddef>
#include <string>

namespace dnb {

// SHA-256 of `size` bytes at `data`. WorkError if OpenSSL fails.
std::string sha256_hex(const void* data, std::size_t size);
std::string sha256_hex(const std::string& data);
// SHA-256 of a file's content; InputError naming the file when it cannot be read.
std::string sha256_file(const std::string& path);

}  // namespace dnb
