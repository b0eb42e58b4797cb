// SHA-256 (core/hash.h): known answers of FIPS 180-2, and a file hashes like its bytes.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "core/errors.h"
#include "core/hash.h"
#include "test_util.h"

namespace dnb {
namespace {

TEST(Sha256, KnownAnswer) {
  // FIPS 180-2 test vectors.
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
}

TEST(Sha256, FileHashesLikeItsBytes) {
  test::TempDir tmp;
  // Larger than the 1 MiB read block, so that the file is fed in several updates.
  std::string bytes(3 << 19, '\0');
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = char(i * 131 % 251);
  std::ofstream(tmp.file("f.bin"), std::ios::binary) << bytes;
  EXPECT_EQ(sha256_file(tmp.file("f.bin")), sha256_hex(bytes.data(), bytes.size()));
  EXPECT_THROW(sha256_file(tmp.file("missing.bin")), InputError);
}

}  // namespace
}  // namespace dnb
