// Fuzz target: the experiment-config loader (experiment/config.h load_config), the TOML file of
// `denoisebench run`. The input is the file, written to the private folder as config.toml.
// fuzz/config.dict has the keys, section names and method names.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "experiment/config.h"
#include "fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace dnb::fuzz;
  const std::string path = write_input("config.toml", {reinterpret_cast<const char*>(data), size});
  run_guarded([&] {
    const auto config = dnb::experiment::load_config(path);
    (void)config.recorded();  // what the results file records of it
  });
  return 0;
}
