// Reading the build's per-method code identities (experiment/provenance.h): a file written for
// another program, or a damaged one, gives nothing, so cells fall back to the program's own hash.
#include <gtest/gtest.h>

#include <string>

#include <nlohmann/json.hpp>

#include "experiment/provenance.h"
#include "test_util.h"

namespace dnb::experiment {
namespace {

const std::string kProgram(64, '1');

nlohmann::json good() {
  return {{"format", "denoisebench-code-ids"}, {"version", 1}, {"program_sha256", kProgram},
          {"shared", std::string(64, 'a')},       {"methods", {{"proposed", std::string(64, 'b')}}}};
}

TEST(ReadCodeIds, ReadsTheIdentitiesOfThisProgram) {
  test::TempDir dir;
  test::write(dir.path() / "ids.json", good().dump());
  const auto ids = read_code_ids(dir.file("ids.json"), kProgram);
  ASSERT_TRUE(ids.has_value());
  EXPECT_EQ(ids->shared, std::string(64, 'a'));
  ASSERT_EQ(ids->methods.size(), 1u);
  EXPECT_EQ(ids->methods.at("proposed"), std::string(64, 'b'));
}

TEST(ReadCodeIds, IgnoresAnotherProgramsFileAMissingOneAndADamagedOne) {
  test::TempDir dir;
  EXPECT_FALSE(read_code_ids(dir.file("missing.json"), kProgram).has_value());
  test::write(dir.path() / "ids.json", good().dump());
  EXPECT_FALSE(read_code_ids(dir.file("ids.json"), std::string(64, '2')).has_value());
  const auto damaged = [&](nlohmann::json j) {
    test::write(dir.path() / "bad.json", j.dump());
    return read_code_ids(dir.file("bad.json"), kProgram).has_value();
  };
  auto j = good();
  j["shared"] = "abc";
  EXPECT_FALSE(damaged(j));
  j = good();
  j["methods"]["proposed"] = 7;
  EXPECT_FALSE(damaged(j));
  j = good();
  j["version"] = 2;
  EXPECT_FALSE(damaged(j));
  j = good();
  j["format"] = 5;
  EXPECT_FALSE(damaged(j));
  test::write(dir.path() / "bad.json", "{\"format\": ");
  EXPECT_FALSE(read_code_ids(dir.file("bad.json"), kProgram).has_value());
}

}  // namespace
}  // namespace dnb::experiment
