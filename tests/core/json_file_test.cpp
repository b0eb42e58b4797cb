// Typed reads of JSON keys (core/json_file.h): what results.json, the nightly's files and the
// benchmark files are read with.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/errors.h"
#include "core/json_file.h"

namespace dnb {
namespace {
namespace jf = json_file;
using nlohmann::json;

// Found by fuzz/results_fuzz.cpp: "spp": 1e300 in a results.json was converted to int with a
// plain cast (undefined behaviour; INT_MIN in practice), and 3e9 wrapped. An integer key now
// takes only a whole number in its type's range; anything else names the file and the key.
TEST(JsonFile, FuzzIntegerKeyOutOfRangeOrFractionalIsRefusedByName) {
  for (const json& v : {json(1e300), json(-1e300), json(3e9), json(2.5), json(std::uint64_t(1) << 40)}) {
    const json j = {{"spp", v}, {"list", {1, v}}};
    try {
      (void)jf::get<int>(j, "spp", "'r.json': records[0]");
      FAIL() << "spp = " << v.dump() << " was read as an int";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("'r.json': records[0]"), std::string::npos) << msg;
      EXPECT_NE(msg.find("'spp'"), std::string::npos) << msg;
    }
    EXPECT_THROW((void)jf::get<std::vector<int>>(j, "list", "'r.json': config"), InputError) << v.dump();
  }
  EXPECT_THROW((void)jf::get<std::uint64_t>(json{{"seed", -1}}, "seed", "x"), InputError);
  EXPECT_THROW((void)jf::get<std::int64_t>(json{{"written", 0x1p63}}, "written", "x"), InputError);
}

TEST(JsonFile, IntegerKeysInRangeAreRead) {
  const json j = {{"a", 16}, {"b", 16.0}, {"c", std::uint64_t(18446744073709551615u)}, {"d", {1, 2, 4}}, {"e", -5}};
  EXPECT_EQ(jf::get<int>(j, "a", "x"), 16);
  EXPECT_EQ(jf::get<int>(j, "b", "x"), 16);  // a whole float, as other writers may put it
  EXPECT_EQ(jf::get<std::uint64_t>(j, "c", "x"), 18446744073709551615u);
  EXPECT_EQ(jf::get<std::vector<int>>(j, "d", "x"), (std::vector<int>{1, 2, 4}));
  EXPECT_EQ(jf::get<std::int64_t>(j, "e", "x"), -5);
  EXPECT_THROW((void)jf::get<int>(json{{"a", "16"}}, "a", "x"), InputError);  // still typed
}

}  // namespace
}  // namespace dnb
