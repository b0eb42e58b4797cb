// SHA-256 through OpenSSL's EVP digest interface (core/hash.h); files are read in 1 MiB blocks.
#include "core/hash.h"

#include <openssl/evp.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <vector>

#include <fmt/format.h>

#include "core/errors.h"

namespace dnb {

namespace {

struct MdCtxDeleter {
  void operator()(EVP_MD_CTX* c) const { EVP_MD_CTX_free(c); }
};
using MdCtx = std::unique_ptr<EVP_MD_CTX, MdCtxDeleter>;

MdCtx new_sha256() {
  MdCtx ctx(EVP_MD_CTX_new());
  if (!ctx || EVP_DigestInit_ex(ctx.get(), EVP_sha256(), nullptr) != 1)
    throw WorkError("OpenSSL: cannot initialise SHA-256");
  return ctx;
}

std::string finish_hex(EVP_MD_CTX* ctx) {
  std::array<unsigned char, EVP_MAX_MD_SIZE> md;
  unsigned int n = 0;
  if (EVP_DigestFinal_ex(ctx, md.data(), &n) != 1) throw WorkError("OpenSSL: SHA-256 failed");
  std::string hex;
  hex.reserve(2 * n);
  for (unsigned int i = 0; i < n; ++i) hex += fmt::format("{:02x}", md[i]);
  return hex;
}

}  // namespace

std::string sha256_hex(const void* data, std::size_t size) {
  MdCtx ctx = new_sha256();
  if (EVP_DigestUpdate(ctx.get(), data, size) != 1) throw WorkError("OpenSSL: SHA-256 failed");
  return finish_hex(ctx.get());
}

std::string sha256_hex(const std::string& data) { return sha256_hex(data.data(), data.size()); }

std::string sha256_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot read '{}': {}", path, std::strerror(errno)));
  MdCtx ctx = new_sha256();
  std::vector<char> buf(1 << 20);
  while (f) {
    f.read(buf.data(), std::streamsize(buf.size()));
    std::streamsize n = f.gcount();
    if (n > 0 && EVP_DigestUpdate(ctx.get(), buf.data(), std::size_t(n)) != 1)
      throw WorkError("OpenSSL: SHA-256 failed");
  }
  if (f.bad()) throw InputError(fmt::format("error reading '{}'", path));
  return finish_hex(ctx.get());
}

}  // namespace dnb
