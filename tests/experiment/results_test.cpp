// experiment/results.h: the one schema of results.json. A document survives its own file
// format exactly, and every malformed or older file is refused naming the file and the key.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <thread>

#include <unistd.h>

#include <fmt/format.h>

#include "core/errors.h"
#include "experiment/results.h"
#include "experiment/store.h"
#include "test_util.h"

namespace dnb::experiment {
namespace {

using nlohmann::json;
using ::testing::AllOf;
using ::testing::HasSubstr;

CellRecord method_record() {
  CellRecord r;
  r.scene = "cornell-box";
  r.scene_hash = "abc";
  r.method = "proposed-no-nlm";
  r.role = Role::Ablation;
  r.spp = 16;
  r.width = 64;
  r.height = 48;
  r.seed = 7;
  r.cell_key = "k1";
  r.metrics = {{"mse", 12.5}, {"psnr", std::nullopt}};
  r.times.input_render = 1.0;
  r.times.filter = 0.25;
  r.times.total = 1.25;
  r.times.reference = 600;
  r.times.filter_runs = std::vector<double>{0.3, 0.25, 0.2};
  r.times.setup = 2.5;
  r.reference = {.spp = 1024, .seed = 1000003, .seconds = 600, .cache_hit = true, .image = "images/c/reference.exr",
                 .unconverged_share = 0.0125, .unconverged_rse = 0.5,
                 .estimated_error = std::map<std::string, double>{{"mse", 0.75}, {"mse_hdr", 1e-5}, {"relmse", 2e-4}}};
  r.files = {{"image", "images/c/x_16.exr"}, {"error_flip", "images/c/x_16.err_flip.exr"}};
  r.input_cache_hit = false;
  r.base_method = "proposed";
  r.kind = MethodKind::Filter;
  r.params = std::map<std::string, std::string>{{"nlm_space", "false"}};
  r.phases = std::map<std::string, double>{{"nlm", 0.1}};
  r.counters = std::map<std::string, double>{{"repaired_samples", 0}};
  r.method_info = std::map<std::string, std::string>{{"oidn_version", "2.5.1"}, {"package", "pyoidn==2.5.1.0"}};
  return r;
}

ResultsDocument document() {
  ResultsDocument d;
  d.config.name = "tiny";
  d.config.width = 64;
  d.config.height = 48;
  d.config.spp = {16};
  d.config.scenes = {"cornell-box"};
  d.config.table2.filter_opencl = "proposed:opencl";
  d.config.methods = {{"proposed-no-nlm", "proposed", "ablation", {{"nlm_space", "false"}}}};
  d.machine = {{"hostname", "h"}};
  d.git_revision = "r1";
  d.written = 1700000000;
  CellRecord input;
  input.scene = "cornell-box";
  input.method = "input";
  input.role = Role::Input;
  input.spp = 16;
  input.width = 64;
  input.height = 48;
  input.metrics = {{"mse", 90.0}};
  input.files = {{"image", "images/c/input_16.exr"}, {"frame", "frames/c/input_16.exr"},
                 {"frame_edges", "frames/c/input_16.edges.exr"}};
  d.records = {input, method_record()};
  d.config.scene_files = {{"mine", {"/data/in.exr", "/data/ref.exr", ""}}};
  d.skipped = {{"mine", "irradiance_cache", 16, "renders the scene itself; 'mine' is read from files"}};
  d.failures = {{"cornell-box", "plug", 16, "k2", "plug-in 'plug' (p.toml): the program exited with status 1", {"Traceback", "E"}}};
  return d;
}

TEST(ResultsDocument, SurvivesItsOwnFileFormatExactly) {
  const json j = document().to_json();
  EXPECT_EQ(j.at("format"), "denoisebench-results");
  EXPECT_EQ(j.at("schema_version"), 4);
  EXPECT_TRUE(j.at("records")[1].at("metrics").at("psnr").is_null());  // non-finite as null
  const ResultsDocument back = ResultsDocument::from_json(json::parse(j.dump()), "results.json");
  EXPECT_EQ(back.to_json(), j);
  const CellRecord& r = back.records[1];
  EXPECT_EQ(r.role, Role::Ablation);
  EXPECT_EQ(r.metric("mse"), 12.5);
  EXPECT_EQ(r.metric("psnr"), std::nullopt);
  EXPECT_EQ(r.metric("flip"), std::nullopt);
  EXPECT_EQ(r.image(), "images/c/x_16.exr");
  EXPECT_EQ(back.config.table2.filter_opencl, "proposed:opencl");
  EXPECT_EQ(back.config.table2.filter_cpu, "proposed");  // the default, written once
  EXPECT_EQ(r.times.setup, 2.5);
  ASSERT_TRUE(r.method_info.has_value());
  EXPECT_EQ(r.method_info->at("oidn_version"), "2.5.1");
  EXPECT_EQ(r.reference.estimated_error->at("mse"), 0.75);
  ASSERT_EQ(back.failures.size(), 1u);
  EXPECT_EQ(back.failures[0].log_tail, (std::vector<std::string>{"Traceback", "E"}));
  EXPECT_NE(back.failure("cornell-box", "plug", 16), nullptr);
  EXPECT_EQ(back.failure("cornell-box", "plug", 4), nullptr);
  EXPECT_EQ(back.records[0].file("frame"), "frames/c/input_16.exr");
  EXPECT_EQ(back.records[0].file("frame_edges"), "frames/c/input_16.edges.exr");
  EXPECT_EQ(back.config.scene_files.at("mine"), (SceneFilesEntry{"/data/in.exr", "/data/ref.exr", ""}));
  ASSERT_NE(back.skip("mine", "irradiance_cache", 16), nullptr);
  EXPECT_EQ(back.skip("mine", "irradiance_cache", 4), nullptr);
  // A version 2 file (no failures, no setup_seconds) and a version 3 one (no frames, no
  // scene_files, no skipped) are still read.
  json v2 = j;
  v2["schema_version"] = 2;
  v2.erase("failures");
  EXPECT_TRUE(ResultsDocument::from_json(v2, "results.json").failures.empty());
  json v3 = j;
  v3["schema_version"] = 3;
  v3.erase("skipped");
  v3["config"].erase("scene_files");
  v3["records"][0]["files"].erase("frame");
  v3["records"][0]["files"].erase("frame_edges");
  const ResultsDocument old = ResultsDocument::from_json(v3, "results.json");
  EXPECT_TRUE(old.skipped.empty());
  EXPECT_TRUE(old.config.scene_files.empty());
  EXPECT_EQ(old.records[0].file("frame"), "");
  json v9 = j;
  v9["schema_version"] = 9;
  EXPECT_THROW(ResultsDocument::from_json(v9, "results.json"), InputError);
  // A record that has no optional fields writes none of them.
  EXPECT_FALSE(j.at("records")[0].contains("params"));
  EXPECT_FALSE(j.at("records")[0].contains("base_method"));
  EXPECT_FALSE(j.at("records")[0].at("reference").contains("estimated_error"));
}

TEST(ResultsDocument, QueriesTheTablesAreWrittenIn) {
  const ResultsDocument d = document();
  EXPECT_EQ(d.table_spp(), 16);
  EXPECT_EQ(d.scenes(), std::vector<std::string>{"cornell-box"});
  EXPECT_EQ(d.methods(Role::Ablation), std::vector<std::string>{"proposed-no-nlm"});
  EXPECT_TRUE(d.methods(Role::Method).empty());
  ASSERT_NE(d.find("cornell-box", "input", 16), nullptr);
  EXPECT_EQ(d.find("cornell-box", "input", 16)->metric("mse"), 90.0);
  EXPECT_EQ(d.find("cornell-box", "input", 256), nullptr);
}

std::string error_of(const json& j) {
  try {
    ResultsDocument::from_json(j, "'run/results.json'");
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

TEST(ResultsDocument, RefusesOlderAndMalformedFilesNamingTheFileAndKey) {
  json j = document().to_json();
  j["format"] = "denoisebench-results-1";
  j.erase("schema_version");
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("run/results.json"), HasSubstr("'format'"), HasSubstr("older")));
  j = document().to_json();
  j["schema_version"] = 1;
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("run/results.json"), HasSubstr("'schema_version'")));
  j = document().to_json();
  j["format"] = "something";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("'format'"), HasSubstr("denoisebench-results")));
  j = document().to_json();
  j["records"][1]["times"].erase("filter");
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: times"), HasSubstr("'filter'")));
  j = document().to_json();
  j["records"][1]["role"] = "baseline";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]"), HasSubstr("'role'"), HasSubstr("ablation")));
  j = document().to_json();
  j["records"][0]["spp"] = "sixteen";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[0]"), HasSubstr("'spp'"), HasSubstr("wrong type")));
  j = document().to_json();
  j["records"][1]["metrics"]["mse"] = "low";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: metrics"), HasSubstr("'mse'")));
  j = document().to_json();
  j.erase("records");
  EXPECT_THAT(error_of(j), HasSubstr("'records'"));
}

// Found by a hostile-user pass: a results.json edited by hand was reported as if a run
// had written it. Negative counts and times, a cell counted twice, and file names outside the
// folder (which the report would read and copy into its page) are refused, naming the key.
TEST(ResultsDocument, RefusesNumbersNoRunWritesAndFilesOutsideTheFolder) {
  json j = document().to_json();
  j["records"][1]["times"]["filter"] = -5;
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: times"), HasSubstr("'filter'"), HasSubstr(">= 0")));
  j = document().to_json();
  j["records"][1]["times"]["filter_runs"] = {0.1, -0.2};
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: times"), HasSubstr("'filter_runs'")));
  j = document().to_json();
  j["records"][0]["spp"] = -3;
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[0]"), HasSubstr("'spp'"), HasSubstr(">= 0")));
  j = document().to_json();
  j["records"][1]["reference"]["seconds"] = -1;
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: reference"), HasSubstr("'seconds'")));
  j = document().to_json();
  j["records"][1]["width"] = 0;
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]"), HasSubstr("'width'"), HasSubstr("1..32768")));
  j = document().to_json();
  j["records"][1]["files"]["image"] = "../../../etc/passwd";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: files"), HasSubstr("'image'"), HasSubstr("outside the results folder")));
  j = document().to_json();
  j["records"][0]["files"]["frame"] = "/etc/passwd";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[0]: files"), HasSubstr("'frame'"), HasSubstr("outside")));
  j = document().to_json();
  j["records"][1]["reference"]["image"] = "images/../../ref.exr";
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[1]: reference"), HasSubstr("'image'"), HasSubstr("outside")));
  j = document().to_json();
  j["records"].push_back(j["records"][1]);
  EXPECT_THAT(error_of(j), AllOf(HasSubstr("records[2]"), HasSubstr("'cell_key'"), HasSubstr("k1"), HasSubstr("seed 7")));
  // The same cell under another seed is another record, not a duplicate.
  j = document().to_json();
  j["records"].push_back(j["records"][1]);
  j["records"][2]["seed"] = 8;
  EXPECT_EQ(error_of(j), "no error");
}

TEST(ResultsDocument, LoadNamesAMissingOrBrokenFile) {
  test::TempDir dir;
  EXPECT_THROW(ResultsDocument::load(dir.file("results.json")), InputError);
  std::ofstream(dir.file("results.json")) << "{ not json";
  try {
    ResultsDocument::load(dir.file("results.json"));
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AllOf(HasSubstr("results.json"), HasSubstr("not valid JSON")));
  }
}

TEST(ResultsStore, KeepsEveryFinishedCellAcrossRunsAndRefusesAnOlderFolder) {
  test::TempDir dir;
  ResultsDocument header = document();
  header.records.clear();
  {
    ResultsStore store(dir.path().string(), header);
    store.add(method_record());
  }
  {
    // A second run of a config without that cell: it is not listed, but still known as finished.
    ResultsStore again(dir.path().string(), header);
    ASSERT_NE(again.finished("k1"), nullptr);
    EXPECT_EQ(again.finished("k1")->to_json(), method_record().to_json());
    EXPECT_TRUE(again.document().records.empty());
    again.write();
  }  // (one store at a time: each holds the folder's lock)
  ResultsStore third(dir.path().string(), header);
  EXPECT_NE(third.finished("k1"), nullptr) << "finished_cells.json lost a cell results.json no longer lists";

  // A folder written by the schema-1 harness cannot be resumed from: say which file and why.
  test::TempDir old;
  std::ofstream(old.file("results.json")) << R"({"format": "denoisebench-results-1", "records": []})";
  try {
    ResultsStore s(old.path().string(), header);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_THAT(e.what(), AllOf(HasSubstr("results.json"), HasSubstr("cannot be resumed"), HasSubstr("older")));
  }
}

TEST(ResultsStore, ASecondRunIntoTheFolderWaitsAndKeepsTheFirstRunsCells) {
  // Before: finished_cells.json was read-modify-written without a lock, and two configs run at
  // once into one folder left only one config's cells.
  test::TempDir dir;
  ResultsDocument header = document();
  header.records.clear();
  std::atomic<bool> second_started{false}, second_ready{false};
  std::thread second;
  {
    ResultsStore first(dir.path().string(), header);
    second = std::thread([&] {
      second_started = true;
      ResultsStore s(dir.path().string(), header);  // waits for `first`
      second_ready = true;
      EXPECT_NE(s.finished("k1"), nullptr) << "the second run did not see the first run's cell";
      CellRecord other = method_record();
      other.cell_key = "k2";
      s.add(other);
    });
    while (!second_started) std::this_thread::yield();
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    EXPECT_FALSE(second_ready) << "a second store opened the folder while the first held it";
    first.add(method_record());
  }
  second.join();
  EXPECT_TRUE(second_ready);
  ResultsStore after(dir.path().string(), header);
  EXPECT_NE(after.finished("k1"), nullptr);
  EXPECT_NE(after.finished("k2"), nullptr);
}

TEST(ResultsStore, RemovesTheTemporaryFilesOfWritersThatDied) {
  test::TempDir dir;
  std::filesystem::create_directories(dir.path() / "images/c");
  // A pid that cannot be running (above the kernel's pid_max of 2^22), and one that is (ours).
  const std::string dead = (dir.path() / "images/c/.x_16.tmp-99999999-0.exr").string();
  const std::string alive = (dir.path() / fmt::format(".results.tmp-{}-7.json", ::getpid())).string();
  std::ofstream(dead) << "partial";
  std::ofstream(alive) << "in flight";
  ResultsDocument header = document();
  header.records.clear();
  ResultsStore store(dir.path().string(), header);
  EXPECT_FALSE(std::filesystem::exists(dead));
  EXPECT_TRUE(std::filesystem::exists(alive));
}

TEST(ResultsCsv, OneRowPerRecordWithMetricsAndTimes) {
  const std::string csv = results_csv(document());
  EXPECT_THAT(csv, HasSubstr("scene,method,role,spp,width,height,mse,"));
  EXPECT_THAT(csv, HasSubstr("cornell-box,proposed-no-nlm,ablation,16,64,48,12.5,"));
  EXPECT_THAT(csv, HasSubstr(",nlm_space=false,images/c/x_16.exr\n"));
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 3);
}

}  // namespace
}  // namespace dnb::experiment
