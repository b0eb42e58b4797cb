// The nightly gates (experiment/nightly.h) on hand-made summaries: identical input passes, a
// worse MSE, a proposed that falls behind and a faster baseline ratio each fail with a message
// naming the scene, method, metric, old and new values; bad input is an InputError; the
// results and benchmark files are read as their programs write them; tolerances follow
// their stated rule; the history keeps every row as columns come and go.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/errors.h"
#include "experiment/nightly.h"
#include "test_util.h"

namespace dnb::nightly {
namespace {

using ::testing::AllOf;
using ::testing::HasSubstr;
using nlohmann::json;

Summary example() {
  Summary s;
  s.date = "2025-01-01T00:00:00Z";
  s.git_revision = "abc";
  s.machine = "host (CPU X, 2 threads)";
  s.cpu_model = "CPU X";
  s.config = {{"name", "quick"}, {"width", 256}, {"height", 192}, {"spp", {16}}, {"seed", 1}, {"reference_spp", 256}};
  for (const char* scene : {"cornell-box", "conference"}) {
    s.quality.push_back({scene, "proposed", "method", 16, 10.0});
    s.quality.push_back({scene, "guided", "method", 16, 12.0});
    s.quality.push_back({scene, "bilateral", "method", 16, 30.0});
    s.quality.push_back({scene, "proposed-no-nlm", "ablation", 16, 11.0});
  }
  s.performance.push_back({"nightly/guided/256x192/threads:1", "guided", "cornell-box 256x192 16spp", 17.0, 16.5, 17.5, 26, 1.5, 5, ""});
  s.performance.push_back({"nightly/proposed/256x192/threads:1", "proposed", "cornell-box 256x192 16spp", 70.0, 68, 72, 105, 1.5, 5, ""});
  return s;
}

Gates example_gates() {
  Gates g;
  g.quality_default = 0.05;
  g.quality["guided"] = 0.10;
  g.quality["conference/guided"] = 0.20;
  g.performance_default = 0.25;
  g.ahead_method = "proposed";
  g.ahead_of = {"guided", "bilateral"};
  return g;
}

QualityEntry& entry(Summary& s, const std::string& scene, const std::string& method) {
  for (auto& e : s.quality)
    if (e.scene == scene && e.method == method) return e;
  throw std::runtime_error("no entry");
}

std::vector<Finding> failed(const Verdict& v) {
  std::vector<Finding> out;
  for (const auto& f : v.findings)
    if (f.failed) out.push_back(f);
  return out;
}

TEST(NightlyCheck, IdenticalRunPassesEveryGate) {
  const Summary s = example();
  const Verdict v = check(s, s, example_gates());
  EXPECT_TRUE(v.passed());
  EXPECT_TRUE(v.performance_checked);
  // 8 MSE entries, 2 scenes x 2 ahead pairs, 2 benchmark cases.
  EXPECT_EQ(v.findings.size(), 8u + 4u + 2u);
  EXPECT_THAT(v.markdown(s, s), HasSubstr("# Nightly check: PASS"));
}

TEST(NightlyCheck, WorseMseFailsNamingSceneMethodMetricOldAndNew) {
  const Summary base = example();
  Summary now = base;
  entry(now, "conference", "bilateral").mse = 33.0;  // +10%, tolerance 5%
  const Verdict v = check(base, now, example_gates());
  ASSERT_FALSE(v.passed());
  const auto f = failed(v);
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].gate, "quality");
  EXPECT_EQ(f[0].scene, "conference");
  EXPECT_EQ(f[0].method, "bilateral");
  EXPECT_EQ(f[0].metric, "mse");
  EXPECT_DOUBLE_EQ(f[0].old_value, 30.0);
  EXPECT_DOUBLE_EQ(f[0].new_value, 33.0);
  EXPECT_THAT(f[0].message, AllOf(HasSubstr("scene conference"), HasSubstr("method bilateral"), HasSubstr("mse rose"),
                                  HasSubstr("from 30 to 33"), HasSubstr("+10.0%"), HasSubstr("tolerance +5.0%")));
  EXPECT_THAT(v.markdown(base, now), AllOf(HasSubstr("FAIL (1 regressions)"), HasSubstr(f[0].message)));
  EXPECT_FALSE(v.to_json()["passed"].get<bool>());
  EXPECT_EQ(v.to_json()["failures"][0]["old"].get<double>(), 30.0);
}

TEST(NightlyCheck, ToleranceIsLookedUpBySceneAndMethodThenMethodThenDefault) {
  const Gates g = example_gates();
  EXPECT_DOUBLE_EQ(g.quality_tolerance("conference", "guided"), 0.20);
  EXPECT_DOUBLE_EQ(g.quality_tolerance("cornell-box", "guided"), 0.10);
  EXPECT_DOUBLE_EQ(g.quality_tolerance("cornell-box", "bilateral"), 0.05);
}

TEST(NightlyCheck, RiseWithinTheMethodsToleranceAndImprovementsPass) {
  const Summary base = example();
  Summary now = base;
  entry(now, "cornell-box", "guided").mse = 12.0 * 1.09;  // guided's own tolerance: 10%
  entry(now, "cornell-box", "proposed").mse = 9.0;        // better
  EXPECT_TRUE(check(base, now, example_gates()).passed());
  entry(now, "cornell-box", "guided").mse = 12.0 * 1.11;
  EXPECT_FALSE(check(base, now, example_gates()).passed());
}

TEST(NightlyCheck, NonFiniteMseFails) {
  const Summary base = example();
  Summary now = base;
  entry(now, "cornell-box", "proposed-no-nlm").mse = NAN;
  const auto f = failed(check(base, now, example_gates()));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_THAT(f[0].message, HasSubstr("non-finite"));
}

TEST(NightlyCheck, ProposedFallingBehindABaselineFails) {
  const Summary base = example();
  Summary now = base;
  entry(now, "cornell-box", "proposed").mse = 10.4;  // within its 5% tolerance...
  entry(now, "cornell-box", "guided").mse = 10.4;    // ...but no longer ahead of guided (a tie is not ahead)
  const auto f = failed(check(base, now, example_gates()));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].gate, "ahead");
  EXPECT_EQ(f[0].compared_with, "guided");
  EXPECT_THAT(f[0].message, AllOf(HasSubstr("scene cornell-box"), HasSubstr("method proposed mse 10.4 is not below"),
                                  HasSubstr("method guided mse 10.4")));
}

TEST(NightlyCheck, AblationVariantsAreNotBaselinesToBeAheadOf) {
  const Summary base = example();
  Summary now = base;
  entry(now, "cornell-box", "proposed-no-nlm").mse = 9.5;  // an ablation may beat the full method
  EXPECT_TRUE(check(base, now, example_gates()).passed());
}

TEST(NightlyCheck, FasterBaselineRatioFailsThePerformanceGate) {
  const Summary now = example();
  Summary base = now;
  base.performance[1].ratio = 50.0;  // the baseline was faster: 70 / 50 = +40% > 25%
  const auto f = failed(check(base, now, example_gates()));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].gate, "performance");
  EXPECT_EQ(f[0].method, "proposed");
  EXPECT_EQ(f[0].metric, "time_ratio");
  EXPECT_THAT(f[0].message, AllOf(HasSubstr("nightly/proposed/256x192/threads:1"), HasSubstr("cornell-box 256x192"),
                                  HasSubstr("method proposed"), HasSubstr("time_ratio rose from 50 to 70"),
                                  HasSubstr("+40.0%"), HasSubstr("tolerance +25.0%")));
}

TEST(NightlyCheck, AllCoreCasesAreReportedNotGated) {
  Summary base = example();
  base.performance.push_back({"nightly/guided/256x192/threads:all", "guided", "cornell-box 256x192 16spp", 17.0, 17, 17, 16, 0.9, 5, ""});
  Summary now = base;
  now.performance.back().ratio = 34.0;  // twice as slow, but an all-core wall time
  const Verdict v = check(base, now, example_gates());
  EXPECT_TRUE(v.passed());
  ASSERT_FALSE(v.notes.empty());
  EXPECT_THAT(v.notes.back(), AllOf(HasSubstr("reported only (not gated)"), HasSubstr("threads:all"),
                                    HasSubstr("time_ratio rose from 17 to 34")));
  EXPECT_THAT(v.markdown(base, now), HasSubstr("over (report only)"));
  Gates all_gated = example_gates();
  all_gated.performance_report_only.clear();
  EXPECT_FALSE(check(base, now, all_gated).passed());
  // The list survives the gates file.
  EXPECT_EQ(Gates::from_json(json::parse(example_gates().to_json().dump()), "g").performance_report_only,
            std::vector<std::string>{"/threads:all"});
}

TEST(NightlyCheck, FailedBenchmarkCaseFails) {
  const Summary base = example();
  Summary now = base;
  now.performance[0].ratio = NAN;
  now.performance[0].error = "proposed: device=opencl: no platform";
  const auto f = failed(check(base, now, example_gates()));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_THAT(f[0].message, HasSubstr("now the case fails: proposed: device=opencl: no platform"));
}

TEST(NightlyCheck, PerformanceIsSkippedOnAnotherCpuUnlessRequired) {
  const Summary base = example();
  Summary now = base;
  now.cpu_model = "CPU Y";
  now.performance[1].ratio = 500;  // would fail, but ratios of another CPU are not comparable
  const Verdict v = check(base, now, example_gates());
  EXPECT_TRUE(v.passed());
  EXPECT_FALSE(v.performance_checked);
  ASSERT_FALSE(v.notes.empty());
  EXPECT_THAT(v.notes.back(), AllOf(HasSubstr("performance gate skipped"), HasSubstr("CPU X"), HasSubstr("CPU Y")));
  CheckOptions require;
  require.require_performance = true;
  EXPECT_THROW(check(base, now, example_gates(), require), InputError);
}

TEST(NightlyCheck, MissingEntriesAndOtherConfigsAreInputErrors) {
  const Summary base = example();
  auto message = [&](const Summary& now) {
    try {
      check(base, now, example_gates());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  Summary now = base;
  now.quality.erase(now.quality.begin() + 2);  // cornell-box bilateral
  EXPECT_THAT(message(now), AllOf(HasSubstr("scene cornell-box"), HasSubstr("method bilateral")));
  now = base;
  now.performance.pop_back();
  EXPECT_THAT(message(now), HasSubstr("nightly/proposed/256x192/threads:1"));
  now = base;
  now.performance.clear();
  EXPECT_THAT(message(now), HasSubstr("no nightly benchmark results"));
  now = base;
  now.config["width"] = 64;
  EXPECT_THAT(message(now), AllOf(HasSubstr("width"), HasSubstr("256"), HasSubstr("64")));
}

// The instruction gate (scripts/nightly_instructions' counts): a rise beyond the tolerance
// fails naming the case, method and both counts; within it, or a fall, passes; another CPU or
// a side without counts skips it with a note; the counts survive the summary's JSON.
TEST(NightlyCheck, InstructionCountsRisingBeyondTheToleranceFail) {
  Summary base = example();
  base.instructions = {{"nightly/guided/64x48/threads:1", "guided", 8.0e7}, {"nightly/proposed/64x48/threads:1", "proposed", 4.0e8}};
  base.instructions_cpu_model = "CPU X";
  Summary now = base;
  now.instructions[1].instructions = 4.2e8;  // +5% > 3%
  now.instructions[0].instructions = 8.1e7;  // +1.25%: passes
  Gates g = example_gates();
  EXPECT_DOUBLE_EQ(g.instructions_default, 0.03);
  const auto f = failed(check(base, now, g));
  ASSERT_EQ(f.size(), 1u);
  EXPECT_EQ(f[0].gate, "instructions");
  EXPECT_EQ(f[0].method, "proposed");
  EXPECT_THAT(f[0].message, AllOf(HasSubstr("nightly/proposed/64x48/threads:1"), HasSubstr("rose from 4e+08 to 4.2e+08"),
                                  HasSubstr("+5.0%"), HasSubstr("tolerance +3.0%")));
  EXPECT_THAT(check(base, now, g).markdown(base, now), HasSubstr("## Instructions (one run, callgrind)"));
  g.instructions_default = 0.06;  // read from gates.json
  EXPECT_TRUE(check(base, now, Gates::from_json(json::parse(g.to_json().dump()), "g")).passed());

  Summary other_cpu = now;
  other_cpu.instructions_cpu_model = "CPU Y";
  const Verdict v = check(base, other_cpu, example_gates());
  EXPECT_TRUE(v.passed());
  EXPECT_THAT(v.notes, testing::Contains(AllOf(HasSubstr("instruction gate skipped"), HasSubstr("CPU Y"))));
  Summary uncounted = now;
  uncounted.instructions.clear();
  EXPECT_THAT(check(base, uncounted, example_gates()).notes,
              testing::Contains(HasSubstr("this run has no instruction counts")));
  Summary missing = now;
  missing.instructions.pop_back();
  EXPECT_THROW(check(base, missing, example_gates()), InputError);

  const Summary back = Summary::from_json(json::parse(now.to_json().dump()), "summary");
  ASSERT_EQ(back.instructions.size(), 2u);
  EXPECT_EQ(back.instructions[1].instructions, 4.2e8);
  EXPECT_EQ(back.instructions_cpu_model, "CPU X");
  // A summary from before the gate (no "instructions" key) still reads, with no counts.
  json old = base.to_json();
  old.erase("instructions");
  EXPECT_TRUE(Summary::from_json(old, "old").instructions.empty());
}

TEST(NightlySummary, ReadsInstructionCountsAndRefusesMalformedOnes) {
  const json doc = {{"format", "denoisebench-instructions-1"},
                    {"context", {{"cpu_model", "CPU X"}}},
                    {"cases", {{{"name", "nightly/nfor/64x48/threads:1"}, {"instructions", 20241080582}}}}};
  Summary s;
  add_instructions(s, doc, "i.json");
  ASSERT_EQ(s.instructions.size(), 1u);
  EXPECT_EQ(s.instructions[0].method, "nfor");
  EXPECT_EQ(s.instructions[0].instructions, 20241080582.0);
  EXPECT_EQ(s.instructions_cpu_model, "CPU X");
  auto error = [](json d) { return test::error_of<InputError>([&] { Summary t; add_instructions(t, d, "i.json"); }); };
  json bad = doc;
  bad["format"] = "other";
  EXPECT_THAT(error(bad), AllOf(HasSubstr("i.json"), HasSubstr("format")));
  bad = doc;
  bad["cases"][0]["instructions"] = 0;
  EXPECT_THAT(error(bad), AllOf(HasSubstr("cases[0]"), HasSubstr("positive")));
  bad = doc;
  bad["cases"][0]["name"] = "guided";
  EXPECT_THAT(error(bad), AllOf(HasSubstr("cases[0]"), HasSubstr("nightly/<method>")));
  bad = doc;
  bad["cases"] = json::array();
  EXPECT_THAT(error(bad), HasSubstr("cases"));
}

TEST(NightlyCheck, NewEntriesAreNotedNotGated) {
  const Summary base = example();
  Summary now = base;
  now.quality.push_back({"cornell-box", "new-method", "method", 16, 99.0});
  const Verdict v = check(base, now, example_gates());
  EXPECT_TRUE(v.passed());
  EXPECT_THAT(v.notes, testing::Contains(HasSubstr("method new-method: new in this run")));
}

// ---------------------------------------------------------------------------------------------
// Reading results.json and bench.json

json results_doc() {
  json r = {{"format", "denoisebench-results"},
            {"schema_version", 2},
            {"git_revision", "r1"},
            {"machine", {{"hostname", "h"}, {"cpu", "CPU X"}, {"hardware_threads", 2}}},
            {"config", {{"name", "tiny"}, {"width", 32}, {"height", 24}, {"spp", {2}}, {"seed", 1}, {"reference_spp", 16}}}};
  auto record = [](const char* method, const char* role, int spp, json mse) {
    return json{{"scene", "cornell-box"}, {"method", method}, {"role", role}, {"spp", spp}, {"width", 32}, {"height", 24},
                {"metrics", {{"mse", mse}}}, {"times", {{"input_render", 1.0}, {"filter", 0.0}, {"total", 1.0}}},
                {"reference", {{"spp", 16}, {"seconds", 2.0}}}};
  };
  r["records"] = {record("input", "input", 2, 900.0), record("path_tracing", "plain", 1, 1900.0),
                  record("guided", "method", 2, 40.5), record("guided-wide", "ablation", 2, nullptr)};
  return r;
}

Summary summarize_json(const json& results, const std::string& where, const json* bench, const std::string& where_bench) {
  return summarize(experiment::ResultsDocument::from_json(results, where), where, bench, where_bench);
}

json bench_run(const std::string& name, double ratio, const std::string& type = "iteration") {
  json b = {{"name", name + (type == "iteration" ? "" : "_" + type)}, {"run_name", name}, {"run_type", type == "iteration" ? "iteration" : "aggregate"},
            {"ratio", ratio}, {"method_ms", 10 * ratio}, {"reference_ms", 10.0}, {"label", "cornell-box 32x24 16spp"}};
  if (type != "iteration") b["aggregate_name"] = type;
  return b;
}

json bench_doc() {
  const std::string g = "nightly/guided/32x24/threads:1/manual_time";
  json runs = {bench_run(g, 3.0), bench_run(g, 1.0), bench_run(g, 2.0), bench_run(g, 99.0, "mean"),
               bench_run("am/ours/1024x768/guide8", 5.0),
               json{{"name", "nightly/proposed:opencl/32x24/threads:all/manual_time"},
                    {"run_name", "nightly/proposed:opencl/32x24/threads:all/manual_time"},
                    {"run_type", "iteration"},
                    {"error_occurred", true},
                    {"error_message", "no OpenCL device"}}};
  return {{"context", {{"cpu_model", "CPU Z"}, {"nightly_reference_workload", "path tracing ..."}}}, {"benchmarks", runs}};
}

TEST(NightlySummary, ReadsMethodRecordsAndNightlyCases) {
  const json b = bench_doc();
  const Summary s = summarize_json(results_doc(), "results.json", &b, "bench.json");
  ASSERT_EQ(s.quality.size(), 2u);  // the input and plain path tracing are not methods
  EXPECT_EQ(s.quality[0].method, "guided");
  EXPECT_DOUBLE_EQ(s.quality[0].mse, 40.5);
  EXPECT_EQ(s.quality[1].role, "ablation");
  EXPECT_TRUE(std::isnan(s.quality[1].mse));  // null in results.json: a non-finite metric
  EXPECT_EQ(s.cpu_model, "CPU Z");
  ASSERT_EQ(s.performance.size(), 2u);
  EXPECT_EQ(s.performance[0].name, "nightly/guided/32x24/threads:1");
  EXPECT_EQ(s.performance[0].method, "guided");
  EXPECT_DOUBLE_EQ(s.performance[0].ratio, 2.0);  // median of the repetitions; aggregates ignored
  EXPECT_DOUBLE_EQ(s.performance[0].ratio_min, 1.0);
  EXPECT_EQ(s.performance[0].repetitions, 3);
  EXPECT_EQ(s.performance[0].frame, "cornell-box 32x24 16spp");
  EXPECT_EQ(s.performance[1].method, "proposed:opencl");
  EXPECT_TRUE(std::isnan(s.performance[1].ratio));
  EXPECT_EQ(s.performance[1].error, "no OpenCL device");
  // The summary survives its own file format.
  const Summary back = Summary::from_json(json::parse(s.to_json().dump()), "summary.json");
  EXPECT_EQ(back.quality.size(), 2u);
  EXPECT_EQ(back.performance[1].error, "no OpenCL device");
}

TEST(NightlySummary, SeveralSeedsGiveOneEntryPerCellTheMeanOfItsSeeds) {
  json r = results_doc();
  r["schema_version"] = 4;
  r["config"]["seeds"] = {1, 2};
  json guided = r["records"][2], other_seed = guided;
  guided["seed"] = 1;
  other_seed["seed"] = 2;
  other_seed["metrics"]["mse"] = 50.5;  // seed 1 has 40.5
  r["records"][2] = guided;
  r["records"].erase(3);  // the ablation: one seed is enough here
  r["records"].push_back(other_seed);
  const Summary s = summarize_json(r, "results.json", nullptr, "");
  ASSERT_EQ(s.quality.size(), 1u);
  EXPECT_DOUBLE_EQ(s.quality[0].mse, 45.5);
  EXPECT_EQ(s.config.at("seeds"), json({1, 2}));
  // The same seed twice is a malformed file, named.
  r["records"].push_back(other_seed);
  try {
    summarize_json(r, "results.json", nullptr, "");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("records[4]: a second record for scene cornell-box, method guided, spp 2, seed 2"));
  }
}

TEST(NightlySummary, MalformedInputNamesTheFileAndKey) {
  auto message = [](const json& r) {
    try {
      summarize_json(r, "run/results.json", nullptr, "");
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  json r = results_doc();
  r["format"] = "something else";
  EXPECT_THAT(message(r), AllOf(HasSubstr("run/results.json"), HasSubstr("format")));
  r = results_doc();
  r.erase("records");
  EXPECT_THAT(message(r), AllOf(HasSubstr("run/results.json"), HasSubstr("'records'")));
  r = results_doc();
  r["records"][2]["metrics"]["mse"] = "high";
  EXPECT_THAT(message(r), AllOf(HasSubstr("records[2]"), HasSubstr("'mse'")));
  r = results_doc();
  r["records"][3]["method"] = "guided";
  r["records"][3]["role"] = "method";
  EXPECT_THAT(message(r), HasSubstr("a second record"));
  EXPECT_THROW(Summary::from_json(json::array(), "x"), InputError);
  EXPECT_THROW(Gates::from_json(json{{"format", "denoisebench-nightly-gates-1"}}, "gates.json"), InputError);
}

TEST(NightlySummary, MissingOrBrokenRunFolderIsAnInputError) {
  test::TempDir dir;
  EXPECT_THROW(summarize_run(dir.path().string()), InputError);
  std::ofstream(dir.file("results.json")) << "{ not json";
  try {
    summarize_run(dir.path().string());
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AllOf(HasSubstr("results.json"), HasSubstr("not valid JSON")));
  }
}

// ---------------------------------------------------------------------------------------------
// Tolerances and history

TEST(NightlyTolerances, FollowTheStatedRule) {
  std::vector<Summary> seeds(3, example());
  // guided on conference: MSE 10, 11, 12 -> relative std 1/11; other entries identical.
  entry(seeds[0], "conference", "guided").mse = 10;
  entry(seeds[1], "conference", "guided").mse = 11;
  entry(seeds[2], "conference", "guided").mse = 12;
  std::vector<Summary> perf(2, example());
  perf[1].performance[0].ratio = 17.0 * 1.1;  // relative std of (17, 18.7): 0.1 / 1.05 / sqrt(2)
  DeriveOptions o;  // k 3 and 4.25, floors 2% and 10%
  const Gates g = derive_gates(seeds, {"a", "b", "c"}, perf, {"p", "q"}, example_gates(), o);
  EXPECT_NEAR(g.quality_tolerance("conference", "guided"), 3.0 / 11.0, 1e-12);
  EXPECT_DOUBLE_EQ(g.quality_tolerance("cornell-box", "guided"), 0.02);  // identical there: the floor
  EXPECT_NEAR(g.quality_tolerance("sponza", "guided"), 3.0 / 11.0, 1e-12);  // a new scene: the method's largest
  EXPECT_DOUBLE_EQ(g.quality_tolerance("conference", "bilateral"), 0.02);
  EXPECT_NEAR(g.quality_default, 3.0 / 11.0, 1e-12);  // the largest
  const double rs = 0.1 * 17 / std::sqrt(2.0) / (17 * 1.05);
  EXPECT_NEAR(g.performance.at("nightly/guided/256x192/threads:1"), 4.25 * rs, 1e-9);  // above max/min - 1 = 0.1
  EXPECT_DOUBLE_EQ(g.performance.at("nightly/proposed/256x192/threads:1"), 0.10);
  // One outlier among many equal runs: the relative std is small, the range is not.
  std::vector<Summary> many(24, example());
  many[23].performance[1].ratio = 70.0 * 1.5;  // relative std 0.1: 4.25x that is below 0.5
  const Gates h = derive_gates({}, {}, many, std::vector<std::string>(24, "run"), example_gates(), o);
  EXPECT_DOUBLE_EQ(h.performance.at("nightly/proposed/256x192/threads:1"), 0.5);
  EXPECT_EQ(g.ahead_of, example_gates().ahead_of);  // kept
  EXPECT_TRUE(g.derivation.contains("quality"));
  EXPECT_TRUE(g.derivation.contains("performance"));
  // The file format round-trips.
  const Gates back = Gates::from_json(json::parse(g.to_json().dump()), "gates.json");
  EXPECT_DOUBLE_EQ(back.quality_tolerance("conference", "guided"), g.quality.at("conference/guided"));
  EXPECT_DOUBLE_EQ(back.quality_tolerance("conference", "unknown"), g.quality_default);
  EXPECT_THROW(derive_gates({example()}, {"a"}, {}, {}, example_gates(), o), InputError);
}

// `denoisebench nightly tolerances` (scripts/nightly_noise) reads run folders and bench files as
// the programs write them, keeps the baseline's ahead rule and writes gates.json.
TEST(NightlyTolerances, DerivedFromRunFoldersAndBenchFilesIntoTheBaseline) {
  test::TempDir dir;
  std::vector<std::string> runs;
  for (double mse : {40.0, 44.0, 48.0}) {  // guided: relative std 4 / 44
    json r = results_doc();
    r["records"][2]["metrics"]["mse"] = mse;
    const std::string run = dir.file("run" + std::to_string(runs.size()));
    std::filesystem::create_directories(run);
    test::write(run + "/results.json", r.dump());
    runs.push_back(run);
  }
  std::vector<std::string> benches;
  for (double scale : {1.0, 1.1}) {
    json b = bench_doc();
    for (auto& run : b["benchmarks"])
      if (run.contains("ratio")) run["ratio"] = run["ratio"].get<double>() * scale;
    benches.push_back(dir.file("bench" + std::to_string(benches.size()) + ".json"));
    test::write(benches.back(), b.dump());
  }
  const std::string baseline = dir.file("baseline");
  std::filesystem::create_directories(baseline);
  test::write(baseline + "/gates.json", example_gates().to_json().dump());
  const Gates g = derive_tolerances(runs, benches, baseline);
  EXPECT_NEAR(g.quality_tolerance("cornell-box", "guided"), 3.0 * 4.0 / 44.0, 1e-12);
  // The guided case's median ratio is 2.0 and 2.2: relative std 0.1 / sqrt(2) / 1.05 (the rule
  // of FollowTheStatedRule), times 4.25.
  EXPECT_NEAR(g.performance.at("nightly/guided/32x24/threads:1"), 4.25 * 0.1 / std::sqrt(2.0) / 1.05, 1e-9);
  EXPECT_EQ(g.ahead_of, example_gates().ahead_of);  // the baseline's rule, kept
  const Gates written = Gates::from_json(json::parse(test::slurp(baseline + "/gates.json")), "gates.json");
  EXPECT_DOUBLE_EQ(written.quality_tolerance("cornell-box", "guided"), g.quality_tolerance("cornell-box", "guided"));
  EXPECT_THROW(derive_tolerances({}, {}, baseline), InputError);
  test::write(dir.file("empty.json"), json{{"context", json::object()}, {"benchmarks", json::array()}}.dump());
  EXPECT_THROW(derive_tolerances({}, {dir.file("empty.json")}, baseline), InputError);
}

TEST(NightlyTolerances, DefaultAheadRuleListsTheFiltersNotTheRenderers) {
  Summary s = example();
  s.quality.push_back({"cornell-box", "irradiance_cache", "method", 16, 5.0});
  Gates empty = example_gates();
  empty.ahead_of.clear();
  const Gates g = derive_gates({s, s}, {"a", "b"}, {}, {}, empty, DeriveOptions{});
  // The irradiance cache renders with its own budget: not a filter of the same frame.
  EXPECT_EQ(g.ahead_of, (std::vector<std::string>{"guided", "bilateral"}));
}

TEST(NightlyHistory, AppendsOneRowPerRunAndWidensTheHeader) {
  test::TempDir dir;
  const std::string path = dir.file("sub/history.csv");
  Summary s = example();
  append_history(path, s, check(s, s, example_gates()));
  Summary t = s;
  t.quality.push_back({"sponza", "guided", "method", 16, 5.0});
  t.machine = "host, with a comma";
  Summary base = s;
  base.quality.push_back({"sponza", "guided", "method", 16, 4.0});
  Gates no_ahead = example_gates();
  no_ahead.ahead_method.clear();
  append_history(path, t, check(base, t, no_ahead));
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string l; std::getline(in, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_THAT(lines[0], AllOf(HasSubstr("date,git_revision,machine,config,verdict,failures,failed_checks"),
                              HasSubstr("mse/cornell-box/proposed"), HasSubstr("ratio/nightly/guided/256x192/threads:1"),
                              HasSubstr("mse/sponza/guided")));
  EXPECT_THAT(lines[1], AllOf(HasSubstr(",pass,0,"), testing::EndsWith(",")));  // no sponza value then
  EXPECT_THAT(lines[2], AllOf(HasSubstr("\"host, with a comma\""), HasSubstr(",fail,1,quality sponza guided,"),
                              testing::EndsWith(",5")));
  // A file that is not a history is refused rather than overwritten.
  std::ofstream(dir.file("other.csv")) << "a,b\n1,2\n";
  EXPECT_THROW(append_history(dir.file("other.csv"), s, check(s, s, example_gates())), InputError);
}

}  // namespace
}  // namespace dnb::nightly
