// Per-method code identities (cmake/code_ids.py, experiment/provenance.h): a finished method cell
// is reused while its method's code is unchanged, so a change to one method re-runs its cells only.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include <nlohmann/json.hpp>

#include "core/hash.h"
#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using test::binary;
using test::slurp;
using test::write;

// Every compiled-in method.
const std::set<std::string> kBuiltIn = {"am",       "am_opencv", "atrous",        "bilateral",            "guided",
                                        "irradiance_cache", "nfor", "nlmeans", "proposed", "svgf", "svgf_temporal",
                                        "temporal_accumulation"};

nlohmann::json ids_of(const std::string& file) { return nlohmann::json::parse(slurp(file)); }

// Runs cmake/code_ids.py over the program's objects, with `replace` ("OBJ=FILE") hashing FILE in
// place of one object, as if that file had been recompiled differently.
nlohmann::json code_ids(const test::TempDir& dir, const std::string& replace = "") {
  const fs::path build = binary().parent_path();
  const std::string out = dir.file("ids.json");
  auto r = test::run_command("/usr/bin/python3 '" + test::source_dir() + "/cmake/code_ids.py' --program '" +
                             binary().string() + "' --objects '" + (build / "denoisebench.objects").string() +
                             "' --binary-dir '" + build.string() + "' --out '" + out + "'" +
                             (replace.empty() ? "" : " --replace '" + replace + "'"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  return ids_of(out);
}

// A copy of object `rel` (relative to the build folder) with one byte more: changed code.
std::string changed_copy(const test::TempDir& dir, const std::string& rel) {
  const fs::path build = binary().parent_path();
  const std::string copy = dir.file(fs::path(rel).filename().string() + ".changed");
  fs::copy_file(build / rel, copy);
  std::ofstream(copy, std::ios::app | std::ios::binary) << '\0';
  return rel + "=" + copy;
}

TEST(CodeIds, TheBuildWritesOneIdentityPerBuiltInMethodForThisVeryProgram) {
  const auto ids = ids_of(binary().string() + ".code-ids.json");
  EXPECT_EQ(ids["format"], "denoisebench-code-ids");
  EXPECT_EQ(ids["program_sha256"], sha256_file(binary().string()));
  std::set<std::string> own, distinct, accounted;
  for (const auto& [method, id] : ids["methods"].items()) {
    own.insert(method);
    distinct.insert(id.get<std::string>());
  }
  // Every method either has an identity of its own or is shared code with the reason given (which
  // can depend on the build: an instrumented build may give a file a static initialiser).
  accounted = own;
  for (const auto& [method, why] : ids["shared_method_files"].items()) {
    EXPECT_FALSE(own.count(method)) << method;
    EXPECT_FALSE(why.get<std::string>().empty());
    accounted.insert(method);
  }
  EXPECT_EQ(accounted, kBuiltIn);
  EXPECT_EQ(distinct.size(), own.size());
  // am.cpp is used by am_opencv.cpp: shared in every build. proposed's file is its own.
  EXPECT_THAT(ids["shared_method_files"]["am"].get<std::string>(), ::testing::HasSubstr("am_opencv.cpp.o"));
  EXPECT_EQ(ids["own_files"]["proposed"], "denoisers/CMakeFiles/dnb_denoisers.dir/proposed.cpp.o");
}

TEST(CodeIds, AChangeToOneMethodsFileChangesThatMethodsIdentityAlone) {
  test::TempDir dir;
  const auto base = code_ids(dir);
  const auto after = code_ids(dir, changed_copy(dir, base["own_files"]["proposed"]));
  EXPECT_EQ(after["shared"], base["shared"]);
  for (const auto& [method, id] : base["methods"].items()) {
    if (method == "proposed")
      EXPECT_NE(after["methods"][method], id);
    else
      EXPECT_EQ(after["methods"][method], id) << method;
  }
}

TEST(CodeIds, AChangeToSharedCodeChangesEveryIdentityAndTheRevisionStringsNone) {
  test::TempDir dir;
  const auto base = code_ids(dir);
  // nlm_space.cpp is proposed's helper and nobody's factory: shared, so every method re-runs
  // (the conservative side: the script cannot tell which methods reach it).
  const auto shared = code_ids(dir, changed_copy(dir, "denoisers/CMakeFiles/dnb_denoisers.dir/nlm_space.cpp.o"));
  EXPECT_NE(shared["shared"], base["shared"]);
  for (const auto& [method, id] : base["methods"].items()) EXPECT_NE(shared["methods"][method], id) << method;
  // The build-identity strings change with every commit and compute nothing.
  const auto revision = code_ids(dir, changed_copy(dir, "core/CMakeFiles/dnb_core.dir/build_info.cpp.o"));
  EXPECT_EQ(revision["shared"], base["shared"]);
  EXPECT_EQ(revision["methods"], base["methods"]);
}

// End to end through `run`: a copy of the program with a code-ids file written for it, then the
// same file with one method's identity changed, as after a rebuild that changed that method.
TEST(CodeIds, ARunAfterAChangeToOneMethodRecomputesThatMethodsCellsOnly) {
  test::TempDir dir;
  const fs::path program = dir.path() / "denoisebench-copy";
  fs::copy_file(binary(), program);
  fs::permissions(program, fs::perms::owner_exec, fs::perm_options::add);
  const std::string a(64, 'a'), b(64, 'b'), c(64, 'c'), d(64, 'd'), e(64, 'e'), f(64, 'f');
  // (A method's identity includes the shared one, so the build changes all three together.)
  const auto write_ids = [&](const std::string& shared, const std::string& bilateral, const std::string& guided) {
    nlohmann::json ids = {{"format", "denoisebench-code-ids"}, {"version", 1},
                          {"program_sha256", sha256_file(program.string())}, {"shared", shared},
                          {"methods", {{"bilateral", bilateral}, {"guided", guided}}}};
    write(program.string() + ".code-ids.json", ids.dump());
  };
  write(dir.path() / "two.toml", R"(name = "two"
width = 24
height = 16
scenes = ["cornell-box"]
spp = [2]
methods = ["bilateral", "guided"]
[reference]
spp = 8
block_spp = 8
[speedup]
spp = [2]
)");
  const std::string out = dir.file("out");
  const auto run = [&] {
    auto r = test::run_command("DENOISEBENCH_CACHE='" + dir.file("cache") + "' '" + program.string() + "' run " +
                               dir.file("two.toml") + " -o " + out);
    ASSERT_EQ(r.exit_code, 0) << r.output;
  };
  const auto when = [&](const std::string& stem) {
    return fs::last_write_time(out + "/images/cornell-box/" + stem + "_2.exr");
  };
  write_ids(a, b, c);
  ASSERT_NO_FATAL_FAILURE(run());
  EXPECT_EQ(nlohmann::json::parse(slurp(out + "/results.json"))["build"]["code_identity"], "per-method");
  const auto bilateral0 = when("bilateral"), guided0 = when("guided"), input0 = when("input");

  write_ids(a, d, c);  // bilateral's file changed
  ASSERT_NO_FATAL_FAILURE(run());
  const auto bilateral1 = when("bilateral");
  EXPECT_NE(bilateral1, bilateral0) << "the changed method's cell was reused";
  EXPECT_EQ(when("guided"), guided0) << "an unchanged method's cell was recomputed";
  EXPECT_EQ(when("input"), input0);

  write_ids(b, e, f);  // shared code changed: every cell again
  ASSERT_NO_FATAL_FAILURE(run());
  EXPECT_NE(when("bilateral"), bilateral1);
  EXPECT_NE(when("guided"), guided0);
  EXPECT_NE(when("input"), input0);
}

}  // namespace
}  // namespace dnb
