// Fuzz target: the results.json reader of `report` and `nightly` (experiment/results.h
// ResultsDocument::load), then the queries the tables and gates are written in.
//
// The input is the file, written to the private folder as results.json. A document that was
// read must also survive its own round trip: from_json(to_json()) of it is read again without
// error (the runner writes with to_json what report reads with from_json), else it is a finding.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "experiment/results.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dnb::fuzz;
  using dnb::experiment::ResultsDocument;
  using dnb::experiment::Role;
  const std::string path = write_input("results.json", {reinterpret_cast<const char*>(data), size});
  run_guarded([&] {
    const ResultsDocument d = ResultsDocument::load(path);
    const auto scenes = d.scenes();
    const int spp = d.table_spp();
    for (Role role : {Role::Plain, Role::Input, Role::Method, Role::Ablation})
      for (const auto& method : d.methods(role))
        for (const auto& scene : scenes) {
          (void)d.find(scene, method, spp);
          (void)d.failure(scene, method, spp);
        }
    const nlohmann::json written = d.to_json();
    try {
      (void)ResultsDocument::from_json(written, "round trip");
    } catch (const dnb::InputError& e) {
      std::fprintf(stderr, "==FINDING== a document read from the file is refused after to_json: %s\n", e.what());
      std::abort();
    }
  });
  return 0;
}
