// `denoisebench nightly accept|check` end to end: a tiny experiment becomes the baseline; the
// same run checks clean; a deliberately weakened method (guided whose fit ignores its guide, set only by
// this test's config) fails the quality gate and a baseline with a faster recorded time ratio
// fails the performance gate, each with a message naming the scene, method, metric, old and new
// values; missing or malformed input exits 2 with a message saying what is wrong.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "test_util.h"

namespace dnb {
namespace {
namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;
using nlohmann::json;

using test::binary;
using test::run_in;
using test::slurp;
using test::write;

// A value as the messages print it (fmt's {:.6g}).
std::string g6(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

const char* kConfig = R"(name = "gate-test"
width = 64
height = 48
scenes = ["cornell-box"]
spp = [4]
methods = ["bilateral", "guided"]
%s
[reference]
spp = 32
block_spp = 16
[timing]
repeats = 1
)";

std::string config(const std::string& extra) {
  std::string c = kConfig;
  c.replace(c.find("%s"), 2, extra);
  return c;
}

// What denoisebench_bench writes for two nightly cases, three repetitions each.
json bench_json() {
  json runs = json::array();
  for (const auto& [method, ratio] : {std::pair{"guided", 17.0}, std::pair{"bilateral", 1.3}})
    for (double jitter : {0.98, 1.0, 1.03}) {
      const std::string name = std::string("nightly/") + method + "/256x192/threads:1/manual_time";
      runs.push_back({{"name", name}, {"run_name", name}, {"run_type", "iteration"}, {"repetitions", 3},
                      {"ratio", ratio * jitter}, {"method_ms", 1.5 * ratio * jitter}, {"reference_ms", 1.5},
                      {"label", "cornell-box 256x192 16spp"}});
    }
  return {{"context", {{"cpu_model", "Test CPU"}, {"nightly_reference_workload", "path tracing cornell-box 32x24"}}},
          {"benchmarks", runs}};
}

class NightlyCommand : public ::testing::Test {
 protected:
  test::CommandResult dnb(const std::string& args) {
    return test::run_command("DENOISEBENCH_CACHE='" + dir.file("cache") + "' '" + binary().string() + "' " + args);
  }
  // Runs the tiny config (with `extra` TOML) into RUN and puts the benchmark file beside it.
  std::string run(const std::string& name, const std::string& extra) {
    write(dir.path() / (name + ".toml"), config(extra));
    const std::string out = dir.file(name);
    auto r = dnb("run " + dir.file(name + ".toml") + " -o " + out);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    write(fs::path(out) / "bench.json", bench_json().dump(1));
    return out;
  }
  void SetUp() override {
    good = run("good", "");
    baseline = dir.file("baseline");
    auto r = dnb("nightly accept " + good + " --baseline " + baseline + " --revision r-good");
    ASSERT_EQ(r.exit_code, 0) << r.output;
  }
  double baseline_mse(const std::string& method) {
    const json b = json::parse(slurp(baseline + "/baseline.json"));
    for (const auto& e : b["quality"])
      if (e["method"] == method) return e["mse"].get<double>();
    return -1;
  }
  test::TempDir dir;
  std::string good, baseline;
};

TEST_F(NightlyCommand, AcceptWritesTheBaselineAndDefaultGates) {
  const json b = json::parse(slurp(baseline + "/baseline.json"));
  EXPECT_EQ(b["git_revision"], "r-good");
  EXPECT_EQ(b["cpu_model"], "Test CPU");
  EXPECT_EQ(b["quality"].size(), 2u);
  ASSERT_EQ(b["performance"].size(), 2u);
  EXPECT_DOUBLE_EQ(b["performance"][0]["time_ratio"].get<double>(), 17.0);  // the median
  const json g = json::parse(slurp(baseline + "/gates.json"));
  EXPECT_EQ(g["ahead"]["method"], "");  // no `proposed` in this config
  EXPECT_TRUE(g["quality"].contains("default_tolerance"));
}

TEST_F(NightlyCommand, IdenticalRunPassesAndAppendsHistory) {
  const std::string history = dir.file("history.csv");
  auto r = dnb("nightly check " + good + " --baseline " + baseline + " --history " + history);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("nightly check PASSED: 4 comparisons"));
  EXPECT_THAT(slurp(good + "/verdict.md"), HasSubstr("# Nightly check: PASS"));
  EXPECT_TRUE(json::parse(slurp(good + "/verdict.json"))["passed"].get<bool>());
  EXPECT_TRUE(fs::exists(good + "/summary.json"));
  r = dnb("nightly check " + good + " --baseline " + baseline + " --history " + history);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(history);
  int lines = 0;
  for (std::string l; std::getline(in, l);) ++lines;
  EXPECT_EQ(lines, 3);  // header + one row per check
  // The history plots.
  r = test::run_command("/usr/bin/python3 '" + test::source_dir() + "/reports/plot_history.py' " + history + " " +
                        dir.file("plots"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.file("plots/history_mse.png")));
  EXPECT_TRUE(fs::exists(dir.file("plots/history_speed.png")));
}

TEST_F(NightlyCommand, WeakenedMethodFailsTheQualityGate) {
  // Only this test sets the parameter: a guided filter whose per-window fit ignores its guide
  // (eps far above the guide's variance) is a 9x9 box blur across every edge (+49% in mse here;
  // a 3x3 window, once used, costs only 5% with the nested sampler's inputs, too close to the gate).
  const std::string worse = run("worse", "[params]\nguided = { eps = 1e6 }");
  auto r = dnb("nightly check " + worse + " --baseline " + baseline);
  ASSERT_EQ(r.exit_code, 1) << r.output;
  const json v = json::parse(slurp(worse + "/verdict.json"));
  ASSERT_EQ(v["failures"].size(), 1u) << v.dump(1);
  const json& f = v["failures"][0];
  EXPECT_EQ(f["gate"], "quality");
  EXPECT_EQ(f["scene"], "cornell-box");
  EXPECT_EQ(f["method"], "guided");
  EXPECT_EQ(f["metric"], "mse");
  EXPECT_DOUBLE_EQ(f["old"].get<double>(), baseline_mse("guided"));
  EXPECT_GT(f["new"].get<double>(), f["limit"].get<double>());
  const std::string msg = f["message"];
  EXPECT_THAT(r.output, AllOf(HasSubstr("REGRESSION " + msg), HasSubstr("nightly check FAILED: 1 of 4")));
  EXPECT_THAT(msg, AllOf(HasSubstr("quality: scene cornell-box, method guided, mse rose from"),
                         HasSubstr(g6(f["old"].get<double>())), HasSubstr("tolerance +5.0%")));
  EXPECT_THAT(slurp(worse + "/verdict.md"), AllOf(HasSubstr("FAIL (1 regressions)"), HasSubstr(msg)));
}

TEST_F(NightlyCommand, FasterBaselineRatioFailsThePerformanceGate) {
  json b = json::parse(slurp(baseline + "/baseline.json"));
  b["performance"][0]["time_ratio"] = 17.0 / 2;  // the baseline recorded guided twice as fast
  write(baseline + "/baseline.json", b.dump(1));
  auto r = dnb("nightly check " + good + " --baseline " + baseline);
  ASSERT_EQ(r.exit_code, 1) << r.output;
  EXPECT_THAT(r.output, AllOf(HasSubstr("REGRESSION performance: case nightly/guided/256x192/threads:1"),
                              HasSubstr("cornell-box 256x192 16spp"), HasSubstr("method guided"),
                              HasSubstr("time_ratio rose from 8.5 to 17"), HasSubstr("+100.0%")));
  // The same baseline measured on another CPU: ratios are not compared (a note says so) unless required.
  b["cpu_model"] = "Other CPU";
  write(baseline + "/baseline.json", b.dump(1));
  r = dnb("nightly check " + good + " --baseline " + baseline);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_THAT(r.output, HasSubstr("performance gate skipped"));
  r = dnb("nightly check " + good + " --baseline " + baseline + " --require-performance");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

TEST_F(NightlyCommand, BadInputExitsTwoSayingWhatIsWrong) {
  auto r = dnb("nightly check " + good + " --baseline " + dir.file("nowhere"));
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, AllOf(HasSubstr("nowhere/baseline.json"), HasSubstr("no baseline"), HasSubstr("nightly accept")));

  const std::string broken = dir.file("broken");
  fs::create_directories(broken);
  write(fs::path(broken) / "results.json", "{\"format\": \"denoisebench-results-1\", ");
  r = dnb("nightly check " + broken + " --baseline " + baseline);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, AllOf(HasSubstr("broken/results.json"), HasSubstr("not valid JSON")));

  // A run without one of the baseline's methods.
  const std::string partial = dir.file("partial");
  fs::create_directories(partial);
  json res = json::parse(slurp(good + "/results.json"));
  json kept = json::array();
  for (const auto& rec : res["records"])
    if (rec["method"] != "guided") kept.push_back(rec);
  res["records"] = kept;
  write(fs::path(partial) / "results.json", res.dump());
  fs::copy_file(good + "/bench.json", partial + "/bench.json");
  r = dnb("nightly check " + partial + " --baseline " + baseline);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, AllOf(HasSubstr("no result for scene cornell-box, method guided")));

  // A run without its benchmark file, and a malformed gates file.
  fs::remove(partial + "/bench.json");
  res["records"] = json::parse(slurp(good + "/results.json"))["records"];
  write(fs::path(partial) / "results.json", res.dump());
  r = dnb("nightly check " + partial + " --baseline " + baseline);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, HasSubstr("bench.json"));
  write(baseline + "/gates.json", "{\"format\": \"denoisebench-nightly-gates-1\", \"quality\": {}}");
  r = dnb("nightly check " + good + " --baseline " + baseline);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_THAT(r.output, AllOf(HasSubstr("gates.json"), HasSubstr("default_tolerance")));
}

}  // namespace
}  // namespace dnb
